"""Ctrl-C, SIGTERM and SIGHUP at random moments of every command: one line, no traceback.

Each command runs as the ``allsky`` command does (``python -m allsky``, its
own session, SIGINT's disposition reset to the default as a terminal's
foreground job has it). At a moment drawn from a seeded generator,
between its start and about its end, it gets SIGINT (sent to its whole
process group, workers included, as a terminal's Ctrl-C is), SIGHUP (to the
group, as a closed terminal sends it) or SIGTERM (to the command alone),
sometimes twice. Whatever the moment, it ends with
0, 1 or 130; with 130 its last line is ``allsky: interrupted; ...``; there
is no traceback, no temporary file, no JSON file cut short, and no worker
left behind. The moments are drawn, not timed: every outcome is checked,
whichever one the machine's load gives.

A signal can arrive before any line of allsky has run, while Python itself
starts; the command cannot handle it there. The child is therefore started
with SIGINT and SIGTERM blocked, as a launcher that cares would start it;
allsky's first line installs its handler and unblocks them, so a signal
sent in those first milliseconds is handled there (the promised line,
exit 130) instead of being lost or shown as Python's traceback.
"""

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src"

#: Each command, with its arguments and about how long it takes here [s] (the span the
#: moments are drawn from; a signal after its end finds it done, which is checked too).
COMMANDS = {
    "help": (["--help"], 0.3),
    "config show": (["config", "show"], 0.5),
    "config check": (["config", "check", "--set", "mission.seed=2"], 0.5),
    "stars": (["stars", "--json", "stars.json"], 1.0),
    "scenarios": (["scenarios", "--json", "scenarios.json"], 0.5),
    "run": (["run", "--json", "s.json", "--telemetry", "t.csv"], 2.0),
    "step": (["step", "--no-pause", "--until", "2", "--json", "step.json"], 2.0),
    "compare": (["compare", "--runs", "2", "--workers", "2", "--json", "c.json"], 6.0),
    "montecarlo": (["montecarlo", "--runs", "12", "--workers", "2", "--out", "mc"], 5.0),
    "faults": (["faults", "--kinds", "gyro_dead", "--modes", "4,5", "--json", "f.json"], 4.0),
    "analyze": (["analyze", "--json", "a.json"], 3.0),
    "plot": (["plot", "{tlm}", "--out", "figs"], 5.0),
    "replay": (["replay", "{tlm}", "--html", "r.html"], 3.0),
    "warm-up": (["warm-up"], 3.0),
}
#: [s] Bound on a command's life after its signal (liveness only; never reached when sound).
GRACE_S = 120


@pytest.fixture(scope="module")
def telemetry(tmp_path_factory):
    path = tmp_path_factory.mktemp("tlm") / "t.csv"
    from allsky.apps.cli import main

    assert main(["run", "--quiet", "--telemetry", str(path)]) == 0
    return path


def _start_blocked():
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM, signal.SIGHUP})


def _env():
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "COLUMNS")}
    return {**env, "PYTHONPATH": str(SRC)}


def _session_gone(pgid) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return True
    except PermissionError:
        return False
    return False


def interrupt(argv, workdir: Path, rng: random.Random, span_s: float):
    """Run ``allsky argv`` in ``workdir``, signal it at a drawn moment; check the outcome."""
    sig = rng.choice([signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
    delay = rng.uniform(0.0, span_s)
    twice = rng.random() < 0.25
    proc = subprocess.Popen([sys.executable, "-m", "allsky", *argv], cwd=workdir, env=_env(),
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE,
                            preexec_fn=_start_blocked,  # noqa: PLW1509 - sigprocmask only, no lock taken
                            start_new_session=True)
    what = f"{' '.join(argv)}: {signal.Signals(sig).name} at {delay:.3f} s"
    sent = 0
    try:
        try:
            proc.wait(timeout=delay)
        except subprocess.TimeoutExpired:
            for _ in range(2 if twice else 1):
                if proc.poll() is not None:
                    break
                try:
                    if sig in (signal.SIGINT, signal.SIGHUP):
                        # Ctrl-C, or the terminal closed: the whole foreground group
                        os.killpg(proc.pid, sig)
                    else:
                        proc.send_signal(sig)
                except ProcessLookupError:
                    break
                sent += 1
                if twice:
                    time.sleep(rng.uniform(0.0, 0.3))
        _, err = proc.communicate(timeout=GRACE_S)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    text = err.decode("utf-8", "replace")
    assert proc.returncode in (0, 1, 130), (what, proc.returncode, text)
    assert "Traceback" not in text and "Error:" not in text.replace("allsky: error:", ""), (
        what, text)
    lines = text.strip().splitlines()
    assert all(line.startswith("allsky: ") for line in lines), (what, text)
    if proc.returncode == 130:
        assert lines and lines[-1].startswith("allsky: interrupted"), (what, text)
        assert sum(line.startswith("allsky: interrupted") for line in lines) == 1, (what, text)
    deadline = time.monotonic() + 10  # liveness bound: the workers end with their parent
    while not _session_gone(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _session_gone(proc.pid), (what, "a process of the command outlived it")
    for path in workdir.rglob("*"):
        assert ".tmp" not in path.name, (what, path)
        if path.suffix == ".json" and path.is_file():
            json.loads(path.read_text())  # whole, or not there at all
    return proc.returncode, sent


def _argv(name, telemetry):
    argv, span = COMMANDS[name]
    return [str(telemetry) if a == "{tlm}" else a for a in argv], span


@pytest.mark.parametrize("name", list(COMMANDS))
def test_a_signal_at_a_random_moment(name, telemetry, tmp_path):
    rng = random.Random(f"allsky signals {name}")
    argv, span = _argv(name, telemetry)
    interrupt(argv, tmp_path, rng, span)


@pytest.mark.parametrize("name", ["run", "montecarlo", "compare"])
def test_a_signal_in_the_first_milliseconds(name, telemetry, tmp_path):
    """Before allsky's first line and while its modules load: the line and 130, or done."""
    rng = random.Random(f"allsky early {name}")
    argv, _ = _argv(name, telemetry)
    interrupt(argv, tmp_path, rng, 0.05)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(COMMANDS))
def test_many_signals_at_random_moments(name, telemetry, tmp_path):
    """The long campaign: a dozen drawn moments per command (about 170 signals in all)."""
    rng = random.Random(f"allsky many signals {name}")
    argv, span = _argv(name, telemetry)
    codes = []
    for k in range(12):
        workdir = tmp_path / str(k)
        workdir.mkdir()
        codes.append(interrupt(argv, workdir, rng, span * 1.2)[0])
    assert set(codes) <= {0, 1, 130}


def test_the_handler_imports_nothing(monkeypatch):
    """A signal that arrives during an import is sent again, with no import of its own.

    Python 3.11's module locks are not re-entrant: an import inside the
    handler, in the middle of another (``threading`` itself may be the module
    half imported), breaks the one under way with a ``KeyError`` in importlib
    or a partially initialised module. So the handler's path for a signal
    inside an import must call no ``__import__`` at all.
    """
    import builtins

    from allsky.apps import cli

    imported = []
    real = builtins.__import__

    def recording(name, *args, **kwargs):
        imported.append(name)
        return real(name, *args, **kwargs)

    def frame_in_import():
        code = compile("import sys\nframe = sys._getframe()", "<frozen importlib._bootstrap>",
                       "exec")
        space = {}
        exec(code, space)  # noqa: S102 - a frame named as importlib's, for the handler to see
        return space["frame"]

    frame = frame_in_import()
    monkeypatch.setattr(cli, "_running", [True])  # a command under way
    monkeypatch.setattr(cli, "_resend", lambda signum: None)  # its thread sends nothing here
    monkeypatch.setattr(cli, "_signalled", [])
    builtins.__import__ = recording
    try:
        cli._interrupt(signal.SIGTERM, frame)
    finally:
        builtins.__import__ = real
    assert imported == []
    assert cli._signalled == [signal.SIGTERM]


def test_a_signal_after_the_command_changes_nothing(monkeypatch):
    """Between the command's end and its handlers' restoring, the handler raises nothing."""
    from allsky.apps import cli

    monkeypatch.setattr(cli, "_running", [])
    monkeypatch.setattr(cli, "_signalled", [])
    assert cli._interrupt(signal.SIGHUP, None) is None
    assert cli._signalled == []
    monkeypatch.setattr(cli, "_running", [True])
    with pytest.raises(KeyboardInterrupt):
        cli._interrupt(signal.SIGHUP, None)
