"""Mission state files: a mission saved at a mode boundary, and resumed from it.

A state file is a NumPy ``.npz`` archive holding the mission's
:meth:`~allsky.sim.mission.Mission.snapshot`: the history as one JSON
string (array ``history``) and each state array as ``state_<field>``
(:class:`allsky.sim.state.State`). The history carries its format number
(:data:`allsky.sim.mission.STATE_FORMAT`) and the scenario, so a file
resumes with nothing else. ``allsky step --save-dir`` writes them and
``allsky step --from`` reads them; :func:`load` refuses, as
:class:`StateError`, any file a mission did not save.
"""

import io
import json
import math
import os
import zipfile
from pathlib import Path

import numpy as np

from allsky.config import ConfigError, scenario_from_dict
from allsky.config.toml_io import os_reason, read_bounded
from allsky.hardware.wiring import SELECTORS
from allsky.sequencer.modes import PLANS, mission_plan
from allsky.sim import faults as sim_faults
from allsky.sim import state as sim_state
from allsky.sim.mission import STATE_FORMAT, Mission, newer_state_arrays

#: Prefix of the state arrays' names in the archive.
ARRAY_PREFIX = "state_"


def save(m: Mission, path, option="--save-dir") -> Path:
    """Save mission ``m`` at its current mode boundary to ``path`` (``.npz``).

    The archive is written under a temporary name beside ``path`` and then
    renamed over it, so ``path`` holds the old file or the new one, never
    half of one. A file that cannot be written is an
    :class:`~allsky.apps.output.OutputError` naming ``option``.
    """
    from allsky.apps.output import OutputError, write_reason

    path = Path(path)
    history, arrays = m.snapshot()
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tmp.open("wb") as f:  # a file object: numpy adds no ".npz" to the name
            np.savez(f, history=np.array(json.dumps(history)),
                     **{ARRAY_PREFIX + k: v for k, v in arrays.items()})
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise OutputError(option, path, write_reason(e)) from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


class StateError(ValueError):
    """A file that is not a mission state to resume; ``str()`` is one line.

    The message says what is wrong (the array, the history entry, the scenario
    key) and does not repeat the file's name, which the caller holds.
    """


#: Largest member of a state archive [bytes]: the history JSON is a few kB, the state
#: arrays a few hundred bytes; a bigger member is not a state (and is not unpacked).
MEMBER_MAX_BYTES = 16 * 2**20
#: Largest state file read, and the most its members may unpack to [bytes].
STATE_MAX_BYTES = 64 * 2**20
#: Largest departure of the saved quaternion from unit norm (the plant keeps 1e-15).
QUATERNION_NORM_TOLERANCE = 1e-6
#: State arrays added since files of this format were first written, with the value an
#: older file stands for (:func:`allsky.sim.mission.newer_state_arrays`): ``locked_star``
#: -1 (not recorded), ``fault_state`` no fault started, the reaction wheels at rest.
NEWER_ARRAYS = newer_state_arrays()
#: Statuses a saved mission can have.
STATUSES = ("running", "complete", "aborted")


def load(path, telemetry=True) -> Mission:
    """Resume the mission saved in ``path`` by :func:`save`, with its own scenario.

    Everything is checked before the mission is built: the archive, the
    history (format :data:`~allsky.sim.mission.STATE_FORMAT`, a plan of
    :data:`allsky.sequencer.modes.PLANS` as the scenario extends it with holds
    and further targets, the next mode inside it, the
    timeline of the modes flown, the scenario by its rules) and every state
    array (shape, dtype, finite; propellant within the tank, a unit
    quaternion, switches, valves and flags within their values).

    ``telemetry`` is passed to the mission (keep its telemetry from here on).

    Raises
    ------
    StateError
        One line saying what is wrong (the file is not named).
    """
    arrays, history = _read_archive(Path(path))
    cfg, plan = _checked_history(history)
    arrays = {**NEWER_ARRAYS, **arrays}
    _check_arrays(arrays, cfg)
    try:
        return Mission.from_snapshot({**history, "plan": list(plan)}, arrays,
                                     telemetry=telemetry)
    except (KeyError, IndexError, TypeError, ValueError) as e:  # a shape no check foresaw
        raise StateError(f"it does not resume ({type(e).__name__}: "
                         f"{' '.join(str(e).split())[:120]})") from None


def _read_archive(path):
    """The state arrays and the history of the ``.npz`` archive at ``path``."""
    try:
        data = read_bounded(path, STATE_MAX_BYTES, "mission state")
    except (OSError, ValueError) as e:  # missing, a directory, no permission, NUL in the name
        raise StateError(f"cannot read it: {os_reason(e) if isinstance(e, OSError) else e}"
                         ) from None
    if not data:
        raise StateError("an empty file")
    if not data.startswith(b"PK"):
        raise StateError("not an .npz archive (a zip of NumPy arrays)")
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            big = [i.filename for i in zf.infolist() if i.file_size > MEMBER_MAX_BYTES]
            if big:
                raise StateError(f"member {big[0]!r} is over {MEMBER_MAX_BYTES >> 20} MB")
            if sum(i.file_size for i in zf.infolist()) > STATE_MAX_BYTES:
                raise StateError(f"its members unpack to over {STATE_MAX_BYTES >> 20} MB")
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            members = {name: z[name] for name in z.files}
    except StateError:
        raise
    except Exception as e:  # noqa: BLE001 - a damaged archive fails in many ways (zip, zlib, npy)
        raise StateError(f"a damaged .npz archive ({type(e).__name__}: "
                         f"{' '.join(str(e).split())[:120]})") from None
    text = members.pop("history", None)
    if text is None:
        raise StateError("no history in the archive")
    if text.shape != () or text.dtype.kind != "U":
        raise StateError(f"history is a {text.dtype} array of shape {text.shape}, not one "
                         "JSON string")
    try:
        history = json.loads(str(text))
    except (ValueError, RecursionError) as e:
        raise StateError(f"history is not JSON ({' '.join(str(e).split())[:120]})") from None
    if not isinstance(history, dict):
        raise StateError("history is not a JSON object")
    unknown = [k for k in members if not k.startswith(ARRAY_PREFIX)]
    if unknown:
        raise StateError(f"unexpected member {unknown[0]!r} in the archive")
    return {k[len(ARRAY_PREFIX):]: v for k, v in members.items()}, history


#: Every key a mission's history holds (:meth:`allsky.sim.mission.Mission.snapshot`):
#: True for those every history has, False for those present only once flown or used.
HISTORY_KEYS = {"format": True, "next_mode": True, "plan": True, "timeline": True,
                "leg_count": True, "counted_arcsec": True, "status": True,
                "abort_reason": True, "programmed_roll_deg": True, "programmed_yaw_deg": True,
                "scenario": True, "events": True, "hold": False, "turn_roll_deg": False,
                "turn_yaw_deg": False, "reference_sun_inertial": False, "held_axes": False,
                "locked_star_name": False, "targets": False}


def _check_keys(h):
    unknown = sorted(k for k in h if k not in HISTORY_KEYS)
    if unknown:
        raise StateError(f"history: unknown key {_shown(unknown[0])} (a format "
                         f"{STATE_FORMAT} history has {', '.join(HISTORY_KEYS)})")
    missing = [k for k, needed in HISTORY_KEYS.items() if needed and k not in h]
    if missing:
        raise StateError(f"history: no {missing[0]} (every format {STATE_FORMAT} history "
                         "has it)")


def _check_events(events):
    """The journal so far: entries of known kinds at finite, ordered times."""
    from allsky.vocabulary import EVENT_KIND

    if not isinstance(events, list):
        raise StateError(f"events = {_shown(events)} is not a list of journal entries")
    last = 0.0
    for i, e in enumerate(events):
        if not isinstance(e, dict):
            raise StateError(f"events[{i}] = {_shown(e)} is not a journal entry (a table)")
        kind = e.get("kind")
        if not isinstance(kind, str) or kind not in EVENT_KIND:
            raise StateError(f"events[{i}].kind = {_shown(kind)} is not a journal kind "
                             "(docs/journal.md)")
        t = e.get("t_s")
        if not _finite(t) or t < last:
            raise StateError(f"events[{i}].t_s = {_shown(t)}: a finite time [s], never "
                             "before the entry before")
        if e.get("mode") is not None and not isinstance(e["mode"], str):
            raise StateError(f"events[{i}].mode = {_shown(e['mode'])} is not a mode's name")
        last = t


def _check_optional(h):
    for key in ("turn_roll_deg", "turn_yaw_deg"):
        if key in h and not _finite(h[key]):
            raise StateError(f"{key} = {_shown(h[key])} is not a finite number")
    for key in ("hold",):
        if key in h and not isinstance(h[key], dict):
            raise StateError(f"{key} = {_shown(h[key])} is not a table")
    if "targets" in h and not (isinstance(h["targets"], list) and h["targets"]
                               and all(isinstance(r, dict) for r in h["targets"])):
        raise StateError(f"targets = {_shown(h['targets'])} is not a list of target records")
    ref = h.get("reference_sun_inertial")
    if ref is not None and not (isinstance(ref, list) and len(ref) == 3
                                and all(map(_finite, ref))):
        raise StateError(f"reference_sun_inertial = {_shown(ref)} is not 3 finite numbers")
    if h.get("locked_star_name") is not None and not isinstance(h["locked_star_name"], str):
        raise StateError(f"locked_star_name = {_shown(h['locked_star_name'])} is not a name")


def _finite(x) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def _checked_history(h):
    """The scenario and plan of a history; StateError for anything a mission never saves."""
    if h.get("format") != STATE_FORMAT or type(h.get("format")) is not int:
        raise StateError(f"format {_shown(h.get('format'))}, not {STATE_FORMAT}")
    _check_keys(h)
    _check_events(h["events"])
    _check_optional(h)
    plan = tuple(h["plan"]) if isinstance(h.get("plan"), list) else None
    if plan not in _known_plans(h):
        known = "; ".join(f"{k}: {' '.join(v)}" for k, v in PLANS.items())
        raise StateError(f"plan {_shown(h.get('plan'))} is not a plan ({known})")
    n = h.get("next_mode")
    if type(n) is not int or not 0 <= n <= len(plan):
        raise StateError(f"next_mode = {_shown(n)} is not a mode of the plan (0..{len(plan)})")
    status = h.get("status")
    if status not in STATUSES:
        raise StateError(f"status = {_shown(status)} is not one of {', '.join(STATUSES)}")
    consistent = {"running": n < len(plan), "complete": n == len(plan), "aborted": n >= 1}
    if not consistent[status]:
        raise StateError(f"status = {status!r} with next_mode = {n} of {len(plan)} modes")
    timeline = h.get("timeline")
    if not isinstance(timeline, list) or len(timeline) != n:
        raise StateError(f"timeline must list the {n} modes flown")
    for i, rec in enumerate(timeline):
        ok = (isinstance(rec, list) and len(rec) == 4 and rec[0] == plan[i]
              and _finite(rec[1]) and _finite(rec[2]) and 0 <= rec[1] <= rec[2]
              and isinstance(rec[3], str))
        if not ok:
            raise StateError(f"timeline entry {i} is not [{plan[i]!r}, start_s, end_s, exit]: "
                             f"{_shown(rec)}")
    if type(h.get("leg_count")) is not int or h["leg_count"] < 0:
        raise StateError(f"leg_count = {_shown(h.get('leg_count'))} is not a count")
    counted = h.get("counted_arcsec")
    if not isinstance(counted, dict) or not all(
            axis in ("roll", "yaw") and isinstance(v, list) and len(v) == 3
            and all(map(_finite, v)) for axis, v in counted.items()):
        raise StateError(f"counted_arcsec = {_shown(counted)} is not the counted angles "
                         "(roll, yaw: 3 numbers each)")
    for key in ("programmed_roll_deg", "programmed_yaw_deg"):
        if h.get(key) is not None and not _finite(h[key]):
            raise StateError(f"{key} = {_shown(h[key])} is not a finite number")
    if h.get("abort_reason") is not None and not isinstance(h["abort_reason"], str):
        raise StateError(f"abort_reason = {_shown(h['abort_reason'])} is not text")
    try:
        cfg = scenario_from_dict(h.get("scenario"))
    except ConfigError as e:
        raise StateError(f"its scenario: {e}") from None
    return cfg, plan


def _known_plans(h) -> list:
    """The plans of ``PLANS``, and each as the history's scenario extends it.

    A scenario extends a plan with the hold on target and with the modes
    that fly each further target (:func:`allsky.sequencer.modes.mission_plan`).
    """
    plans = list(PLANS.values())
    try:
        cfg = scenario_from_dict(h.get("scenario"))
    except ConfigError:  # reported with the scenario's own words below
        return plans
    return plans + [mission_plan(p, cfg) for p in PLANS.values()]


def _shown(v, limit=60) -> str:
    text = repr(v)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _check_arrays(arrays, cfg):
    """Every state array as :func:`allsky.sim.state.new_state` makes it, with values a
    mission can hold."""
    template = sim_state.new_state(np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3), 1.0)
    for name, like in template._asdict().items():
        a = arrays.get(name)
        if a is None:
            raise StateError(f"no state array {ARRAY_PREFIX}{name}")
        if a.shape != like.shape or a.dtype != like.dtype:
            raise StateError(f"{ARRAY_PREFIX}{name} is {a.dtype} of shape {a.shape}, not "
                             f"{like.dtype} of shape {like.shape}")
        if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
            raise StateError(f"{ARRAY_PREFIX}{name} holds {a[~np.isfinite(a)][0]}: the state "
                             "is finite")
    extra = sorted(set(arrays) - set(template._fields))
    if extra:
        raise StateError(f"unexpected array {ARRAY_PREFIX}{extra[0]}")
    tank = float(cfg.jets.propellant_kg)
    left = float(arrays["propellant_kg"][0])
    if not 0.0 <= left <= tank:
        raise StateError(f"{ARRAY_PREFIX}propellant_kg = {left!r}: must be within 0..{tank:g} "
                         "kg (jets.propellant_kg, the tank at ejection)")
    if arrays["frame"][0] < 0:
        raise StateError(f"{ARRAY_PREFIX}frame (the mission clock) must be >= 0")
    q = arrays["x"][0:4]
    with np.errstate(over="ignore"):  # a norm past the float range is inf: refused below
        norm = float(np.linalg.norm(q))
    if not abs(norm - 1.0) <= QUATERNION_NORM_TOLERANCE:
        raise StateError(f"{ARRAY_PREFIX}x: quaternion {q.tolist()} is not of unit norm "
                         f"(within {QUATERNION_NORM_TOLERANCE:g})")
    sw = arrays["switches"]
    limits = np.ones(sw.shape, dtype=int)
    limits[list(SELECTORS)] = 2  # a selector holds the axis 0, 1 or 2
    if np.any(sw > limits):
        k = int(np.flatnonzero(sw > limits)[0])
        raise StateError(f"{ARRAY_PREFIX}switches: S{k} = {int(sw[k])} (an on/off switch is "
                         "0 or 1, a selector 0, 1 or 2)")
    fs = arrays["fault_state"]
    onsets = fs[sim_faults.ONSET]
    if not np.all((onsets == sim_faults.UNKNOWN) | (onsets >= 0.0)) \
            or not np.all(np.isin(fs[sim_faults.LATCHED], (0.0, 1.0))):
        raise StateError(f"{ARRAY_PREFIX}fault_state: onsets must be >= 0 s or "
                         f"{sim_faults.UNKNOWN:g} (not started), latches 0 or 1")
    from allsky.sim import journal as sim_journal
    from allsky.sim.mission import tracker_star_names

    filled, lost = (int(v) for v in arrays["journal_n"][:2])
    rows = arrays["journal"].shape[0]
    if not (0 <= filled <= rows and lost >= 0):
        raise StateError(f"{ARRAY_PREFIX}journal_n = {arrays['journal_n'].tolist()}: rows "
                         f"filled within 0..{rows} (the journal buffer), rows lost >= 0")
    codes = {k.code for k in sim_journal.EVENT_KIND.values()}
    bad = [r for r in arrays["journal"][:filled, sim_journal.KIND] if int(r) not in codes]
    if bad:
        raise StateError(f"{ARRAY_PREFIX}journal: a row of kind code {bad[0]!r}, not a journal "
                         "kind")
    stars = len(tracker_star_names(cfg))
    k = int(arrays["locked_star"][0])
    if not -1 <= k < stars:
        raise StateError(f"{ARRAY_PREFIX}locked_star = {k}: -1 (none) or a star of the "
                         f"tracker's catalog, 0..{stars - 1}")
    for name, allowed in (("rate_sign", (-1, 1)), ("pwpf_out", (-1, 0, 1)),
                          ("overflow", (0, 1))):
        if not np.all(np.isin(arrays[name], allowed)):
            raise StateError(f"{ARRAY_PREFIX}{name} = {arrays[name].tolist()}: each must be "
                             f"one of {', '.join(map(str, allowed))}")
