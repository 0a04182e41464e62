"""The live progress line: it shows the modes under way and never changes the flight."""

import io

from allsky.apps import progress, states
from allsky.sim.mission import Mission


def test_progress_line_names_each_mode_and_the_flight_is_unchanged(default_cfg, saved_states):
    m = Mission(default_cfg, telemetry=False)
    out = io.StringIO()
    summary = progress.fly(m, stream=out)
    text = out.getvalue()
    assert summary == saved_states["mission"].summary()
    for name in m.plan:
        assert f"Mode {name} " in text
    # Compiled already in this process (the fixtures flew missions): no compile note.
    assert "compiling" not in text
    # Refreshed every PROGRESS_EVERY_S of mission time: about 1323 s / 20 s lines.
    assert text.count(" s |") >= int(summary["mission_time_s"] / progress.PROGRESS_EVERY_S)


def test_quiet_writes_nothing(default_cfg):
    m = Mission(default_cfg, telemetry=False)
    out = io.StringIO()
    assert progress.fly(m, quiet=True, stream=out)["status"] == "complete"
    assert out.getvalue() == ""


def test_resumed_mission_counts_from_its_next_mode(saved_states):
    m = states.load(saved_states["6-1"], telemetry=False)
    out = io.StringIO()
    progress.fly(m, stream=out)
    assert "5/7 modes" in out.getvalue() and "Mode 5 " not in out.getvalue()


def test_run_json_dash_prints_the_summary_alone_on_stdout(capsys, saved_states):
    import json

    from allsky.apps import cli

    assert cli.main(["run", "--json", "-"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out) == {
        "format": 1, **json.loads(json.dumps(saved_states["mission"].summary()))}
    assert captured.err == ""  # no progress line either


def test_run_quiet_keeps_the_report(capsys):
    from allsky.apps import cli

    assert cli.main(["run", "--quiet"]) == 0
    captured = capsys.readouterr()
    assert captured.out.startswith("allsky mission: complete")
    assert captured.err == ""


def test_compile_note_only_when_the_frame_loop_is_compiled(default_cfg, monkeypatch):
    monkeypatch.setattr(progress, "frame_loop_needs_compiling", lambda params=None: True)
    out = io.StringIO()
    progress.fly(Mission(default_cfg, telemetry=False), stream=out)
    text = out.getvalue()
    assert "Mode 1 Sun orientation, t = 0 s (compiling the frame loop on first use, once)" in text
    assert text.count("compiling") == 1  # the first description only


def test_compile_note_alone_when_stderr_is_not_a_terminal(default_cfg, monkeypatch, capsys):
    monkeypatch.setattr(progress, "frame_loop_needs_compiling", lambda params=None: True)
    progress.fly(Mission(default_cfg, telemetry=False))
    captured = capsys.readouterr()
    assert captured.err == f"allsky: {progress.COMPILE_NOTE}\n"
    assert captured.out == ""
    progress.fly(Mission(default_cfg, telemetry=False), quiet=True)
    assert capsys.readouterr().err == ""


_ZERO_SIZE_TERMINAL = """
import fcntl, os, struct, sys, termios
fcntl.ioctl(2, termios.TIOCSWINSZ, struct.pack("HHHH", 0, 0, 0, 0))
from allsky.apps import cli
sys.exit(cli.main(["run"]))
"""


@__import__("pytest").mark.skipif(__import__("os").name != "posix", reason="needs a pty")
def test_a_terminal_of_zero_size_gets_a_line():
    """A terminal that reports 0 x 0 (some containers): tqdm alone would show nothing."""
    import os
    import pty
    import sys

    pid, fd = pty.fork()
    if pid == 0:  # the child: stdin, stdout and stderr are the terminal
        os.execv(sys.executable, [sys.executable, "-c", _ZERO_SIZE_TERMINAL])
    out = b""
    while True:
        try:
            data = os.read(fd, 65536)
        except OSError:  # the child closed the terminal
            break
        if not data:
            break
        out += data
    _, status = os.waitpid(pid, 0)
    os.close(fd)
    text = out.decode(errors="replace")
    assert os.waitstatus_to_exitcode(status) == 0
    assert "Mode 1 Sun orientation, t = 0 s" in text and "/7 modes" in text


def _needs_compiling_in_a_new_process(env):
    import os
    import subprocess
    import sys

    code = "from allsky.apps import progress; print(progress.frame_loop_needs_compiling())"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**os.environ, **env}, check=True)
    return done.stdout.strip()


@__import__("pytest").mark.skipif(__import__("os").environ.get("NUMBA_DISABLE_JIT") == "1",
                                  reason="nothing is compiled without the JIT")
def test_compile_detection_reads_numba_cache(default_cfg, tmp_path):
    """An empty cache directory means a compile; the cache this process wrote means none.

    (With the loop built ahead of time at install, allsky.aot, nothing compiles at all:
    ALLSKY_AOT=0 asks for numba's loop here.)
    """
    Mission(default_cfg, telemetry=False).run_mode()  # compiled and cached here, if not yet
    assert progress.frame_loop_needs_compiling() is False  # compiled in this process
    jit_only = {"ALLSKY_AOT": "0"}
    assert _needs_compiling_in_a_new_process(
        {**jit_only, "NUMBA_CACHE_DIR": str(tmp_path)}) == "True"
    assert _needs_compiling_in_a_new_process(jit_only) == "False"


def test_progress_line_moves_with_the_slices(default_cfg, monkeypatch):
    """Within a leg longer than a slice, the line shows the mission time between pauses."""
    from allsky.sim import mission

    monkeypatch.setattr(mission, "SLICE_FRAMES", 700)  # 7 s of mission time
    monkeypatch.setattr(progress, "PROGRESS_EVERY_S", 1e9)  # no stepping pauses
    out = io.StringIO()
    summary = progress.fly(Mission(default_cfg, telemetry=False), stream=out)
    shown = {int(t) for t in __import__("re").findall(r"t = (\d+) s", out.getvalue())}
    assert len(shown) >= summary["mission_time_s"] / 7.0 - len(summary["modes"]) * 2
