"""One exit-code contract and the same flags on every command.

0 ok, 1 mission aborted, 2 usage/input/output error (one line), 3 internal
error (one line and a crash report), 130 interrupted (tests/apps/test_interrupts.py).
"""

import json
import os
from pathlib import Path

import pytest

from allsky.apps import cli, output

COMMANDS = ["run", "step", "compare", "plot", "analyze", "montecarlo", "stars",
            "config show", "config check"]


def _one_error_line(err, start="allsky: error: "):
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(start), err
    return lines[0]


# -- usage errors ---------------------------------------------------------------------------

@pytest.mark.parametrize("argv", [["run", "--bogus"], ["nope"], ["compare", "--runs", "0"],
                                  ["montecarlo", "--workers", "x"], []])
def test_argparse_errors_are_one_line_exit_2(argv, capsys):
    assert cli.main(argv) == 2
    _one_error_line(capsys.readouterr().err)


@pytest.mark.parametrize("command", COMMANDS)
def test_version_and_quiet_after_every_command(command, capsys):
    assert cli.main([*command.split(), "--version"]) == 0
    assert capsys.readouterr().out.startswith("allsky ")
    parser = cli._parser()
    args = parser.parse_args([*command.split(), *(["x.csv"] if command == "plot" else []),
                              "--quiet"])
    assert args.quiet is True


def test_help_lists_the_exit_codes(capsys):
    assert cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    for code in cli.EXIT_CODES:
        assert f"  {code:<4} " in out


# -- internal errors: one line and a crash report ----------------------------------------------

def test_internal_error_is_one_line_with_a_crash_report(monkeypatch, tmp_path, capsys):
    from allsky.apps import analyze

    def broken(cfg):
        raise RuntimeError("boom")

    monkeypatch.setattr(analyze, "analyze", broken)
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    assert cli.main(["analyze"]) == 3
    line = _one_error_line(capsys.readouterr().err, "allsky: internal error: RuntimeError: boom")
    path = Path(line.rsplit("(details in ", 1)[1].rstrip(")"))
    assert path.parent == tmp_path and path.name.startswith("allsky-crash-")
    report = path.read_text()
    assert "Traceback" in report and "RuntimeError: boom" in report


# -- output paths: checked before the work, the others written after a failure -------------------

def test_bad_json_path_refused_before_flying(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    from allsky.sim import mission

    monkeypatch.setattr(mission.Mission, "run_mode", lambda self: pytest.fail("flew"))
    code = cli.main(["run", "--json", "/nonexistent/x.json", "--telemetry", "good.csv"])
    assert code == 2
    line = _one_error_line(capsys.readouterr().err)
    assert line == ("allsky: error: --json: cannot write /nonexistent/x.json: directory does "
                    "not exist")
    assert not (tmp_path / "good.csv").exists()


@pytest.mark.parametrize("argv, option", [
    (["run", "--telemetry", "t.txt"], "t.txt"),
    (["run", "--plots", "file.txt/figs"], "--plots"),
    (["step", "--telemetry", "/nonexistent/t.csv"], "--telemetry"),
    (["compare", "--json", "/nonexistent/c.json"], "--json"),
    (["analyze", "--plot", "/nonexistent/a.png"], "--plot"),
    (["montecarlo", "--runs", "2", "--json", "/nonexistent/m.json"], "--json"),
])
def test_every_output_path_is_checked_first(argv, option, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "file.txt").write_text("")
    assert cli.main(argv) == 2
    assert option in _one_error_line(capsys.readouterr().err)


def test_a_failed_write_does_not_stop_the_others(tmp_path, capsys, monkeypatch):
    from allsky.apps import progress

    gone = tmp_path / "gone"
    gone.mkdir()
    fly = progress.fly

    def fly_then_remove_the_directory(m, quiet=False, stream=None):
        summary = fly(m, quiet=quiet, stream=stream)
        gone.rmdir()
        return summary

    monkeypatch.setattr(progress, "fly", fly_then_remove_the_directory)
    tlm = tmp_path / "t.csv"
    code = cli.main(["run", "--json", str(gone / "s.json"), "--telemetry", str(tlm)])
    captured = capsys.readouterr()
    assert code == 2
    assert _one_error_line(captured.err) == (f"allsky: error: --json: cannot write "
                                             f"{gone / 's.json'}: directory does not exist")
    assert tlm.exists() and f"wrote telemetry {tlm}" in captured.out


def test_write_atomic_leaves_the_old_file_when_the_writer_fails(tmp_path):
    path = tmp_path / "x.json"
    path.write_text("old")

    def half_then_fail(tmp):
        tmp.write_text("half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        output.write_atomic(path, writer=half_then_fail)
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["x.json"]


# -- worker caps ---------------------------------------------------------------------------------

@pytest.mark.parametrize("requested, runs, cores, expected, noted", [
    (None, 100, 2, 2, False), (None, 1, 8, 1, False), (1000, 2, 2, 2, True),
    (64, 4, 2, 2, True), (64, 4, 64, 4, True), (2, 100, 2, 2, False), (3, 100, 2, 2, True)])
def test_cap_workers(requested, runs, cores, expected, noted):
    n, note = output.cap_workers(requested, runs, cores)
    assert n == expected and (note is not None) == noted


def test_compare_caps_workers_and_says_so(monkeypatch, capsys):
    from allsky.apps import compare as app

    seen = {}

    def fake(cfg, runs, workers, on_progress, **options):
        seen["workers"] = workers
        raise SystemExit(0)

    monkeypatch.setattr(app, "compare", fake)
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    with pytest.raises(SystemExit):
        app.run_from_cli(None, cli._parser().parse_args(["compare", "--runs", "2",
                                                          "--workers", "1000"]))
    assert seen["workers"] == 2
    assert "--workers 1000: starting 2 worker processes" in capsys.readouterr().err


def test_montecarlo_caps_workers_and_says_so(monkeypatch, capsys):
    from allsky.apps import campaign

    seen = {}

    def fake(cfg, **kw):
        seen.update(kw)
        raise SystemExit(0)

    monkeypatch.setattr(campaign, "run_recorded", fake)
    monkeypatch.setattr(os, "cpu_count", lambda: 8)
    with pytest.raises(SystemExit):
        campaign.run_from_cli(None, cli._parser().parse_args(["montecarlo", "--runs", "4",
                                                               "--workers", "64"]))
    assert seen["workers"] == 4
    assert "--workers 64: starting 4 worker processes (4 runs)" in capsys.readouterr().err


# -- --json - is stdout everywhere, and nothing else goes there ----------------------------------

@pytest.mark.parametrize("argv", [["step", "--no-pause", "--until", "1"], ["analyze"],
                                  ["stars"], ["run"]])
def test_json_dash_is_stdout_alone(argv, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert cli.main([*argv, "--json", "-"]) == 0
    json.loads(capsys.readouterr().out)
    assert not (tmp_path / "-").exists()


def test_compare_json_dash_is_stdout_alone(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert cli.main(["compare", "--json", "-"]) == 0
    assert json.loads(capsys.readouterr().out)["runs"] == 1
    assert not (tmp_path / "-").exists()


# -- command specifics ------------------------------------------------------------------------

def test_config_check_with_set_alone(capsys):
    assert cli.main(["config", "check", "--set", "mission.seed=3"]) == 0
    assert capsys.readouterr().out.startswith("ok: ")
    assert cli.main(["config", "check", "--set", "mission.seed=-3"]) == 2
    assert "mission.seed" in _one_error_line(capsys.readouterr().err)


def test_step_every_has_a_floor(capsys):
    assert cli.main(["step", "--no-pause", "--every", "0.05"]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert "--every 0.05" in line and "0.1 s and 10 frames" in line


def test_stars_lists_the_window_and_the_locked_star(capsys):
    from allsky.config import load_scenario

    assert cli.main(["stars", "--json", "-"]) == 0
    data = json.loads(capsys.readouterr().out)
    lo, hi = data["magnitude_window"]
    inside = [s for s in data["stars"] if s["in_window"]]
    assert inside == [s for s in data["stars"] if lo <= s["magnitude"] <= hi]
    reference = [s["name"] for s in data["stars"] if s["reference"]]
    cfg = load_scenario(None, [])
    # The star the programmed angles are computed for.
    assert reference == [cfg.star_tracker.reference_star] == ["Canopus"]
    mags = [s["magnitude"] for s in data["stars"]]
    assert mags == sorted(mags)
    assert cli.main(["stars", "--window"]) == 0
    out = capsys.readouterr().out
    assert f"{reference[0]}" in out and "reference (planned)" in out


def test_run_report_names_the_tracker_star_and_the_files(tmp_path, capsys):
    js = tmp_path / "s.json"
    assert cli.main(["run", "--quiet", "--json", str(js)]) == 0
    out = capsys.readouterr().out
    # Canopus (V = -0.62..-0.74 by catalog) is the only star in the default window.
    assert "tracker star Canopus" in out and f"wrote JSON summary {js}" in out


def test_report_gives_ra_and_dec_to_a_sensible_precision(saved_states):
    from allsky.apps.report import format_report

    summary = saved_states["mission"].summary()
    # Vega, J2000: RA 18h 36m 56.3s = 18.6156 h, Dec +38 deg 47' 01" = +38.7837 deg.
    summary["target"] = {**summary["target"], "ra_deg": 279.234735, "dec_deg": 38.783689}
    summary["target"].pop("star", None)
    assert "Target: RA 18.616 h, Dec +38.78 deg" in format_report(summary)


def test_figure_and_telemetry_suffixes_are_checked_before_the_work(capsys, tmp_path):
    """A figure or telemetry file with a suffix nobody writes is refused before flying."""
    from matplotlib.backend_bases import FigureCanvasBase

    from allsky.apps.output import FIGURE_SUFFIXES

    supported = {f".{k}" for k in FigureCanvasBase.get_supported_filetypes()}
    assert set(FIGURE_SUFFIXES) <= supported
    for argv, option in ((["analyze", "--plot", str(tmp_path / "a.txt")], "--plot"),
                         (["compare", "--plot", str(tmp_path / "c.txt")], "--plot"),
                         (["run", "--telemetry", str(tmp_path / "t.txt")], "--telemetry")):
        assert cli.main([*argv, "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith(f"allsky: error: {option}: cannot write") and "suffix" in err
        assert "\n" not in err
    assert list(tmp_path.iterdir()) == []
