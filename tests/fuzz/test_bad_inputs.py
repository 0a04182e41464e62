"""The campaign kept: seeded bad inputs of every class against the commands that read them.

A seeded generator (:func:`campaign`) makes bad inputs of each class a user
can hand allsky -- scenario files, ``--disperse`` specs, command logs,
mission summaries, telemetry files, state files and paths -- by mutating a
valid file (bytes flipped, cut short, fields of the wrong type, nesting
past any bound, format numbers, control characters) and feeds each to the
command that reads it, as the ``allsky`` command line does (``main``).
Whatever the input, the command answers: exit 0, 1 or 2, never 3, never a
traceback; exit 2 is one line ``allsky: error: ...`` with no raw control
character. Flying is replaced by a stub (a valid input is accepted, not
flown), so the campaign measures the readers. A short campaign runs by
default; the long one (``-m slow``) gives the counts in docs/validation.md.
"""

import hashlib
import json
import random

import numpy as np
import pytest

from allsky.apps import telemetry_files
from allsky.apps.cli import main
from allsky.apps.output import OutputError
from allsky.config import load_scenario
from allsky.sim.mission import Mission

CLASSES = ("scenario", "disperse", "commands", "summary", "telemetry", "state", "path")
#: Inputs per class: the default run, and the long campaign.
SHORT, LONG = 12, 210


class Valid:
    """Valid files of each class, made once, that the mutations start from."""

    def __init__(self, tmp, saved_states):
        m = saved_states["mission"]
        self.scenario = load_scenario().to_toml().encode()
        self.disperse = (b'[dispersions]\ngyro.drift_deg_h = { dist = "normal", sigma = 0.5 }\n'
                         b'jets.thrust_n = { dist = "uniform", low = 0.2, high = 0.3 }\n')
        self.commands = (b'format = 1\n\n[[commands]]\nt_s = 3.0\nkind = "speed"\nspeed = 5.0\n'
                         b'\n[[commands]]\nt_s = 9.0\nkind = "end"\n')
        self.summary = json.dumps({"format": 1, **m.summary()}).encode()
        tlm = tmp / "t.csv"
        telemetry_files.write(tlm, m.telemetry()[:40])
        self.tlm_path = tlm
        self.telemetry = tlm.read_bytes()
        self.state = saved_states["5"].read_bytes()


def _flip(rng, data: bytes) -> bytes:
    b = bytearray(data)
    for _ in range(rng.randint(1, 12)):
        if b:
            b[rng.randrange(len(b))] = rng.randrange(256)
    return bytes(b)


def _cut(rng, data: bytes) -> bytes:
    lines = data.splitlines(keepends=True)
    if rng.random() < 0.5 and len(lines) > 2:  # at a line boundary
        return b"".join(lines[: rng.randrange(1, len(lines))])
    return data[: rng.randrange(len(data))]


VALUES = ["[]", "{}", "-1e999", '""', "true", "[[1]]", "1979-05-27"]


def _toml_nasty(rng) -> bytes:
    depth = rng.choice([65, 500, 20000])
    value = rng.choice(VALUES)
    return rng.choice([
        ("[" + ".".join(["a"] * depth) + "]\n").encode(),
        ("x = " + "[" * depth + "]" * depth + "\n").encode(),
        ("x = " + "{a = " * min(depth, 900) + "1" + "}" * min(depth, 900) + "\n").encode(),
        ("a." * depth + "b = 1\n").encode(),
        b"[mission]\nseed = " + b"9" * rng.choice([30, 5000]) + b"\n",
        b"[mission]\nseed = \"\x00\"\n", b"\xff\xfe[mission]\n", b"[[mission]]\nseed = 1\n",
        f"[{rng.choice(['gyro', 'jets', 'mission', 'target'])}]\n"
        f"{rng.choice(['seed', 'drift_deg_h', 'thrust_n', 'star', 'x'])} = "
        f"{value}\n".encode(),
    ])


def _json_mutant(rng, text: bytes) -> bytes:
    data = json.loads(text)
    keys = list(data)
    junk = [None, True, -1, 1e308, "x", [], {}, [1, [2]], {"a": {"b": 1}}, 2**70]
    for _ in range(rng.randint(1, 3)):
        k = rng.choice(keys)
        data[k] = rng.choice(junk)
    if rng.random() < 0.3:
        data["format"] = rng.choice([0, 2, "1", 1.0, None])
    if rng.random() < 0.1:
        return ("[" * 30000 + "]" * 30000).encode()
    return json.dumps(data).encode()


def _log_mutant(rng, text: bytes) -> bytes:
    kinds = ['["speed"]', '{a = 1}', '"nope"', "1", '"end"', '"hold"', '"fault"']
    choice = rng.random()
    if choice < 0.3:
        return text.replace(b'kind = "speed"', f"kind = {rng.choice(kinds)}".encode())
    if choice < 0.45:
        return text.replace(b"format = 1\n", rng.choice([b"", b"format = 2\n",
                                                         b'format = "1"\n']))
    if choice < 0.6:
        return text.replace(b"t_s = 9.0", rng.choice([b"t_s = -1.0", b"t_s = nan",
                                                       b"t_s = 1.0", b't_s = "9"']))
    return _flip(rng, text)


def _state_mutant(rng, data: bytes, tmp) -> bytes:
    import io

    with np.load(io.BytesIO(data), allow_pickle=False) as z:
        members = {k: z[k] for k in z.files}
    history = json.loads(str(members["history"]))
    choice = rng.random()
    if choice < 0.3:
        events = history["events"]
        if events:
            e = events[rng.randrange(len(events))]
            e.pop(rng.choice(list(e)), None)
    elif choice < 0.5:
        k = rng.choice(list(history))
        history[k] = rng.choice([None, -1, "x", [], {}, 1e308, [[1]]])
    elif choice < 0.8:
        name = rng.choice([k for k in members if k != "history"])
        a = members[name].copy()
        if a.size:
            value = rng.choice([10**6, -5, 3, 2**40]) if a.dtype.kind in "iu" else (
                rng.choice([np.nan, 1e300, -1.0, 7.0]))
            a.flat[rng.randrange(a.size)] = np.array(value).astype(a.dtype)
        members[name] = a
    else:
        return _flip(rng, data)
    members["history"] = np.array(json.dumps(history))
    buf = io.BytesIO()
    np.savez(buf, **members)
    return buf.getvalue()


def _path_case(rng, tmp, valid):
    """A command line whose paths are bad: (argv, files to write)."""
    ctrl = "".join(rng.choice(["\x1b[2J", "\x07", "\r", "\t", "\x00", "\x7f"]) for _ in range(2))
    scen = tmp / "s.toml"
    return rng.choice([
        ["run", "--json", str(tmp / f"no{ctrl}dir" / "x.json")],
        ["run", "--telemetry", str(tmp / f"t{ctrl}.txt")],
        ["config", "check", str(tmp / f"missing{ctrl}.toml")],
        ["run", str(scen), "--json", str(scen)],
        ["run", "--json", str(tmp), "--quiet"],
        ["serve", "--no-browser", "--save-commands", str(tmp / "a.toml"), "--json",
         str(tmp / "a.toml")],
        ["plot", str(tmp / f"{ctrl}.csv")],
        ["replay", str(valid.tlm_path), "--html", str(valid.tlm_path)],
        ["step", "--from", str(tmp / f"x{ctrl}.npz")],
    ])


def campaign(n_per_class, seed, tmp, valid):
    """Yield ``(class, argv, bytes)`` bad inputs, ``n_per_class`` of each class, seeded."""
    rng = random.Random(seed)
    for cls in CLASSES:
        for k in range(n_per_class):
            d = tmp / f"{cls}{k}"
            d.mkdir()
            if cls == "path":
                (d / "s.toml").write_bytes(b"")
                argv = _path_case(rng, d, valid)
                yield cls, argv, "\0".join(argv).encode()
                continue
            r = rng.random()
            if cls in ("scenario", "disperse"):
                base = valid.scenario if cls == "scenario" else valid.disperse
                data = (_toml_nasty(rng) if r < 0.4 else _flip(rng, base) if r < 0.7
                        else _cut(rng, base))
                path = d / "in.toml"
                argv = (["config", "check", str(path)] if cls == "scenario"
                        else ["run", "--quiet", "--disperse", str(path)])
            elif cls == "commands":
                data = _log_mutant(rng, valid.commands) if r < 0.7 else _toml_nasty(rng)
                path = d / "log.toml"
                argv = ["run", "--quiet", "--commands", str(path)]
            elif cls == "summary":
                data = (_json_mutant(rng, valid.summary) if r < 0.6 else _flip(rng, valid.summary)
                        if r < 0.8 else _cut(rng, valid.summary))
                path = d / "s.json"
                argv = ["replay", str(valid.tlm_path), "--summary", str(path), "--html",
                        str(d / "r.html")]
            elif cls == "telemetry":
                data = _flip(rng, valid.telemetry) if r < 0.5 else _cut(rng, valid.telemetry)
                path = d / "t.csv"
                argv = ["replay", str(path), "--html", str(d / "r.html")]
            else:
                data = _state_mutant(rng, valid.state, d)
                path = d / "s.npz"
                argv = ["step", "--no-pause", "--from", str(path)]
            path.write_bytes(data)
            yield cls, argv, data


@pytest.fixture()
def no_flight(monkeypatch):
    """Flying (and serving) is a stub: a valid input is accepted, answered exit 2 'flown'."""
    def flown(*a, **k):
        raise OutputError("--stub", "-", "flown")

    monkeypatch.setattr(Mission, "run_mode", flown)
    from allsky.apps import serve

    monkeypatch.setattr(serve, "run_from_cli", flown)


def _answer(capsys, argv):
    code = main(argv)
    _, err = capsys.readouterr()
    assert code in (0, 1, 2), (argv, code, err)
    assert "Traceback" not in err, (argv, err)
    if code == 2:
        assert err.startswith("allsky: error:") and err.count("\n") == 1, (argv, err)
        assert not any(ord(c) < 32 and c != "\n" for c in err), (argv, err)
    return "accepted" if (code != 2 or "flown" in err) else "refused"


def run_campaign(n, seed, tmp_path, saved_states, capsys):
    valid = Valid(tmp_path, saved_states)
    seen, counts = set(), {}
    for cls, argv, data in campaign(n, seed, tmp_path, valid):
        verdict = _answer(capsys, argv)
        seen.add(hashlib.sha256(cls.encode() + b"\0" + data).hexdigest())
        counts.setdefault(cls, {"accepted": 0, "refused": 0})[verdict] += 1
    return len(seen), counts


def test_short_campaign(tmp_path, saved_states, capsys, no_flight):
    distinct, counts = run_campaign(SHORT, "allsky bad inputs", tmp_path, saved_states, capsys)
    assert distinct >= 0.8 * SHORT * len(CLASSES)
    assert all(c["refused"] for c in counts.values())


@pytest.mark.slow
def test_long_campaign(tmp_path, saved_states, capsys, no_flight):
    """At least 1000 distinct bad inputs; the counts go to docs/validation.md."""
    distinct, counts = run_campaign(LONG, "allsky long campaign", tmp_path, saved_states,
                                    capsys)
    with capsys.disabled():
        print(f"\nbad inputs: {distinct} distinct; {json.dumps(counts)}")
    assert distinct >= 1000
