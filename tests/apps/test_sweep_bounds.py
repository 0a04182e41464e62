"""``compare --sweep``: bounded as --runs is, and a Ctrl-C writes the points finished."""

import json
import os
import signal

from allsky.apps import cli
from allsky.studies import dither_sweep


def test_a_sweep_of_too_many_points_is_refused_before_flying(capsys):
    values = ",".join(str(k) for k in range(1, 1002))
    assert cli.main(["compare", "--sweep", f"amplitude_urad={values}"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("allsky: error: --sweep") and "more than 1000" in err
    assert len(err.splitlines()) == 1


def test_a_sweep_of_too_many_missions_is_refused(capsys):
    amps = ",".join(str(k) for k in range(1, 101))
    recs = ",".join(str(100 + k) for k in range(1, 11))
    assert cli.main(["compare", "--runs", "10000", "--sweep", f"amplitude_urad={amps}",
                     "--sweep", f"record_s={recs}"]) == 2
    err = capsys.readouterr().err
    assert "more than 10000000" in err and len(err.splitlines()) == 1


def test_ctrl_c_during_the_grid_writes_the_points_finished(monkeypatch, tmp_path, capsys):
    original = dither_sweep.fly_dither
    calls = [0]

    def fly_then_interrupt(job):
        calls[0] += 1
        if calls[0] == 2:  # Ctrl-C as the second point starts: the first is finished
            os.kill(os.getpid(), signal.SIGINT)
        return original(job)

    monkeypatch.setattr(dither_sweep, "fly_dither", fly_then_interrupt)
    out = tmp_path / "sweep.json"
    code = cli.main(["compare", "--quiet", "--workers", "1", "--sweep",
                     "amplitude_urad=100,1000,10000", "--json", str(out)])
    captured = capsys.readouterr()
    assert code == 130, captured.err
    data = json.loads(out.read_text())
    assert data["interrupted"] is True
    assert [p["amplitude_urad"] for p in data["points"]] == [100.0]
    line = captured.err.strip().splitlines()[-1]
    assert line.startswith("allsky: interrupted; after 1 of 3 grid points") and str(out) in line
