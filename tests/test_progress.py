"""The live progress line: it shows the modes under way and never changes the flight."""

import io

from allsky.apps import progress
from allsky.sim.mission import Mission


def test_progress_line_names_each_mode_and_the_flight_is_unchanged(default_cfg, saved_states):
    m = Mission(default_cfg, telemetry=False)
    out = io.StringIO()
    summary = progress.fly(m, stream=out)
    text = out.getvalue()
    assert summary == saved_states["mission"].summary()
    for name in m.plan:
        assert f"Mode {name} " in text
    assert "Mode 1 Sun orientation, t = 0 s (compiling the frame loop on first use)" in text
    # Refreshed every PROGRESS_EVERY_S of mission time: about 1323 s / 20 s lines.
    assert text.count(" s |") >= int(summary["mission_time_s"] / progress.PROGRESS_EVERY_S)


def test_quiet_writes_nothing(default_cfg):
    m = Mission(default_cfg, telemetry=False)
    out = io.StringIO()
    assert progress.fly(m, quiet=True, stream=out)["status"] == "complete"
    assert out.getvalue() == ""


def test_resumed_mission_counts_from_its_next_mode(saved_states):
    m = Mission.load(saved_states["6-1"], telemetry=False)
    out = io.StringIO()
    progress.fly(m, stream=out)
    assert "5/7 modes" in out.getvalue() and "Mode 5 " not in out.getvalue()


def test_run_json_dash_prints_the_summary_alone_on_stdout(capsys, saved_states):
    import json

    from allsky.apps import cli

    assert cli.main(["run", "--json", "-"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out) == json.loads(json.dumps(saved_states["mission"].summary()))
    assert captured.err == ""  # no progress line either


def test_run_quiet_keeps_the_report(capsys):
    from allsky.apps import cli

    assert cli.main(["run", "--quiet"]) == 0
    captured = capsys.readouterr()
    assert captured.out.startswith("allsky mission: complete")
    assert captured.err == ""
