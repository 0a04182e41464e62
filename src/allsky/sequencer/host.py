"""The seam between master sequencer 20 and the mission it drives, written down.

:class:`Host` is everything the sequencer's steps -- the interpreter
(:func:`allsky.sequencer.master_sequencer.run_mode`), its actions and the
dither analysis (:mod:`allsky.sequencer.dither_mode`) -- may read or change
on the mission: the state arrays of the hardware, the scenario and the
frame loop's parameters, a few named results, and a handful of methods.
The hardware is read through ``view`` and written through ``board``, which
journals every write it makes.
Nothing else of the mission is touched, and the sequencer writes no private
field of it; :class:`allsky.sim.mission.Mission` is the host
(``tests/sequencer/test_host.py`` holds both sides to this list).

As SciPy's ``OdeSolver`` writes down what a solver offers to
``solve_ivp``, this page writes down what a mission offers to the
sequencer; a study or a front end that needs to hear of the flight passes
hooks to the mission (:class:`allsky.sim.mission.Hooks`) rather than
reaching into it.
"""

from typing import Any, Protocol


class Host(Protocol):
    """What master sequencer 20 may use of the mission it runs."""

    #: the mission state as read-only views (:class:`allsky.sim.state.State`): the hardware's
    #: outputs, read; every change goes through ``board``
    view: Any
    #: the one writer of the hardware between legs (:class:`allsky.sim.board.Board`):
    #: switches, counters, rate-command directions, registers 23 and 24, drift counters,
    #: CPU 22; each write journaled in the same call
    board: Any
    cfg: Any  #: the scenario (read only)
    params: Any  #: the frame loop's parameters (read only)
    pulse_weight_arcsec: float  #: [arcsec] per converter pulse
    apply_calibration: bool  #: ``calibration.apply``
    programmed_roll_deg: float | None  #: [deg] register 24's roll, once computed
    programmed_yaw_deg: float | None  #: [deg] register 24's yaw, once computed
    counted_arcsec: dict  #: [arcsec] counters 14/16/18 at each calibration turn's end
    dither_estimates: dict | None  #: the dither analysis's estimates
    dither_record: Any  #: the dither record analysed
    hold: dict | None  #: the hold on target's measurements
    current_mode: str | None  #: the mode being flown, by name (abort reasons name it)
    #: [deg] the roll and yaw from the target held to the one being flown, formed by CPU 22
    #: (``sequencer.between_targets = "direct"``); None otherwise
    turn_roll_deg: float | None
    turn_yaw_deg: float | None
    #: the body axes CPU 22 holds the vehicle in, as columns in the first target's reference
    #: frame (a 3x3 list), once it has turned from target to target; None before
    held_axes: list | None

    #: the mission clock: the frame the flight stands at (:mod:`allsky.clock`)
    frame: int

    def now_s(self) -> float:
        """Mission time [s]: the time of the frame the flight stands at."""

    def note(self, kind: str, **fields) -> dict:
        """Journal an entry of ``kind`` (:data:`allsky.vocabulary.EVENT_KINDS`) now.

        ``**fields`` are the entry's fields for that kind (docs/journal.md);
        the time and the mode are added. Returns the entry.
        """

    def leg(self, what, program, watch, mask=0, signal=0, blank_s=0.0, hold_s=None,
            on_timeout=None, record_rows=0, carry_settle=False):
        """Fly the frame loop until ``what`` happens (:class:`allsky.sequencer.legs.Leg`).

        Parameters
        ----------
        what : str
            What the leg waits for, in words (abort reasons and hooks show it).
        program : int
            The computer's program, a ``legs.PROGRAM_*`` code.
        watch : int
            What ends the leg, a ``legs.WATCH_*`` code.
        mask : int
            Bits of the ``legs.SIG_*`` signals that must settle
            (``Leg.settle_mask``).
        signal : int
            The ``legs.SIG_*`` signal watched for a hand-over
            (``Leg.handover_signal``).
        blank_s : float
            [s] The watched signal is ignored this long after the leg starts.
        hold_s : float, optional
            [s] Settle time (``WATCH_SETTLE``) or duration (``WATCH_ELAPSED``);
            None for the scenario's settle time.
        on_timeout : str, optional
            The abort reason's words should the mode time out first (default:
            ``what`` not achieved).
        record_rows : int
            Most rows of the dither record the leg keeps.
        carry_settle : bool
            The settle time goes on from the previous leg's.

        Returns
        -------
        numpy.ndarray
            The leg's dither record; a leg that ends otherwise than done raises
            :class:`allsky.sequencer.master_sequencer.ModeAbort`.
        """

    def extra_leg(self, mode: str, allowed_s: float, what, program, watch, **kwargs):
        """A leg outside the plan, flown as part of ``mode`` within ``allowed_s`` [s].

        ``what``, ``program``, ``watch`` and ``**kwargs`` (any other keyword
        of :meth:`leg`) are passed to :meth:`leg`.
        """

    def extend_mode(self, seconds: float) -> None:
        """Move the mode's deadline on by ``seconds`` [s] (a recovery)."""

    def program_target(self) -> None:
        """The ground computation of register 24's angles for the target being flown.

        From the reference attitude of the first target when the targets are
        flown one from the other (``sequencer.between_targets = "direct"``).
        """

    def pointing_error_arcsec(self) -> float:
        """True angle between the roll axis and the target being flown [arcsec]."""

    def next_target(self) -> None:
        """Close the target flown and begin the next of ``target.sequence``."""

