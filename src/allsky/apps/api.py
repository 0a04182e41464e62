"""The Python API: missions, comparisons and campaigns as tables, figures, pages.

What a notebook or a script calls; :mod:`allsky` exports it, so that
``import allsky; f = allsky.fly()`` is the whole set-up.

:func:`fly` flies one mission and returns a :class:`Flight`: the summary
(as ``allsky run --json`` writes it), the telemetry and the journal as
pandas DataFrames, every figure of :mod:`allsky.apps.plots`, the replay
page inline in Jupyter, and the files ``allsky run`` writes.
:func:`compare` flies the calibration comparison (one row per seed and
method), :func:`montecarlo` a campaign (its rows, as the campaign records
them). Each is the command line's own path: the same scenario loading,
the same flight (:func:`allsky.apps.report.fly_drawn`), the same study
functions (:func:`allsky.studies.compare.compare`,
:func:`allsky.apps.campaign.run_recorded`), so the same scenario and seed
give the same numbers as the CLI.

Long work shows a progress bar: tqdm's notebook widget in Jupyter (with
ipywidgets), its terminal line on a terminal, nothing elsewhere. The
kernel's interrupt (Ctrl-C in a script) keeps what finished, as the CLI
does: the result of the part done comes back, marked ``interrupted``,
with an :class:`InterruptedWarning`.

Nothing heavy is imported until a function is called: ``import allsky``
stays cheap, and pandas is imported by the first table.
"""

from __future__ import annotations

import html
import json
import math
import os
import sys
import warnings
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # names for the annotations; imported lazily at run time
    import matplotlib.figure
    import numpy
    import pandas

    from allsky.config import Scenario
    from allsky.sim.mission import Mission

__all__ = ["FIGURES", "Flight", "InterruptedWarning", "Replay", "StrictError", "compare",
           "comparison_rows",
           "events_frame", "flight_html", "fly", "in_jupyter", "montecarlo", "telemetry_frame",
           "units_of"]

#: Figure name -> file name of :func:`allsky.apps.plots.write_plots` it draws.
FIGURES = {
    "attitude": "attitude_errors.png",
    "switches": "switches.png",
    "counters": "counters.png",
    "jets": "jets.png",
    "calibration": "calibration.png",
    "hold": "hold.png",
}
#: [px] height of the inline replay frame (the page lays itself out in it).
REPLAY_HEIGHT_PX = 860
#: Files :meth:`Flight.save` writes, by what they hold.
SAVED_FILES = {"summary": "summary.json", "report": "report.txt",
               "scenario": "scenario.toml", "replay": "replay.html",
               "figures": "figures"}
#: Telemetry file formats :meth:`Flight.save` writes (the CLI's suffixes).
TELEMETRY_FORMATS = ("parquet", "csv")


class InterruptedWarning(UserWarning):
    """Work stopped by the kernel's interrupt (Ctrl-C); the result is the part done.

    Examples
    --------
    A script that must not go on with part of a result makes the warning an
    error: a Ctrl-C then raises it instead of returning the part done.

    >>> import warnings
    >>> import allsky
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("error", allsky.InterruptedWarning)
    ...     f = allsky.fly()
    >>> f.interrupted
    False
    """


class StrictError(RuntimeError):
    """A mission flown with ``strict=True`` that warned, aborted or did not finish.

    :func:`fly` raises it; ``message`` gives the judgement and the first
    warning (:func:`allsky.apps.verdict.strict_failure`), and ``flight``, the
    :class:`Flight`, keeps everything flown.

    Attributes
    ----------
    flight : Flight
        The mission flown, all of it.
    warnings : list of str
        The summary's warnings.

    Examples
    --------
    >>> import allsky
    >>> try:
    ...     allsky.fly("gyro-failure-to-target", strict=True)
    ... except allsky.StrictError as e:
    ...     print(str(e)[:70])
    ...     flight = e.flight
    mission complete, as the sequencer judged, with a warning (and 1 more)
    >>> flight.status, len(flight.summary["warnings"])
    ('complete', 2)
    """

    def __init__(self, message: str, flight: Flight) -> None:
        super().__init__(message)
        self.flight = flight
        self.warnings = list(flight.summary.get("warnings") or [])


# ---------------------------------------------------------------------------
# Scenarios and progress
# ---------------------------------------------------------------------------

def _overrides(values: Mapping | None) -> list:
    """``{"target.star": "Vega"}`` -> ``["target.star=\\"Vega\\""]`` (TOML values)."""
    from allsky.config.toml_io import toml_value

    if values is None:
        return []
    if not isinstance(values, Mapping):
        raise TypeError(f"set= takes a dict of KEY: value, not {type(values).__name__}")

    def plain(v):
        if hasattr(v, "tolist"):  # NumPy scalars and arrays
            return v.tolist()
        if isinstance(v, Mapping):
            return {k: plain(x) for k, x in v.items()}
        if isinstance(v, list | tuple):
            return [plain(x) for x in v]
        return v

    return [f"{key}={toml_value(plain(value))}" for key, value in values.items()]


def _scenario(scenario=None, set=None, disperse=None) -> Scenario:
    """The scenario a call flies, validated, with ``set`` applied over it."""
    from allsky.config import Scenario, load_scenario, scenario_from_dict

    overrides = _overrides(set)
    if isinstance(scenario, Scenario):
        if disperse is not None:
            raise ValueError("disperse= needs a scenario file or name, not a Scenario "
                             "(put the [dispersions] in the Scenario)")
        return scenario_from_dict(scenario.as_dict(), overrides) if overrides else scenario
    if isinstance(scenario, Mapping):
        if disperse is not None:
            raise ValueError("disperse= needs a scenario file or name, not a dict "
                             "(put a 'dispersions' table in the dict)")
        return scenario_from_dict(scenario, overrides)
    if scenario is not None and not isinstance(scenario, str | os.PathLike):
        raise TypeError("scenario is a file, a packaged scenario's name, a Scenario or a "
                        f"dict, not {type(scenario).__name__}")
    return load_scenario(scenario, overrides, disperse)


def in_jupyter() -> bool:
    """Whether this code runs in a Jupyter kernel (an IPython shell with a kernel)."""
    ipython = sys.modules.get("IPython")
    shell = ipython.get_ipython() if ipython is not None else None
    return shell is not None and getattr(shell, "kernel", None) is not None


def _bar_class(progress: bool | None):
    """The tqdm class to show progress with (None: no progress shown).

    ``progress`` None: the notebook widget in Jupyter when ipywidgets is
    there, the terminal line when stderr is a terminal, else nothing. True:
    the widget in Jupyter (ImportError naming the package without
    ipywidgets), the line on stderr elsewhere. False: nothing.
    """
    if progress is False:
        return None
    if in_jupyter():
        try:
            import ipywidgets  # noqa: F401 - tqdm's notebook bar draws with it
        except ImportError:
            if progress:
                raise ImportError("a progress bar in Jupyter needs ipywidgets: "
                                  "pip install 'allsky[notebook]'") from None
            return None
        from tqdm.notebook import tqdm

        return tqdm
    if progress or sys.stderr.isatty():
        from tqdm import tqdm

        return tqdm
    return None


def _interrupted(what: str) -> None:
    warnings.warn(f"interrupted: {what}", InterruptedWarning, stacklevel=3)


def units_of(names: Iterable[str]) -> dict:
    """Unit of each column from its name: the suffix of its last part that has one.

    ``scale_factor_error_ppm.roll`` -> ``ppm``, ``mode_end_4_s`` -> ``s``,
    ``gyro.drift_deg_h[0]`` -> ``deg/h``; ``-`` for a column whose name
    carries no unit (text, counts, ratios). The suffixes are the scenario
    keys' (:data:`allsky.config.meanings.UNIT_SUFFIXES`).

    Parameters
    ----------
    names : iterable of str
        Column names.

    Returns
    -------
    dict
        Name -> unit.
    """
    from allsky.config.meanings import UNIT_SUFFIXES

    def unit(name):
        for part in reversed(name.split(".")):
            part = part.split("[", 1)[0]
            for suffix, u in UNIT_SUFFIXES:
                if part.endswith(suffix):
                    return u
        return "-"

    return {n: unit(n) for n in names}


# ---------------------------------------------------------------------------
# One mission
# ---------------------------------------------------------------------------

class Replay:
    """The replay page of a flight: shown inline in Jupyter, or saved as a file.

    The page is :func:`allsky.apps.replay.render_html` of the flight: one
    self-contained HTML file that makes no network request (its own
    Content-Security-Policy forbids any). Inline it is an ``<iframe
    srcdoc>`` inside the notebook's own page: no server, no file beside the
    notebook; its ``window.allsky`` API (docs/replay.md) works inside the
    frame.

    Parameters
    ----------
    page : str
        The page's HTML.
    height_px : int
        [px] height of the inline frame.

    Examples
    --------
    >>> import allsky
    >>> r = allsky.fly().replay()     # in Jupyter: the page, inline
    >>> r
    <Replay: ... MB page>
    >>> r.save("replay.html")         # doctest: +SKIP
    PosixPath('replay.html')
    """

    def __init__(self, page: str, height_px: int = REPLAY_HEIGHT_PX) -> None:
        self.html = page
        self.height_px = int(height_px)

    def __repr__(self) -> str:
        return f"<Replay: {len(self.html) / 1e6:.1f} MB page>"

    def _repr_html_(self) -> str:
        return (f'<iframe class="allsky-replay" title="allsky mission replay" '
                f'srcdoc="{html.escape(self.html, quote=True)}" '
                f'style="width: 100%; box-sizing: border-box; height: {self.height_px}px; '
                'border: 1px solid #ccc">'
                "</iframe>")

    def save(self, path: str | os.PathLike) -> Path:
        """Write the page to ``path`` (whole or not at all); return the path.

        Parameters
        ----------
        path : str or path-like
            The ``.html`` file to write.

        Returns
        -------
        pathlib.Path
        """
        from allsky.apps.output import check_output, write_atomic

        check_output("path", path, suffixes=(".html", ".htm"))
        return write_atomic(path, self.html)


class Flight:
    """A flown mission: its summary, telemetry, journal, figures and replay.

    Made by :func:`fly`, or from a :class:`~allsky.sim.mission.Mission`
    flown (or stepped) by hand. A Flight is what was flown when it was
    made: the summary and the telemetry are read then.

    Parameters
    ----------
    mission : allsky.sim.mission.Mission
        The mission, finished or not.
    scenario : allsky.config.Scenario, optional
        The scenario asked for, before its dispersions were drawn (default:
        the mission's own); :meth:`save` writes it.
    summary : dict, optional
        The mission's summary, when already made (default: read from the
        mission).
    interrupted : bool
        The flight was stopped by the kernel's interrupt before its end.

    Attributes
    ----------
    mission : allsky.sim.mission.Mission
        The mission flown (its state, parameters, journal).
    scenario : allsky.config.Scenario
        The scenario asked for.
    interrupted : bool
        Stopped before the end by an interrupt.

    Examples
    --------
    >>> import allsky
    >>> f = allsky.fly("gyro-failure-to-target")
    >>> f                        # in Jupyter: the summary, in amber, the first warning
    <Flight complete, as the sequencer judged: Sirius, true pointing error 392461.2 arcsec; ...>
    >>> last = f.telemetry.iloc[-1]   # what the dead gyro says [arcsec/s], the truth [rad/s]
    >>> float(last["gyro_pitch"]), round(float(last["rate_y"]), 3)
    (0.0, 0.338)
    >>> f.timeline["mode"].tolist()
    ['1', '2', '3', '4', '5', '6-1', '6-2']
    >>> f.replay()               # in Jupyter: the replay page, inline
    <Replay: ... MB page>
    """

    def __init__(self, mission: Mission, scenario: Scenario | None = None,
                 summary: dict | None = None, interrupted: bool = False) -> None:
        self.mission = mission
        self.scenario = mission.cfg if scenario is None else scenario
        self.interrupted = bool(interrupted)
        self._summary = mission.summary() if summary is None else summary
        self._table = mission.telemetry()
        self._frames: dict = {}

    # -- what the mission wrote ---------------------------------------------
    @property
    def summary(self) -> dict:
        """The summary, as ``allsky run --json`` writes it (:meth:`Mission.summary`).

        Returns
        -------
        dict
            ``status``, ``modes``, ``calibration`` beside ``truth``,
            ``target``, ``end``, ``warnings``, ``events`` ... (docs/journal.md);
            ``dispersions`` when the scenario's were drawn.
        """
        return self._summary

    @property
    def status(self) -> str:
        """``complete``, ``aborted``, or ``running`` (stopped before the end)."""
        return self._summary["status"]

    @property
    def table(self) -> numpy.ndarray:
        """The telemetry as recorded: a float64 array, columns in schema order.

        Returns
        -------
        numpy.ndarray
            One row per record, :data:`allsky.sim.recorder.COLUMNS` order
            (empty when flown without telemetry).
        """
        return self._table

    @property
    def telemetry(self) -> pandas.DataFrame:
        """The telemetry as a DataFrame indexed by mission time [s].

        One column per documented telemetry column (docs/telemetry.md) but
        ``time``, which is the index. Counters, registers, flags, valve
        commands and the switch bitmask are integers; the rest float64.

        Returns
        -------
        pandas.DataFrame
            ``attrs["units"]``: column (and ``time``) -> unit;
            ``attrs["meanings"]``: column -> what it holds.
        """
        if "telemetry" not in self._frames:
            self._frames["telemetry"] = telemetry_frame(self._table)
        return self._frames["telemetry"].copy(deep=False)

    @property
    def events(self) -> pandas.DataFrame:
        """The journal as a DataFrame: one row per entry, in the order written.

        Returns
        -------
        pandas.DataFrame
            Columns ``t_s`` [s], ``mode``, ``kind``, ``description`` (the
            entry in words, :func:`allsky.apps.events.event_text`), then
            each field of the kinds present (docs/journal.md), empty where
            a kind has no such field. ``attrs["units"]`` as
            :func:`units_of` reads the names.
        """
        if "events" not in self._frames:
            self._frames["events"] = events_frame(self._summary.get("events") or [])
        return self._frames["events"].copy(deep=False)

    @property
    def timeline(self) -> pandas.DataFrame:
        """The mode timeline: one row per mode flown, as the sequencer judged it.

        Returns
        -------
        pandas.DataFrame
            Columns ``mode``, ``start_s``, ``end_s``, ``duration_s`` [s] and
            ``exit`` (the exit text, or ``aborted: <reason>``).
        """
        import pandas as pd

        modes = self._summary["modes"]
        frame = pd.DataFrame(modes, columns=["mode", "start_s", "end_s", "exit"])
        frame.insert(3, "duration_s", frame["end_s"] - frame["start_s"])
        frame.attrs["units"] = units_of(frame.columns)
        return frame

    def report(self) -> str:
        """The report ``allsky run`` prints, as text.

        Returns
        -------
        str
            The drawn dispersions (when any), then
            :func:`allsky.apps.report.format_report`.
        """
        from allsky.apps.report import format_report, tracker_star
        from allsky.config.dispersions import format_drawn

        drawn = self._summary.get("dispersions")
        head = format_drawn(self._summary["seed"], drawn) + "\n\n" if drawn else ""
        return head + format_report(self._summary, tracker_star(self.mission.cfg))

    # -- figures and the replay ---------------------------------------------
    def plot(self, name: str = "attitude") -> matplotlib.figure.Figure:
        """One figure of the flight, as :mod:`allsky.apps.plots` draws it.

        Parameters
        ----------
        name : str
            One of :data:`FIGURES`: ``attitude`` (attitude errors, modes
            shaded, the true final error), ``switches`` (S1-S19),
            ``counters``, ``jets`` (valves and propellant), ``calibration``
            (against the truth), ``hold`` (the drift on target).

        Returns
        -------
        matplotlib.figure.Figure

        Raises
        ------
        ValueError
            An unknown name, a flight without telemetry, a calibration
            figure without a calibration, a hold figure without a hold.
        """
        from allsky.apps import plots

        if name not in FIGURES:
            raise ValueError(f"unknown figure {name!r}; the figures: {', '.join(FIGURES)}")
        file_name = FIGURES[name]
        if file_name == plots.CALIBRATION_FILE:
            if self._summary.get("calibration") is None:
                raise ValueError("the mission stored no calibration: no calibration figure")
            fig = plots.calibration(self._summary)
        elif len(self._table) == 0:
            raise ValueError("the flight recorded no telemetry (fly(telemetry=False)): "
                             f"no {name} figure")
        elif file_name == plots.HOLD_FILE:
            if not plots.hold_spans(self._table):
                raise ValueError("the mission held no target (target.hold_s = 0): no hold "
                                 "figure")
            fig = plots.hold_drift(self._table, self._summary)
        else:
            draw = next(f for file, f in plots.TELEMETRY_FIGURES.values() if file == file_name)
            fig = (draw(self._table, self._summary) if draw in plots.USES_SUMMARY
                   else draw(self._table))
        _show_inline()
        return fig

    def replay(self, height_px: int = REPLAY_HEIGHT_PX) -> Replay:
        """The replay page of the flight, shown inline in Jupyter.

        Parameters
        ----------
        height_px : int
            [px] height of the inline frame.

        Returns
        -------
        Replay
            :func:`allsky.apps.replay.render_html` of
            :func:`~allsky.apps.replay.replay_data` (telemetry, summary,
            scenario flown); ``Replay.save(path)`` writes it.

        Raises
        ------
        ValueError
            The flight recorded no telemetry.
        """
        from allsky.apps.replay import render_html, replay_data

        if len(self._table) == 0:
            raise ValueError("the flight recorded no telemetry (fly(telemetry=False)): "
                             "nothing to replay")
        if "replay" not in self._frames:
            self._frames["replay"] = render_html(replay_data(self._table, self._summary,
                                                             self.mission.cfg))
        return Replay(self._frames["replay"], height_px)

    def save(self, directory: str | os.PathLike, telemetry: str = "parquet") -> dict:
        """Write the flight's files into ``directory`` (created if needed).

        The files ``allsky run`` writes, under fixed names: the summary
        (``--json``), the report it prints, the telemetry (``--telemetry``),
        the figures (``--plots``) and the replay page (``--html``), and the
        scenario asked for, which flies the same mission again. Each is
        written whole or not at all.

        Parameters
        ----------
        directory : str or path-like
            Where to write.
        telemetry : {"parquet", "csv"}
            The telemetry file's format.

        Returns
        -------
        dict
            What was written -> its path: ``summary`` (summary.json),
            ``report`` (report.txt), ``scenario`` (scenario.toml) and, when
            telemetry was recorded, ``telemetry`` (telemetry.parquet or
            .csv), ``replay`` (replay.html) and ``figures`` (a list of PNG
            files in figures/).
        """
        from allsky.apps import plots, telemetry_files
        from allsky.apps.output import check_output, write_atomic
        from allsky.apps.replay import write_replay
        from allsky.apps.summaries import summary_text

        if telemetry not in TELEMETRY_FORMATS:
            raise ValueError(f"telemetry={telemetry!r}: one of {', '.join(TELEMETRY_FORMATS)}")
        check_output("directory", directory, directory=True)
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        written = {
            "summary": write_atomic(out / SAVED_FILES["summary"],
                                    summary_text(self._summary)),
            "report": write_atomic(out / SAVED_FILES["report"], self.report() + "\n"),
            "scenario": write_atomic(out / SAVED_FILES["scenario"], self.scenario.to_toml()),
        }
        if len(self._table):
            written["telemetry"] = telemetry_files.write(out / f"telemetry.{telemetry}",
                                                         self._table)
            written["replay"] = write_replay(out / SAVED_FILES["replay"], self._table,
                                             self._summary, self.mission.cfg)
            written["figures"] = plots.write_plots(self._table, out / SAVED_FILES["figures"],
                                                   self._summary).files
        return written

    # -- how it shows itself --------------------------------------------------
    def __repr__(self) -> str:
        from allsky.apps.verdict import judge

        s = self._summary
        where = s["end"]["target"] if s.get("end") else s["target"].get("star", "target")
        if s["status"] == "complete":
            j = judge(s)
            what = (f"{j['label']}: {where}, true pointing error "
                    f"{s['end']['true_pointing_error_arcsec']:.1f} arcsec")
            if j["first_warning"]:
                what += f"; warning: {j['first_warning']}"
        elif s["status"] == "aborted":
            what = f"aborted: {s['abort_reason']}"
        else:
            what = "not finished"
        return f"<Flight {what}; t = {s['mission_time_s']:.1f} s, seed {s['seed']}>"

    def _repr_html_(self) -> str:
        return flight_html(self._summary, self.interrupted)


def _show_inline() -> None:
    """Let IPython draw a figure made without pyplot as an inline PNG.

    Figures are made on matplotlib's object API (no pyplot state); IPython
    shows a Figure only once a formatter for it is registered, which pyplot's
    inline backend does. Outside IPython nothing happens.
    """
    ipython = sys.modules.get("IPython")
    shell = ipython.get_ipython() if ipython is not None else None
    if shell is None:
        return
    formatter = shell.display_formatter.formatters.get("image/png")
    if formatter is None:
        return
    from matplotlib.figure import Figure

    try:
        formatter.lookup_by_type(Figure)
    except KeyError:
        from IPython.core.pylabtools import print_figure

        formatter.for_type(Figure, lambda f: print_figure(f, "png", bbox_inches="tight"))


def fly(scenario: str | os.PathLike | Scenario | Mapping | None = None, *,
        set: Mapping | None = None, disperse: str | os.PathLike | None = None, plan: str = "legacy",
        telemetry: bool = True, progress: bool | None = None, strict: bool = False) -> Flight:
    """Fly one mission, as ``allsky run`` does, and return the :class:`Flight`.

    Parameters
    ----------
    scenario : str, path-like, Scenario or dict, optional
        A scenario TOML file, the name of a packaged scenario
        (``"voyager1-wrong-star"``; ``allsky scenarios`` lists them), a
        :class:`~allsky.config.Scenario`, or a dict of sections merged over
        the default; None: the packaged default mission.
    set : dict, optional
        Keys to override, as ``--set`` does: ``{"target.star": "Vega",
        "mission.seed": 7}`` (dotted key -> Python value).
    disperse : str or path-like, optional
        A TOML file with a ``[dispersions]`` table merged over the
        scenario's, as ``--disperse`` (with a file or name only).
    plan : {"legacy", "dither"}
        The patent's modes, or the dither calibration in place of Modes 4
        and 5 (the comparison's second method).
    telemetry : bool
        Record telemetry (figures and the replay need it).
    progress : bool, optional
        Show a progress bar (None: in Jupyter with ipywidgets, or on a
        terminal).
    strict : bool
        Raise :class:`StrictError` unless the mission completed without a
        warning, as ``allsky run --strict`` exits 1: for scripts, where a
        mission "complete, as the sequencer judged" must not pass.

    Returns
    -------
    Flight
        The mission flown. After the kernel's interrupt (Ctrl-C), the part
        flown, with ``interrupted`` True and an :class:`InterruptedWarning`.

    Raises
    ------
    allsky.config.ConfigError
        A scenario that cannot be read, an unknown key or a value that
        breaks its rule (the message names the key, the value and the rule).
    StrictError
        With ``strict``: a warning in the summary, an abort, or a flight not
        finished; its ``flight`` attribute holds the mission flown.

    Examples
    --------
    >>> import allsky
    >>> f = allsky.fly(set={"target.star": "Vega", "mission.seed": 7})
    >>> f.status
    'complete'
    >>> round(f.summary["end"]["true_pointing_error_arcsec"], 1)   # [arcsec] the truth
    5.0
    """
    from allsky.apps import progress as progress_line
    from allsky.apps.report import fly_drawn, where_stopped
    from allsky.config.dispersions import disperse as draw
    from allsky.sequencer.modes import PLANS

    if plan not in PLANS:
        raise ValueError(f"plan={plan!r}: one of {', '.join(PLANS)}")
    asked = _scenario(scenario, set, disperse)
    cfg, drawn = draw(asked)
    bar = _bar_class(progress)
    if bar is None:  # none; outside Jupyter the compile note, as allsky run gives it
        def how(m):
            return progress_line.fly(m, quiet=progress is False or in_jupyter())
    elif in_jupyter() or progress:
        def how(m):
            return progress_line.fly(m, bar=bar)
    else:  # on a terminal: the line of allsky run
        how = progress_line.fly
    flown = fly_drawn(cfg, drawn, telemetry=telemetry, fly=how, plan=PLANS[plan])
    if flown.interrupted:
        _interrupted(f"mission stopped at {where_stopped(flown.mission)}; the Flight holds "
                     "the part flown")
    flight = Flight(flown.mission, asked, flown.summary, flown.interrupted)
    if strict:
        from allsky.apps.verdict import strict_failure

        why = strict_failure(flown.summary)
        if why is not None:
            raise StrictError(why, flight)
    return flight


# ---------------------------------------------------------------------------
# Tables
# ---------------------------------------------------------------------------

def telemetry_frame(table) -> pandas.DataFrame:
    """A telemetry table as a DataFrame indexed by time [s], units in ``attrs``.

    Parameters
    ----------
    table : numpy.ndarray
        Telemetry rows, :data:`allsky.sim.recorder.COLUMNS` order.

    Returns
    -------
    pandas.DataFrame
        See :attr:`Flight.telemetry`.
    """
    import numpy as np
    import pandas as pd

    from allsky.sim import recorder

    table = np.asarray(table, dtype=np.float64).reshape(-1, len(recorder.COLUMNS))
    columns = recorder.COLUMNS[1:]
    index = pd.Index(table[:, 0], name=recorder.COLUMNS[0].name)
    data = {}
    integers = (recorder.INTEGER, recorder.FLAG, recorder.SET, recorder.BITMASK)
    for i, c in enumerate(columns, start=1):
        values = table[:, i]
        if c.kind in integers and np.isfinite(values).all():
            values = values.astype(np.int64)
        data[c.name] = values
    frame = pd.DataFrame(data, index=index)
    frame.attrs["units"] = {c.name: c.unit for c in recorder.COLUMNS}
    frame.attrs["meanings"] = {c.name: c.meaning for c in recorder.COLUMNS}
    return frame


def events_frame(events: list) -> pandas.DataFrame:
    """A journal (the summary's ``events``) as a DataFrame, one row per entry.

    Parameters
    ----------
    events : list of dict
        Journal entries ``{t_s, mode, kind, ...}``.

    Returns
    -------
    pandas.DataFrame
        See :attr:`Flight.events`.
    """
    import pandas as pd

    from allsky.apps.events import event_text

    head = ["t_s", "mode", "kind", "description"]
    rest = []
    for e in events:
        rest += [k for k in e if k not in head and k not in rest]
    rows = [{**e, "description": event_text(e)} for e in events]
    frame = pd.DataFrame(rows, columns=head + rest)
    frame = frame.astype({"t_s": "float64"})
    frame.attrs["units"] = units_of(frame.columns)
    return frame


def _flat(prefix: str, value, out: dict) -> dict:
    if isinstance(value, Mapping):
        for k, v in value.items():
            _flat(f"{prefix}.{k}" if prefix else str(k), v, out)
    else:
        out[prefix] = value
    return out


def comparison_rows(result: Mapping) -> list:
    """The rows of a comparison, one per seed and method, nested keys joined by dots.

    Parameters
    ----------
    result : dict
        :func:`allsky.studies.compare.compare`'s result.

    Returns
    -------
    list of dict
        ``{"seed", "method", ...}``, the method's metrics flattened:
        ``scale_factor_error_ppm.roll``, ``mode_time_s.4`` ...; the methods
        in the order flown (legacy, dither, then the Kalman filter on the
        legacy manoeuvres, ``kalman``, and on the dither's,
        ``kalman_dither``; the sections of
        ``allsky.studies.compare.METHOD_KEYS``). A seed's information
        limit (its ``crlb``) is not a method and makes no row; the campaign's
        bounds are in the result's ``crlb`` section.
    """
    from allsky.studies.compare import METHOD_KEYS

    rows = []
    for r in result["rows"]:
        for method in METHOD_KEYS:
            if method in r:
                rows.append(_flat("", r[method], {"seed": r["seed"], "method": method}))
    return rows


def _frame(rows: list, columns: list | None = None) -> pandas.DataFrame:
    import pandas as pd

    if columns is None:
        columns = []
        for r in rows:
            columns += [k for k in r if k not in columns]
    frame = pd.DataFrame(rows, columns=columns)
    frame.attrs["units"] = units_of(frame.columns)
    return frame


def _methods(methods) -> tuple:
    from allsky.studies.compare import METHODS

    names = (methods,) if isinstance(methods, str) else tuple(methods)
    unknown = [n for n in names if n not in METHODS]
    if unknown:
        raise ValueError(f"unknown method {unknown[0]!r} (known: {', '.join(METHODS)})")
    if not {"legacy", "dither"} <= set(names):
        raise ValueError("legacy and dither are always compared: methods=['legacy', "
                         "'dither'] or ['legacy', 'dither', 'kalman']")
    return names


def compare(runs: int = 1, methods: Iterable[str] = ("legacy", "dither"),
            vehicle: str | None = None,
            scenario: str | os.PathLike | Scenario | Mapping | None = None, *,
            set: Mapping | None = None, workers: int | None = None,
            progress: bool | None = None) -> pandas.DataFrame:
    """Fly the calibration comparison as ``allsky compare``: a row per seed and method.

    In a notebook the result shows itself as the terminal's headline table
    (:class:`allsky.apps.comparison.Comparison`); it is the DataFrame of the rows.

    Each seed flies the same vehicle with each method
    (:func:`allsky.studies.compare.compare`; docs/comparison.md).

    Parameters
    ----------
    runs : int
        Number of seeds, from the scenario's ``mission.seed`` on.
    methods : sequence of str
        ``["legacy", "dither"]``, or with ``"kalman"`` the three-axis Kalman
        filter too (its two flights: rows ``kalman`` and ``kalman_dither``).
    vehicle : {"jets", "wheels"}, optional
        The actuators both methods fly (None: the scenario's).
    scenario : str, path-like, Scenario or dict, optional
        As :func:`fly` takes it (None: the packaged default).
    set : dict, optional
        Keys to override, as :func:`fly` takes them.
    workers : int, optional
        Worker processes (default: one per core, never more than ``runs``).
    progress : bool, optional
        Show a progress bar (None: in Jupyter with ipywidgets, or on a
        terminal).

    Returns
    -------
    allsky.apps.comparison.Comparison
        A pandas DataFrame that Jupyter shows as the headline table of
        ``allsky compare``; its rows: one per seed and method (:func:`comparison_rows`): ``seed``,
        ``method``, ``status``, the calibration's errors, time, excursion,
        propellant and pointing errors, units in the names and in
        ``attrs["units"]``. ``attrs["comparison"]`` holds the rest of what
        ``allsky compare --json`` writes (statistics over the runs, the
        predicted spreads); ``attrs["interrupted"]`` is True after the
        kernel's interrupt, the rows being the seeds finished.

    Raises
    ------
    KeyboardInterrupt
        Interrupted before the first seed finished.

    Examples
    --------
    Eight missions, about 10 s on two cores (shown, not run as a doctest); in
    Jupyter ``c`` shows itself as the headline table:

    >>> import allsky
    >>> c = allsky.compare(runs=4)   # doctest: +SKIP
    >>> c.headline()[0]              # doctest: +SKIP
    'Calibration methods compared on the same vehicle (4 runs, seeds 1-4)'
    >>> c.groupby("method")["scale_factor_error_ppm.roll"].std()   # doctest: +SKIP
    method
    dither    1572.304000
    legacy       2.648142
    Name: scale_factor_error_ppm.roll, dtype: float64
    """
    from allsky.apps.output import cap_workers
    from allsky.studies import compare as study

    methods = _methods(methods)
    runs = int(runs)
    if runs < 1:
        raise ValueError(f"runs={runs}: at least 1")
    cfg = _scenario(scenario, set)
    workers, _ = cap_workers(workers, runs)
    one = runs == 1
    bar_class = _bar_class(progress)
    bar = None
    if bar_class is not None:
        total = study.FLIGHTS["three" if "kalman" in methods else "pair"] if one else runs
        bar = bar_class(total=total, desc="missions", unit="mission" if one else "seed",
                        leave=False)

    def flown(name):
        bar.set_postfix_str(name, refresh=False)
        bar.update(1)

    try:
        result = study.compare(cfg, runs=runs, workers=workers, vehicle=vehicle,
                               methods=methods,
                               on_flight=flown if one and bar is not None else None,
                               on_progress=None if one or bar is None else
                               lambda done, total: bar.update(done - bar.n))
    finally:
        if bar is not None:
            bar.close()
    from allsky.apps.comparison import Comparison

    frame = _frame(comparison_rows(result))
    frame.attrs["comparison"] = study.label_percentiles(
        {k: v for k, v in result.items() if k != "rows"})
    frame.attrs["interrupted"] = bool(result.get("interrupted"))
    frame = Comparison.of(frame, {k: v for k, v in result.items() if k != "rows"})
    if result.get("interrupted"):
        _interrupted(f"after {result['runs']} of {result['runs_requested']} seeds; the "
                     "table holds those")
    return frame


def montecarlo(runs: int, scenario: str | os.PathLike | Scenario | Mapping | None = None,
               scheduler: str | None = None, *, set: Mapping | None = None,
               disperse: str | os.PathLike | None = None, workers: int | None = None,
               out: str | os.PathLike | None = None, resume: bool = False,
               progress: bool | None = None, batch: int | None = None) -> pandas.DataFrame:
    """Fly a Monte Carlo campaign, as ``allsky montecarlo``; its rows as a DataFrame.

    Run i flies ``mission.seed + i`` with the scenario's ``[dispersions]``
    drawn for it (docs/montecarlo.md).

    Parameters
    ----------
    runs : int
        Number of runs.
    scenario : str, path-like, Scenario or dict, optional
        As :func:`fly` takes it, with its ``[dispersions]`` (and
        ``[[faults]]``); None: the packaged default.
    scheduler : str, optional
        Address of a Dask distributed scheduler (``tcp://HOST:PORT``) to
        fly on instead of local processes.
    set : dict, optional
        Keys to override, as :func:`fly` takes them.
    disperse : str or path-like, optional
        A TOML file with a ``[dispersions]`` table, as ``--disperse``.
    workers : int, optional
        Local worker processes (default: one per core, never more than
        ``runs``).
    out : str or path-like, optional
        A campaign directory: each run is recorded there as it finishes
        (``campaign.json``, ``runs.csv``), then ``summary.txt``,
        ``summary.json`` and ``histograms.png``, as the CLI writes them;
        ``allsky montecarlo --resume --out DIR`` continues it.
    resume : bool
        Continue the campaign in ``out``, flying only the runs it lacks.
    progress : bool, optional
        Show a progress bar (None: in Jupyter with ipywidgets, or on a
        terminal).
    batch : int, optional
        With ``scheduler``: runs per Dask task, as ``--batch`` (None: chosen
        from the task overhead and the missions' time,
        :func:`allsky.studies.montecarlo.batch_size`). The rows do not
        depend on it.

    Returns
    -------
    pandas.DataFrame
        One row per run, sorted by run, the campaign's columns in its order
        (:func:`allsky.studies.montecarlo.columns`: run, seed, status,
        abort reason, the values drawn, the mode ends, the calibration
        errors, pointing error, propellant, mission time). ``attrs``:
        ``units``, ``summary`` (:func:`allsky.studies.montecarlo.summarize`:
        counts, outcome probabilities, statistics), ``interrupted`` (after
        the kernel's interrupt: the runs finished).

    Raises
    ------
    allsky.studies.montecarlo.CampaignError
        Seeds past the largest, a directory holding another campaign, a
        Dask scheduler that cannot be reached or is lost.

    Examples
    --------
    Twenty missions, from a checkout (the file is in its ``docs/examples/``);
    shown, not run as a doctest:

    >>> import allsky
    >>> spec = "docs/examples/gyro_and_sky_dispersions.toml"   # the gyros' and sky's spreads
    >>> runs = allsky.montecarlo(20, disperse=spec)   # doctest: +SKIP
    >>> runs["status"].value_counts()   # doctest: +SKIP
    status
    complete    20
    Name: count, dtype: int64
    """
    from allsky.apps import campaign
    from allsky.apps.output import cap_workers, check_output, write_atomic
    from allsky.studies.montecarlo import columns

    runs = int(runs)
    if runs < 1:
        raise ValueError(f"runs={runs}: at least 1")
    if resume and out is None:
        raise ValueError("resume=True needs out=DIR: the campaign directory to continue")
    check_output("out", out, directory=True)
    cfg = _scenario(scenario, set, disperse)
    if scheduler is None:
        workers, _ = cap_workers(workers, runs)
    bar_class = _bar_class(progress)
    bar = [None]

    def on_progress(done, total):
        if bar[0] is None:
            if done >= total:
                return
            bar[0] = bar_class(total=total, initial=done, unit="run", desc="missions",
                               leave=False)
        else:
            bar[0].update(done - bar[0].n)

    try:
        result = campaign.run_recorded(cfg, runs=runs, workers=workers, scheduler=scheduler,
                                       out=out, resume=resume, batch=batch,
                                       on_progress=None if bar_class is None else on_progress,
                                       on_note=lambda text: warnings.warn(text, stacklevel=4))
    finally:
        if bar[0] is not None:
            bar[0].close()
    frame = _frame(result["rows"], columns(cfg))
    s = result["summary"]
    frame.attrs.update(summary=s, interrupted=bool(result["interrupted"]))
    if out is not None:
        folder = Path(out)
        text = campaign.format_summary(s, outcomes=bool(cfg.faults))
        write_atomic(folder / campaign.SUMMARY_TEXT, text + "\n")
        write_atomic(folder / campaign.SUMMARY_JSON, json.dumps(s, indent=2) + "\n")
        campaign.plot_histograms(result["rows"], folder / campaign.HISTOGRAMS)
    if result["interrupted"]:
        more = f"; resume=True with out={str(out)!r} flies the rest" if out is not None else ""
        _interrupted(f"after {s['recorded']} of {s['runs']} runs; the table holds those{more}")
    return frame


# ---------------------------------------------------------------------------
# A Flight in a notebook
# ---------------------------------------------------------------------------

_CSS = ("font-family: system-ui, sans-serif; font-size: 13px; line-height: 1.35; "
        "max-width: 980px")
_TABLE = "border-collapse: collapse; margin: 4px 0 8px 0; font-size: 12px"
_CELL = "padding: 1px 8px; text-align: right; border-bottom: 1px solid #ddd"
#: Mode strip colours, by mode (the replay's and the figures' order of modes).
_MODE_COLOURS = ("#4e79a7", "#f28e2b", "#59a14f", "#e15759", "#b07aa1", "#76b7b2",
                 "#edc948", "#9c755f", "#bab0ac", "#ff9da7")


def _esc(v) -> str:
    return html.escape(str(v), quote=True)


def _table(head: list, rows: list, left=(0,)) -> str:
    """An HTML table; the columns ``left`` aligned left, the others right."""
    def align(i):
        return "left" if i in left else "right"

    th = "".join(f'<th style="{_CELL}; text-align: {align(i)}">{_esc(h)}</th>'
                 for i, h in enumerate(head))
    body = "".join("<tr>" + "".join(
        f'<td style="{_CELL}; text-align: {align(i)}">{c}</td>'
        for i, c in enumerate(r)) + "</tr>" for r in rows)
    return f'<table style="{_TABLE}"><tr>{th}</tr>{body}</table>'


def _num(v, spec: str) -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, spec)


def _mode_strip(modes: list) -> str:
    """The timeline as a strip: one block per mode, as wide as it lasted."""
    if not modes:
        return "<div><i>no mode flown</i></div>"
    t0, t1 = modes[0]["start_s"], modes[-1]["end_s"]
    span = max(t1 - t0, 1e-9)
    names = list(dict.fromkeys(r["mode"] for r in modes))
    cells = []
    for r in modes:
        width = 100.0 * (r["end_s"] - r["start_s"]) / span
        colour = _MODE_COLOURS[names.index(r["mode"]) % len(_MODE_COLOURS)]
        aborted = r["exit"].startswith("aborted")
        tip = (f"Mode {r['mode']}: {r['start_s']:.1f}-{r['end_s']:.1f} s "
               f"({r['end_s'] - r['start_s']:.1f} s); {r['exit']}")
        border = "outline: 2px solid #cf222e; " if aborted else ""
        cells.append(f'<div title="{_esc(tip)}" style="{border}width: {width:.3f}%; '
                     f"background: {colour}; color: white; font-size: 11px; overflow: hidden; "
                     f'white-space: nowrap; text-align: center; padding: 2px 0">'
                     f"{_esc(r['mode'])}</div>")
    return ('<div style="display: flex; width: 100%; margin: 4px 0 2px 0">'
            + "".join(cells) + f'</div><div style="font-size: 11px; color: #555">'
            f"0 to {t1:.1f} s; hover a mode for its exit</div>")


def flight_html(summary: Mapping, interrupted: bool = False) -> str:
    """A mission summary as a compact HTML block (how a :class:`Flight` shows itself).

    The status (with the abort reason), the warnings, the mode timeline,
    the calibration against the truth and the end of the flight: the
    machine's judgement beside what happened.

    Parameters
    ----------
    summary : dict
        A mission summary (:attr:`Flight.summary`).
    interrupted : bool
        The flight was stopped by an interrupt.

    Returns
    -------
    str
        HTML, with inline styles only.
    """
    from allsky.apps.verdict import COLOURS, judge, unwritten
    from allsky.sim.results import calibration_errors
    from allsky.units import RAD2ARCSEC
    from allsky.vocabulary import AXES, SCALE_FACTOR_AXES

    s = summary
    status = s["status"]
    j = judge(s)
    shown = "not finished" + (" (interrupted)" if interrupted else "") if \
        status == "running" else j["label"]
    colour = COLOURS[j["tone"]]
    tgt = s["target"]
    name = tgt.get("star") or f"RA {tgt['ra_deg']:.3f} deg, Dec {tgt['dec_deg']:+.3f} deg"
    parts = [f'<div class="allsky-flight" style="{_CSS}">',
             (f'<div><b>allsky mission: <span style="color: {colour}">{_esc(shown)}</span>'
              f"</b> &mdash; target {_esc(name)}, seed {s['seed']}, "
              f"{s['mission_time_s']:.1f} s, propellant {s['propellant_kg']:.3f} kg</div>")]
    if j["tone"] == "amber":
        parts.append(f'<div class="allsky-judged" style="color: {colour}">&#9888; '
                     f'{_esc(j["first_warning"])}</div>')
    if s.get("abort_reason"):
        parts.append(f'<div style="color: #cf222e">abort reason: {_esc(s["abort_reason"])}'
                     "</div>")
    if s.get("warnings"):
        items = "".join(f"<li>{_esc(w)}</li>" for w in s["warnings"])
        parts.append(f'<div style="color: #9a6700"><b>Warnings ({len(s["warnings"])})</b>'
                     f'<ul style="margin: 2px 0">{items}</ul></div>')
    parts.append(_mode_strip(s["modes"]))
    rows = [[f"<b>{_esc(r['mode'])}</b>", f"{r['start_s']:.1f}", f"{r['end_s']:.1f}",
             f"{r['end_s'] - r['start_s']:.1f}", _esc(r["exit"])] for r in s["modes"]]
    parts.append("<details><summary>Mode timeline (the sequencer's judgement)</summary>"
                 + _table(["mode", "start [s]", "end [s]", "duration [s]", "exit"], rows,
                          left=(0, 4))
                 + "</details>")
    cal, truth = s.get("calibration"), s["truth"]
    if cal is not None:
        err = calibration_errors(cal, truth)
        applied = cal.get("drift_applied_deg_h", cal["drift_deg_h"])
        clipped = s.get("drift_dac_clipped") or {}
        never = unwritten(s)

        def row(entry, label, stored, applied_text, true, error):
            if entry in never:  # the power-on word: no measurement to hold to the truth
                return [label, f"<i>{_esc(never[entry])}</i>", "", true, ""]
            return [label, stored, applied_text, true, error]

        crows = [row(("drift_deg_h", a), f"drift {a} [deg/h]", _num(cal["drift_deg_h"][a], "+.4f"),
                     _num(applied[a], "+.4f") + (" <b>clipped</b>" if clipped.get(a) else ""),
                     _num(truth["drift_deg_h"][a], "+.4f"), _num(err["drift_deg_h"][a], "+.4f"))
                 for a in AXES]
        crows += [row(("scale_factor", a), f"scale factor {a} (error [ppm])",
                      _num(cal["scale_factor"][a], ".7f"), "",
                      _num(truth["scale_factor"][a], ".7f"),
                      _num(err["scale_factor_ppm"][a], "+.1f")) for a in SCALE_FACTOR_AXES]
        crows += [row(("cross_coupling", k), f"{k.replace('_', ' ')} [arcsec]",
                      _num(cal["cross_coupling"][k] * RAD2ARCSEC, "+.2f"), "",
                      _num(truth["cross_coupling"][k] * RAD2ARCSEC, "+.2f"),
                      _num(err["cross_coupling_arcsec"][k], "+.2f"))
                  for k in truth["cross_coupling"]]
        applied_note = "" if s.get("calibration_applied", True) else \
            " &mdash; <b>not applied</b> (calibration.apply = false)"
        parts.append(f"<div><b>Calibration</b> against the truth{applied_note}</div>"
                     + _table(["", "counted / stored", "applied", "truth", "error"], crows))
    end = s.get("end")
    if end is not None:
        rates = ", ".join(f"{a} {end['body_rate_deg_s'][a]:+.5f}" for a in AXES)
        final = "at the stop" if status == "running" else "at the end"
        parts.append(
            f"<div><b>What really happened</b> {final} (t = {end['t_s']:.1f} s, Mode "
            f"{_esc(end['mode'])}): true pointing error "
            f"<b>{end['true_pointing_error_arcsec']:.1f} arcsec</b> to {_esc(end['target'])}; "
            f"body rates [deg/s] {rates}; propellant used {end['propellant_kg']:.3f} kg "
            f"({end['propellant_remaining_kg']:.3f} kg left)</div>")
    planned, locked = s.get("reference_star"), s.get("locked_star")
    if locked is not None and locked != planned:
        parts.append(f'<div style="color: #cf222e">the tracker locked {_esc(locked)}, not the '
                     f"planned {_esc(planned)}</div>")
    parts.append("</div>")
    return "".join(parts)


