"""Ctrl-C and SIGTERM on every command: exit 130, one line, the finished work written whole.

Signals are sent at deterministic points (from a wrapped function, after a
known unit of work), never after a delay; the outcome is checked whatever
the machine's load.
"""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from allsky.apps import campaign, cli, step, telemetry_files
from allsky.sim import frame_loop, mission
from allsky.sim.mission import Mission
from allsky.studies import compare as compare_study
from allsky.studies import montecarlo

SRC = Path(__file__).resolve().parents[2] / "src"


def _signal_after(monkeypatch, module, name, n, sig=signal.SIGINT, when="after"):
    """Wrap ``module.name`` so that its ``n``-th call sends ``sig`` to this process."""
    original = getattr(module, name)
    calls = [0]

    def wrapped(*args, **kwargs):
        calls[0] += 1
        if when == "before" and calls[0] == n:
            os.kill(os.getpid(), sig)
        result = original(*args, **kwargs)
        if when == "after" and calls[0] == n:
            os.kill(os.getpid(), sig)
        return result

    monkeypatch.setattr(module, name, wrapped)
    return calls


def _one_interrupted_line(err):
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("allsky: interrupted"), err
    assert "Traceback" not in err
    return lines[0]


def _no_temporary_files(directory):
    assert not [p.name for p in Path(directory).iterdir() if ".tmp" in p.name]


# -- run: the report, --json and --telemetry of the part flown --------------------------------

@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_run_interrupted_mid_leg_writes_the_part_flown(monkeypatch, tmp_path, capsys, sig):
    monkeypatch.setattr(mission, "SLICE_FRAMES", 5000)  # slices of 50 s: legs are cut
    _signal_after(monkeypatch, frame_loop, "run_leg", 3, sig)
    js, tlm = tmp_path / "s.json", tmp_path / "t.csv"
    code = cli.main(["run", "--json", str(js), "--telemetry", str(tlm)])
    captured = capsys.readouterr()
    assert code == 130
    line = _one_interrupted_line(captured.err)
    assert str(js) in line and str(tlm) in line
    assert "allsky mission: not finished" in captured.out
    summary = json.loads(js.read_text())
    assert summary["status"] == "running"
    # The mode the flight stopped in is in the timeline, from its journal entry.
    now = [e for e in summary["events"] if e["kind"] == "mode_start"][-1]
    assert now["mode"] not in [r["mode"] for r in summary["modes"]]
    assert f"{now['mode']:<5}{now['t_s']:>9.1f}{'-':>9}{'-':>8}  in progress" in captured.out
    table, _ = telemetry_files.read(tlm)
    t = table[:, 0]  # time [s]
    # The telemetry reaches the mission time at which the flight stopped, mid-leg.
    assert len(t) > 0 and abs(t[-1] - summary["mission_time_s"]) <= 0.5
    _no_temporary_files(tmp_path)


def test_run_interrupted_json_to_stdout_keeps_stdout_json(monkeypatch, capsys):
    _signal_after(monkeypatch, Mission, "run_mode", 2)
    assert cli.main(["run", "--json", "-"]) == 130
    captured = capsys.readouterr()
    assert json.loads(captured.out)["status"] == "running"
    _one_interrupted_line(captured.err)


# -- the frame loop returns to Python often: Ctrl-C honoured, flight unchanged --------------

def test_sliced_flight_equals_the_straight_one(monkeypatch, default_cfg, saved_states):
    monkeypatch.setattr(mission, "SLICE_FRAMES", 997)
    frames = []
    original = frame_loop.run_leg

    def counting(p, s, *args):
        f0 = int(s.frame[0])
        out = original(p, s, *args)
        frames.append(int(s.frame[0]) - f0)
        return out

    monkeypatch.setattr(frame_loop, "run_leg", counting)
    m = Mission(default_cfg, telemetry=False)
    m.run()
    assert max(frames) <= 997  # never longer than a slice in compiled code
    straight = saved_states["mission"].state
    for name in m.state._fields:
        if name != "leg_clock":  # the progress of the last leg when it was paused
            np.testing.assert_array_equal(getattr(m.state, name), getattr(straight, name))


def test_slice_is_a_small_fraction_of_half_a_second():
    """SLICE_FRAMES at the measured cost per frame (0.4-0.5 us, docstring) is < 0.1 s."""
    assert mission.SLICE_FRAMES * 0.5e-6 <= 0.1


# -- step: at the prompt, Ctrl-C ends the session with its outputs --------------------------

class _Terminal:
    def isatty(self):
        return True


def test_step_ctrl_c_at_the_prompt_writes_report_json_and_telemetry(monkeypatch, tmp_path,
                                                                    capsys):
    answers = iter(["", ""])

    def ask():
        try:
            return next(answers)
        except StopIteration:
            raise KeyboardInterrupt from None

    monkeypatch.setattr(step, "_ask", ask)
    monkeypatch.setattr(sys, "stdin", _Terminal())
    js, tlm = tmp_path / "s.json", tmp_path / "t.parquet"
    code = cli.main(["step", "--json", str(js), "--telemetry", str(tlm)])
    captured = capsys.readouterr()
    assert code == 130
    _one_interrupted_line(captured.err)
    data = json.loads(js.read_text())
    assert [s["mode"] for s in data["stops"]] == ["1", "2", "3"]
    assert data["summary"]["status"] == "running"
    assert "allsky mission: not finished" in captured.out
    table, _ = telemetry_files.read(tlm)
    assert table[-1, 0] == pytest.approx(data["summary"]["mission_time_s"], abs=0.5)
    _no_temporary_files(tmp_path)


# -- compare: the pairs finished, marked interrupted -----------------------------------------

def test_compare_interrupted_keeps_the_pairs_finished(monkeypatch, tmp_path, capsys):
    _signal_after(monkeypatch, compare_study, "fly_pair", 2, when="before")
    js = tmp_path / "c.json"
    code = cli.main(["compare", "--runs", "3", "--workers", "1", "--json", str(js)])
    captured = capsys.readouterr()
    assert code == 130
    line = _one_interrupted_line(captured.err)
    assert "after 1 of 3 pairs" in line
    data = json.loads(js.read_text())
    assert data["interrupted"] is True and data["runs"] == 1 and data["runs_requested"] == 3
    assert len(data["rows"]) == 1
    assert "interrupted after 1 of 3 pairs" in captured.out


# -- montecarlo: rows saved, a second Ctrl-C also clean ---------------------------------------

def test_montecarlo_ctrl_c_saves_rows_and_a_second_ctrl_c_is_clean(monkeypatch, tmp_path,
                                                                   capsys):
    _signal_after(monkeypatch, campaign.ResultsFile, "write", 1)
    # A second Ctrl-C while the interrupted campaign ends its workers.
    _signal_after(monkeypatch, montecarlo, "stop_pool", 1, when="before")
    out = tmp_path / "mc"
    code = cli.main(["montecarlo", "--runs", "40", "--workers", "2", "--out", str(out),
                     "--quiet"])
    captured = capsys.readouterr()
    assert code == 130
    notes = [ln for ln in captured.err.splitlines() if not ln.startswith("allsky: --workers")]
    line = _one_interrupted_line("\n".join(notes))
    assert f"continue with --resume --out {out}" in line
    rows = campaign.read_rows(out)
    assert 1 <= len(rows) < 40 and all(r["status"] == "complete" for r in rows)
    assert (out / campaign.SUMMARY_JSON).exists()
    _no_temporary_files(out)


# -- workers end with their parent ------------------------------------------------------------

def _children(pid):
    try:
        return {int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()}
    except OSError:
        return set()


def _alive(pid):
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")


@pytest.mark.skipif(not Path("/proc/self/task").exists(), reason="needs Linux /proc")
def test_workers_exit_when_the_campaign_parent_is_killed(tmp_path):
    out = tmp_path / "mc"
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    proc = subprocess.Popen([sys.executable, "-m", "allsky", "montecarlo", "--runs", "200",
                             "--workers", "2", "--out", str(out), "--quiet"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    try:
        deadline = time.monotonic() + 120  # liveness bound only
        while time.monotonic() < deadline:
            rows = out / campaign.RESULTS
            if rows.exists() and rows.read_bytes().count(b"\n") >= 2:
                break
            assert proc.poll() is None
            time.sleep(0.05)
        workers = _children(proc.pid)
        assert workers, "no worker processes"
    finally:
        proc.kill()  # SIGKILL: the parent cannot tidy up
        proc.wait()
    deadline = time.monotonic() + 10  # liveness bound only
    while time.monotonic() < deadline and any(_alive(w) for w in workers):
        time.sleep(0.1)
    assert not any(_alive(w) for w in workers)


# -- a lost Dask cluster: one line, exit 2, --resume continues --------------------------------

def test_lost_dask_cluster_is_one_line_and_resume_continues(monkeypatch, tmp_path, capsys):
    from concurrent.futures import CancelledError

    from allsky.config import load_scenario

    cfg = load_scenario(None, [])

    class Lost:
        def __iter__(self):
            yield [montecarlo.fly_one(cfg, 0, int(cfg.mission.seed))]
            raise CancelledError("all workers lost")

        def salvage(self):
            return []

    monkeypatch.setattr(montecarlo, "_dask_stream", lambda data, jobs, address, batch=None: (
        Lost(), lambda interrupted=False: None))
    out = tmp_path / "mc"
    code = cli.main(["montecarlo", "--runs", "3", "--scheduler", "tcp://127.0.0.1:1",
                     "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert "lost the Dask cluster" in err and f"--resume --out {out}" in err
    assert [r["run"] for r in campaign.read_rows(out)] == [0]


# -- a real Dask scheduler lost mid-campaign: one line, the rows kept ---------------------------

def _free_port():
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_real_scheduler_killed_mid_campaign_is_one_line(monkeypatch, tmp_path, capsys):
    """The scheduler process is SIGKILLed after the second row is saved: exit 2, one line."""
    pytest.importorskip("distributed")
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PYTHONPATH": str(SRC), "DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED":
           "False"}
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "env": env,
             "start_new_session": True}
    scheduler = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler",
                                  "--host", "127.0.0.1", "--port", str(port),
                                  "--no-dashboard"], **quiet)
    worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address,
                               "--nworkers", "1", "--nthreads", "1", "--no-dashboard"], **quiet)
    try:
        saved = [0]
        original = campaign.ResultsFile.write

        def write_then_lose(self, row):
            original(self, row)
            saved[0] += 1
            if saved[0] == 2:
                os.kill(scheduler.pid, signal.SIGKILL)

        monkeypatch.setattr(campaign.ResultsFile, "write", write_then_lose)
        out = tmp_path / "mc"
        code = cli.main(["montecarlo", "--runs", "400", "--scheduler", address, "--out",
                         str(out), "--quiet"])
        err = capsys.readouterr().err
        assert code == 2, err
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
        assert "lost the Dask cluster" in err and f"--resume --out {out}" in err
        rows = campaign.read_rows(out)
        assert 2 <= len(rows) < 400
    finally:
        for proc in (worker, scheduler):
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.wait()


def test_a_campaign_that_cannot_reach_its_scheduler_leaves_nothing(monkeypatch, tmp_path,
                                                                   capsys):
    pytest.importorskip("distributed")
    monkeypatch.setattr(montecarlo, "DASK_CONNECT_TIMEOUT_S", 1.0)
    out = tmp_path / "mc"
    argv = ["montecarlo", "--runs", "2", "--scheduler", f"tcp://127.0.0.1:{_free_port()}",
            "--out", str(out), "--quiet"]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("allsky: error: cannot reach the Dask scheduler") and err.count(
        "\n") == 1
    assert not out.exists()  # the same command can simply be run again
    out.mkdir()
    assert cli.main(argv) == 2
    assert list(out.iterdir()) == []  # a directory that was there stays, empty


def test_a_second_campaign_on_a_locked_directory_is_refused(tmp_path, capsys):
    out = tmp_path / "mc"
    assert cli.main(["montecarlo", "--runs", "2", "--workers", "1", "--out", str(out),
                     "--quiet"]) == 0
    capsys.readouterr()
    held = campaign._DirectoryLock(out)  # as a campaign flying there now holds it
    try:
        assert cli.main(["montecarlo", "--runs", "4", "--resume", "--out", str(out),
                         "--quiet"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "another allsky montecarlo is flying" in err
        assert len(campaign.read_rows(out)) == 2
    finally:
        held.release()
    assert cli.main(["montecarlo", "--runs", "4", "--resume", "--out", str(out),
                     "--quiet"]) == 0
    assert len(campaign.read_rows(out)) == 4
