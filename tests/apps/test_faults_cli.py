"""``allsky faults``: a case that raised is a defect: exit 3, its reason labelled as its cell."""

from allsky.apps import cli
from allsky.apps import faults as faults_app
from allsky.studies import faults as faults_study


def _result():
    cases = [{"kind": "gyro_dead", "mode": "4", "status": "error",
              "outcome": "TypeError: boom", "pointing_error_arcsec": None},
             {"kind": "gyro_dead", "mode": "5", "status": "aborted",
              "outcome": "Mode 5: timeout", "pointing_error_arcsec": None},
             {"kind": "tracker_dropout", "mode": "4", "status": "error",
              "outcome": "ValueError: bad", "pointing_error_arcsec": None},
             {"kind": "tracker_dropout", "mode": "5", "status": "complete",
              "outcome": "complete", "pointing_error_arcsec": 3.2}]
    return {"modes": ["4", "5"], "kinds": ["gyro_dead", "tracker_dropout"],
            "reference": {"status": "complete", "pointing_error_arcsec": 1.0},
            "cases": cases, "faults": {"gyro_dead": "x", "tracker_dropout": "y"},
            "counts": {"status": {"complete": 1, "aborted": 1, "error": 2}}}


def test_reasons_are_labelled_as_their_cells():
    text = faults_app.format_matrix(_result())
    assert "  E1  TypeError: boom" in text and "  E2  ValueError: bad" in text
    assert "  A1  Mode 5: timeout" in text
    assert "A2" not in text and "A3" not in text
    row = next(line for line in text.splitlines() if line.strip().startswith("gyro_dead"))
    assert row.split()[1:] == ["E1", "A1"]


def test_a_case_that_raised_exits_3_with_one_line(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(faults_study, "fault_matrix", lambda *a, **k: _result())
    out = tmp_path / "m.json"
    code = cli.main(["faults", "--quiet", "--kinds", "gyro_dead,tracker_dropout", "--modes",
                     "4,5", "--json", str(out)])
    captured = capsys.readouterr()
    assert code == 3, captured.err
    assert out.exists()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("allsky: internal error: 2 cases")
