"""A worker killed with SIGKILL does not end montecarlo, compare or faults, nor change them.

The flight of one chosen job kills the worker process flying it the first
time (SIGKILL, as ``kill -9`` or the out-of-memory killer would); the
workers are forked from the test process, so the patched flight is theirs.
The campaign replaces the worker, flies the job again and ends complete,
equal to an undisturbed campaign. A job that kills its worker every time
becomes a row of status ``worker_died`` and the others are unchanged.
"""

import json
import os
import signal
from pathlib import Path

from allsky.apps import campaign, cli
from allsky.studies import compare as compare_study
from allsky.studies import faults as faults_study
from allsky.studies import montecarlo


def _killing(monkeypatch, module, name, chosen, marks: Path, times=1):
    """Make ``module.name`` SIGKILL its worker on the job ``chosen(args)`` picks, ``times``."""
    original = getattr(module, name)

    def flight(*args, **kwargs):
        if chosen(*args):
            n = len(list(marks.glob("kill-*")))
            if n < times:
                (marks / f"kill-{n}").write_text(str(os.getpid()))
                os.kill(os.getpid(), signal.SIGKILL)
        return original(*args, **kwargs)

    monkeypatch.setattr(module, name, flight)


def _kills(marks: Path) -> int:
    return len(list(marks.glob("kill-*")))


def test_montecarlo_flies_the_killed_run_again(monkeypatch, tmp_path, capsys):
    calm, hit = tmp_path / "calm", tmp_path / "hit"
    assert cli.main(["montecarlo", "--runs", "6", "--workers", "2", "--out", str(calm),
                     "--quiet", "--json", str(tmp_path / "calm.json")]) == 0
    _killing(monkeypatch, montecarlo, "fly_one", lambda cfg, run, seed: run == 3, tmp_path)
    assert cli.main(["montecarlo", "--runs", "6", "--workers", "2", "--out", str(hit),
                     "--quiet", "--json", str(tmp_path / "hit.json")]) == 0
    assert _kills(tmp_path) == 1
    assert "Traceback" not in capsys.readouterr().err
    assert campaign.read_rows(hit) == campaign.read_rows(calm)
    assert json.loads((tmp_path / "hit.json").read_text()) == json.loads(
        (tmp_path / "calm.json").read_text())


def test_montecarlo_a_run_that_kills_twice_is_a_row_worker_died(monkeypatch, tmp_path,
                                                               capsys):
    out = tmp_path / "mc"
    _killing(monkeypatch, montecarlo, "fly_one", lambda cfg, run, seed: run == 1, tmp_path,
             times=99)
    assert cli.main(["montecarlo", "--runs", "4", "--workers", "2", "--out", str(out),
                     "--quiet"]) == 0
    captured = capsys.readouterr()
    rows = campaign.read_rows(out)
    assert [r["status"] for r in rows] == ["complete", "worker_died", "complete", "complete"]
    assert rows[1]["abort_reason"] == "its worker process died twice (SIGKILL, SIGKILL)"
    assert "1 worker_died" in captured.out and "Traceback" not in captured.err


def test_compare_flies_the_killed_pair_again(monkeypatch, tmp_path, capsys):
    argv = ["compare", "--runs", "3", "--workers", "2", "--quiet", "--json"]
    assert cli.main([*argv, str(tmp_path / "calm.json")]) == 0
    _killing(monkeypatch, compare_study, "fly_pair", lambda job, *rest: job[1] == 2, tmp_path)
    assert cli.main([*argv, str(tmp_path / "hit.json")]) == 0
    assert _kills(tmp_path) == 1
    assert "Traceback" not in capsys.readouterr().err
    assert json.loads((tmp_path / "hit.json").read_text()) == json.loads(
        (tmp_path / "calm.json").read_text())


def test_faults_flies_the_killed_case_again(monkeypatch, tmp_path, capsys):
    argv = ["faults", "--kinds", "gyro_dead,tracker_dropout", "--modes", "4,5", "--workers",
            "2", "--quiet", "--json"]
    assert cli.main([*argv, str(tmp_path / "calm.json")]) == 0
    _killing(monkeypatch, faults_study, "fly_case",
             lambda data, kind, mode: (kind, mode) == ("tracker_dropout", "4"), tmp_path)
    assert cli.main([*argv, str(tmp_path / "hit.json")]) == 0
    assert _kills(tmp_path) == 1
    assert "Traceback" not in capsys.readouterr().err
    calm, hit = (json.loads((tmp_path / f"{n}.json").read_text()) for n in ("calm", "hit"))
    for result in (calm, hit):
        result.pop("wall_s")
    assert hit == calm
