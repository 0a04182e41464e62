"""Output paths: regular files replaced whole, anything else written in place, nothing clobbered.

``write_atomic`` against every kind of path a user may give (a new file, a
regular one, a symbolic link, a dangling one, a FIFO, a character device
made with mknod in a temporary directory, a descriptor path, a full disk),
and the command line against the same kinds, two options on one path, and
stdout that is closed or whose reader went away. Every answer is 0, 1, 2 or
141 with at most one error line, and no node is replaced by a file.
"""

import errno
import json
import os
import stat
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from allsky.apps import cli, output
from allsky.apps.output import OutputError, check_distinct, check_output, write_atomic

SRC = Path(__file__).resolve().parents[2] / "src"
ROOT_ONLY = pytest.mark.skipif(os.geteuid() != 0, reason="mknod and mount need root")


def _null_device(path):
    """A character device node at ``path`` with /dev/null's numbers (skip where not allowed)."""
    try:
        os.mknod(path, 0o666 | stat.S_IFCHR, os.stat(os.devnull).st_rdev)
    except (PermissionError, OSError) as e:
        pytest.skip(f"cannot make a device node here ({e.strerror})")
    return path


def _full_device(path):
    try:
        os.mknod(path, 0o666 | stat.S_IFCHR, os.stat("/dev/full").st_rdev)
    except (PermissionError, OSError, FileNotFoundError) as e:
        pytest.skip(f"cannot make /dev/full's node here ({getattr(e, 'strerror', e)})")
    return path


def _read_fifo(path, into):
    with open(path, "rb") as f:
        into.append(f.read())


def _no_temporaries(directory):
    assert not [p.name for p in Path(directory).iterdir() if ".tmp" in p.name]


# -- write_atomic -------------------------------------------------------------------------------

def test_a_regular_file_is_replaced_whole(tmp_path):
    target = tmp_path / "a.json"
    target.write_text("old")
    inode = target.stat().st_ino
    write_atomic(target, "new")
    assert target.read_text() == "new" and target.stat().st_ino != inode  # a new file
    _no_temporaries(tmp_path)


def test_a_symlink_is_followed_and_stays_a_link(tmp_path):
    real = tmp_path / "real" / "a.json"
    real.parent.mkdir()
    real.write_text("old")
    link = tmp_path / "link.json"
    link.symlink_to(real)
    write_atomic(link, "new")
    assert link.is_symlink() and os.readlink(link) == str(real)
    assert real.read_text() == "new"
    _no_temporaries(tmp_path)
    _no_temporaries(real.parent)


def test_a_dangling_symlink_makes_its_target(tmp_path):
    link = tmp_path / "link.json"
    link.symlink_to(tmp_path / "made.json")
    write_atomic(link, "x")
    assert link.is_symlink() and (tmp_path / "made.json").read_text() == "x"


def test_a_fifo_is_written_in_place(tmp_path):
    fifo = tmp_path / "p.csv"
    os.mkfifo(fifo)
    got = []
    reader = threading.Thread(target=_read_fifo, args=(fifo, got))
    reader.start()
    write_atomic(fifo, writer=lambda tmp: Path(tmp).write_text("a,b\n"))
    reader.join(timeout=30)
    assert got == [b"a,b\n"] and stat.S_ISFIFO(os.stat(fifo).st_mode)
    _no_temporaries(tmp_path)


def test_a_descriptor_path_is_written_through_the_descriptor(tmp_path):
    read_end, write_end = os.pipe()
    try:
        write_atomic(f"/dev/fd/{write_end}", "through the pipe\n")
        os.close(write_end)
        assert os.read(read_end, 100) == b"through the pipe\n"
    finally:
        os.close(read_end)
    assert output.descriptor_of("/dev/stdout") == 1 and output.descriptor_of("/proc/self/fd/7") == 7
    link = tmp_path / "out"
    link.symlink_to("/dev/stderr")
    assert output.descriptor_of(link) == 2


@ROOT_ONLY
def test_a_device_node_stays_a_device(tmp_path):
    node = _null_device(tmp_path / "null")
    write_atomic(node, "discarded")
    assert stat.S_ISCHR(os.stat(node).st_mode)
    _no_temporaries(tmp_path)


@ROOT_ONLY
def test_a_full_device_is_one_error_naming_the_option_and_says_it_is_cut(tmp_path):
    node = _full_device(tmp_path / "full")
    with pytest.raises(OutputError) as e:
        write_atomic(node, "x" * 10, option="--json")
    assert str(e.value) == f"--json: cannot write {node}: no space left on the device"
    assert str(node) in output.torn_writes()
    assert stat.S_ISCHR(os.stat(node).st_mode)
    output._torn.clear()


@ROOT_ONLY
def test_a_full_disk_leaves_the_old_file_and_no_temporary(tmp_path):
    mnt = tmp_path / "small"
    mnt.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mnt)],
                          capture_output=True, check=False)
    if done.returncode != 0:
        pytest.skip("cannot mount a small tmpfs here")
    try:
        target = mnt / "t.json"
        target.write_text("old")
        with pytest.raises(OutputError, match="no space left on the device"):
            write_atomic(target, "x" * 200_000, option="--json")
        assert target.read_text() == "old"
        _no_temporaries(mnt)
        assert output.torn_writes() == []
    finally:
        subprocess.run(["umount", str(mnt)], check=False)


# -- checks before the work -------------------------------------------------------------------

def test_two_options_on_one_path_are_refused(tmp_path):
    a = tmp_path / "a.csv"
    with pytest.raises(OutputError, match="--json writes the same file"):
        check_distinct([("--json", a, None), ("--telemetry", a, None)])
    link = tmp_path / "l.csv"
    link.symlink_to(a)
    a.write_text("")
    with pytest.raises(OutputError, match="--json writes the same file"):
        check_distinct([("--json", a, None), ("--telemetry", link, None)])
    with pytest.raises(OutputError, match="--json writes the same file"):
        check_distinct([("--json", tmp_path / "figs", None), ("--plots", tmp_path / "figs",
                                                              ("jets.png",))])
    with pytest.raises(OutputError, match="--json writes the same file"):
        check_distinct([("--json", tmp_path / "figs" / "jets.png", None),
                        ("--plots", tmp_path / "figs", ("jets.png",))])
    with pytest.raises(OutputError, match="it is the SCENARIO this command reads"):
        check_distinct([("--json", a, None)], [("SCENARIO", a)])
    check_distinct([("--json", os.devnull, None), ("--telemetry", os.devnull, None)])
    check_distinct([("--json", tmp_path / "x.json", None), ("--plots", tmp_path / "figs",
                                                             ("x.json2",))])


def test_special_paths_pass_the_check_a_missing_directory_does_not(tmp_path):
    fifo = tmp_path / "p"
    os.mkfifo(fifo)
    check_output("--json", fifo)
    check_output("--json", "/dev/stdout")
    check_output("--json", os.devnull)
    with pytest.raises(OutputError, match="directory does not exist"):
        check_output("--json", tmp_path / "no" / "x.json")
    link = tmp_path / "into-nowhere.json"
    link.symlink_to(tmp_path / "no" / "x.json")
    with pytest.raises(OutputError, match="directory does not exist"):
        check_output("--json", link)


# -- the command line ---------------------------------------------------------------------------

@pytest.mark.parametrize("argv", [
    ["run", "--json", "x.csv", "--telemetry", "x.csv"],
    ["run", "--html", "a.html", "--json", "a.html"],
    ["run", "--json", "d", "--plots", "d"],
    ["run", "--json", "figs/jets.png", "--plots", "figs"],
    ["compare", "--json", "c.png", "--plot", "c.png"],
    ["montecarlo", "--runs", "2", "--json", "mc/summary.json", "--out", "mc"],
    ["analyze", "--json", "a.png", "--plot", "a.png"],
])
def test_the_cli_refuses_one_path_for_two_outputs_before_flying(argv, tmp_path, monkeypatch,
                                                                capsys):
    from allsky.sim import mission

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(mission.Mission, "run_mode", lambda self: pytest.fail("flew"))
    for name in ("figs", "mc"):  # directories that exist: the file inside is a file of theirs
        (tmp_path / name).mkdir()
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("allsky: error: --")
    assert "writes the same file" in err
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["figs", "mc"]  # nothing written


def test_the_cli_refuses_to_write_over_its_scenario(tmp_path, monkeypatch, capsys):
    scenario = tmp_path / "s.toml"
    scenario.write_text("[mission]\nseed = 2\n")
    assert cli.main(["run", str(scenario), "--json", str(scenario)]) == 2
    assert "it is the SCENARIO this command reads" in capsys.readouterr().err
    assert scenario.read_text() == "[mission]\nseed = 2\n"


#: The kinds of path the fuzz draws for each output option.
KINDS = ["new", "regular", "symlink", "dangling", "fifo", "device", "directory", "missing-dir",
         "same-as-json"]


def _make(kind, base: Path, name, json_path):
    p = base / name
    if kind == "regular":
        p.write_text("old")
    elif kind == "symlink":
        (base / f"real-{name}").write_text("old")
        p.symlink_to(base / f"real-{name}")
    elif kind == "dangling":
        p.symlink_to(base / f"made-{name}")
    elif kind == "fifo":
        os.mkfifo(p)
    elif kind == "device":
        try:
            os.mknod(p, 0o666 | stat.S_IFCHR, os.stat(os.devnull).st_rdev)
        except OSError:
            p.write_text("old")  # not allowed here: a regular file instead
    elif kind == "directory":
        p.mkdir()
    elif kind == "missing-dir":
        p = base / "nowhere" / name
    elif kind == "same-as-json":
        p = json_path
    return p


_names = iter(range(10**9))


@settings(max_examples=25, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(json_kind=st.sampled_from(KINDS[:-1]), tlm_kind=st.sampled_from(KINDS))
def test_any_output_paths_get_an_answer_and_no_node_is_clobbered(tmp_path, capsys, json_kind,
                                                                 tlm_kind):
    base = tmp_path / str(next(_names))
    base.mkdir()
    json_path = _make(json_kind, base, "s.json", None)
    tlm_path = _make(tlm_kind, base, "t.csv", json_path)
    readers, got = [], []
    for p in {json_path, tlm_path}:
        if p.exists() and stat.S_ISFIFO(os.stat(p).st_mode):
            t = threading.Thread(target=_read_fifo, args=(p, got), daemon=True)
            t.start()
            readers.append((p, t))
    before = {p: os.lstat(p).st_mode for p in base.iterdir()}
    code = cli.main(["run", "--quiet", "--json", str(json_path), "--telemetry", str(tlm_path)])
    err = capsys.readouterr().err
    assert code in (0, 1, 2), err
    assert "Traceback" not in err
    if code == 2:
        assert err.count("\n") == 1 and err.startswith("allsky: error: --"), err
    for p, t in readers:
        if code == 2:  # refused before flying: nobody will write; end the reader
            with open(p, "wb"):
                pass
        t.join(timeout=60)
        assert not t.is_alive()
    for p, mode in before.items():  # every node stays what it was: a link a link, a FIFO a FIFO
        assert stat.S_IFMT(os.lstat(p).st_mode) == stat.S_IFMT(mode), p
    if code == 0:
        for p in (json_path, tlm_path):
            if os.path.isfile(p):
                assert Path(p).read_text() != "old"
        if os.path.isfile(json_path):
            assert json.loads(Path(json_path).read_text())["status"] == "complete"
    _no_temporaries(base)


def _env():
    return {**{k: v for k, v in os.environ.items() if k != "PYTHONPATH"},
            "PYTHONPATH": str(SRC)}


def test_closed_stdout_still_writes_every_file_then_one_line(tmp_path):
    js = tmp_path / "s.json"
    proc = subprocess.run([sys.executable, "-m", "allsky", "run", "--quiet", "--json", str(js)],
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                          env=_env(), timeout=300, preexec_fn=lambda: os.close(1), check=False)
    assert proc.returncode == 2
    assert proc.stderr == ("allsky: error: stdout: cannot write: it is closed; what was meant "
                           "for it is lost, every file asked for is written\n")
    assert json.loads(js.read_text())["status"] == "complete"


def test_closed_stdin_and_stderr_are_no_error(tmp_path):
    """Started with stdin closed (step then does not pause) or stderr closed: it just runs."""
    js = tmp_path / "step.json"
    proc = subprocess.run([sys.executable, "-m", "allsky", "step", "--until", "2", "--json",
                           str(js)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                          env=_env(), timeout=300, preexec_fn=lambda: os.close(0), check=False)
    assert proc.returncode == 0, proc.stderr
    assert [s["mode"] for s in json.loads(js.read_text())["stops"]][-1] == "2"
    proc = subprocess.run([sys.executable, "-m", "allsky", "run", "--json", str(js)],
                          stdout=subprocess.DEVNULL, env=_env(), timeout=300,
                          preexec_fn=lambda: os.close(2), check=False)
    assert proc.returncode == 0
    assert json.loads(js.read_text())["status"] == "complete"


def _closed_early(argv, tmp_path):
    """Run ``allsky argv`` with a stdout pipe whose reader closes it at once (``| head -0``)."""
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before the first line
    try:
        return subprocess.run([sys.executable, "-m", "allsky", *argv], stdout=write_end,
                              stderr=subprocess.PIPE, text=True, env=_env(), timeout=600,
                              cwd=tmp_path, check=False)
    finally:
        os.close(write_end)


def test_a_closed_pipe_does_not_stop_the_campaign_files(tmp_path):
    proc = _closed_early(["montecarlo", "--runs", "3", "--workers", "1", "--out", "mc",
                          "--quiet"], tmp_path)
    assert proc.returncode == cli.EXIT_STDOUT_GONE and proc.stderr == ""
    for name in ("summary.txt", "summary.json", "histograms.png", "runs.csv"):
        assert (tmp_path / "mc" / name).stat().st_size > 0, name


def test_a_closed_pipe_does_not_stop_the_figures(tmp_path):
    proc = _closed_early(["run", "--quiet", "--plots", "figs", "--json", "s.json"], tmp_path)
    assert proc.returncode == cli.EXIT_STDOUT_GONE and proc.stderr == ""
    assert len(list((tmp_path / "figs").glob("*.png"))) >= 5
    assert json.loads((tmp_path / "s.json").read_text())["status"] == "complete"


def test_json_to_stdout_through_its_device_path(tmp_path):
    out = tmp_path / "out.txt"
    with out.open("w") as f:
        proc = subprocess.run([sys.executable, "-m", "allsky", "stars", "--json", "/dev/stdout"],
                              stdout=f, stderr=subprocess.PIPE, text=True, env=_env(),
                              timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    assert out.is_file() and not out.is_symlink()
    text = out.read_text()
    body, end = json.JSONDecoder().raw_decode(text)  # the JSON through the descriptor,
    assert body["stars"] and "Sirius" in text[end:]   # then the table, nothing overwritten


# -- the console: any encoding, a lost stream ---------------------------------------------------

def test_an_ascii_console_gets_ascii_not_an_error():
    import io

    from allsky.apps.console import ConsoleStream, ascii_text

    raw = io.BytesIO()
    stream = ConsoleStream(io.TextIOWrapper(raw, encoding="ascii"), 1)
    stream.write("12.0 ± 0.3″ at 45° → done\n")
    stream.flush()
    assert raw.getvalue() == b'12.0 +/- 0.3" at 45 deg -> done\n'
    assert ascii_text("café ▽ Δt") == "cafe v dt"
    assert stream.lost is None


def test_compare_on_an_ascii_console(tmp_path):
    env = {**_env(), "PYTHONIOENCODING": "ascii"}
    proc = subprocess.run([sys.executable, "-m", "allsky", "compare", "--runs", "2",
                           "--workers", "1", "--quiet"], capture_output=True, env=env,
                          timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    assert b"+/-" in proc.stdout
    proc.stdout.decode("ascii")


def test_a_stream_lost_mid_command_drops_the_rest_quietly():
    from allsky.apps.console import ConsoleStream

    class Broken:
        encoding = "utf-8"

        def write(self, text):
            raise BrokenPipeError(errno.EPIPE, "Broken pipe")

        def flush(self):
            pass

    read_end, write_end = os.pipe()
    stream = ConsoleStream(Broken(), write_end)
    assert stream.write("x\n") == 2 and stream.lost == errno.EPIPE and stream.dropped
    assert stream.write("y\n") == 2
    os.close(read_end)
    os.close(write_end)


def test_an_exception_python_can_only_ignore_is_one_line_and_an_interrupt_comes_back(capsys):
    """Raised in a callback from compiled code: one line; a Ctrl-C there is delivered again."""
    import ctypes

    from allsky.apps.console import guarded

    lost = []

    @ctypes.CFUNCTYPE(None)
    def callback():
        raise lost_kind[0]("in the callback")

    with guarded(on_lost_interrupt=lambda: lost.append(1)):
        lost_kind = [ValueError]
        callback()
        lost_kind[0] = KeyboardInterrupt
        callback()
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("allsky: warning: ignored in ")
    assert "ValueError: in the callback" in err and "Traceback" not in err
    assert lost == [1]


def test_the_null_device_takes_an_output_of_any_suffix():
    check_output("--html", os.devnull, suffixes=(".html", ".htm"))
    with pytest.raises(OutputError, match="unknown suffix"):
        check_output("--html", "page.txt", suffixes=(".html", ".htm"))
