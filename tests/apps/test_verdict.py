"""Success only where it is one; a report that tells the whole flight.

A mission the sequencer completed while its summary warns is "complete, as
the sequencer judged" (amber) on every display, ``--strict`` fails it, and a
register word no mode wrote is "not calibrated (Mode N aborted)", never an
error against the truth. The report names the scenario, the faults flown and
the wheels, and stays within 100 columns.
"""

import json
import re

import pytest
from hypothesis import given
from hypothesis import strategies as st

import allsky
from allsky.apps import cli, verdict
from allsky.apps.api import flight_html
from allsky.apps.faults import scenario_cards
from allsky.apps.report import WIDTH, angle_text, format_report
from allsky.config.faults import packaged_scenarios


@given(st.sampled_from(["complete", "aborted", "running"]),
       st.lists(st.text(min_size=1, max_size=40), max_size=4))
def test_amber_exactly_when_the_sequencer_completed_and_the_summary_warns(status, warnings):
    j = verdict.judge({"status": status, "warnings": warnings, "abort_reason": "x"})
    assert (j["tone"] == "amber") == (status == "complete" and bool(warnings))
    assert (j["tone"] == "ok") == (status == "complete" and not warnings)
    assert j["label"] == verdict.LABELS[j["tone"]]
    assert j["first_warning"] == (warnings[0] if warnings else None)
    failed = verdict.strict_failure({"status": status, "warnings": warnings,
                                     "abort_reason": "x"})
    assert (failed is None) == (j["tone"] == "ok")
    if warnings:
        assert warnings[0] in failed


@given(st.floats(min_value=-1e7, max_value=1e7, allow_nan=False))
def test_degrees_beside_arcsec_past_one_degree(arcsec):
    text = angle_text(arcsec)
    assert text.startswith(f"{arcsec:.1f} arcsec")
    assert ("deg" in text) == (abs(arcsec) >= 3600.0)
    if abs(arcsec) >= 3600.0:
        assert f"({arcsec / 3600.0:.3f} deg)" in text


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """``runs(name, *argv)``: ``allsky run NAME ARGV --json``: (exit code, report, summary)."""
    cache, folder = {}, tmp_path_factory.mktemp("verdict")

    def get(*argv):
        if argv not in cache:
            import contextlib
            import io

            path = folder / f"{len(cache)}.json"
            out, err = io.StringIO(), io.StringIO()
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                code = cli.main(["run", *argv, "--quiet", "--json", str(path)])
            cache[argv] = (code, out.getvalue(), json.loads(path.read_text()), err.getvalue())
        return cache[argv]

    return get


def test_strict_fails_the_gyro_failure_and_passes_the_default(runs):
    code, report, summary, err = runs("gyro-failure-to-target", "--strict")
    assert summary["status"] == "complete" and len(summary["warnings"]) == 2
    assert code == 1 and report.startswith("allsky mission: complete, as the sequencer judged")
    assert err.startswith("allsky: --strict: mission complete, as the sequencer judged")
    assert summary["warnings"][0] in err
    assert runs("--strict")[0] == 0
    assert runs("gyro-failure-to-target")[0] == 0  # without --strict: the sequencer's word


def test_the_first_line_judges_and_names_the_scenario(runs):
    _, report, summary, _ = runs("gyro-failure-to-target")
    lines = report.splitlines()
    assert lines[0] == ("allsky mission: complete, as the sequencer judged; scenario "
                        "gyro-failure-to-target")
    assert lines[1].startswith("  The pitch gyro fails as the vehicle yaws to the target")
    head = " ".join(x.strip() for x in lines[:8])
    assert "! the first of 2 warnings: " + summary["warnings"][0][:60] in head
    _, plain, _, _ = runs("--strict")
    assert plain.splitlines()[0] == "allsky mission: complete; scenario default"


def test_the_report_has_the_faults_and_degrees_within_100_columns(runs):
    _, report, summary, _ = runs("gyro-failure-to-target")
    assert max(map(len, report.splitlines())) <= WIDTH
    faults = report.split("\nFaults (1)\n")[1].split("\n\n")[0].splitlines()
    onset = summary["faults"][0]["onset_s"]
    assert re.match(rf"\s+1 gyro_dead\s+{onset:.1f}\s+"
                    rf"{summary['mission_time_s'] - onset:.1f}\s+acting\s+pitch gyro dead",
                    faults[1]), faults
    err = summary["end"]["true_pointing_error_arcsec"]
    assert f"{err:.1f} arcsec ({err / 3600:.3f} deg) to Sirius" in report


def test_a_fault_that_ended_has_its_duration(runs):
    _, report, summary, _ = runs("mariner4-star-hopping")
    assert summary["status"] == "complete"
    assert max(map(len, report.splitlines())) <= WIDTH
    row = report.split("\nFaults (1)\n")[1].splitlines()[1]
    onset = summary["faults"][0]["onset_s"]
    assert re.match(rf"\s+1 tracker_stray_light\s+{onset:.1f}\s+120\.0\s+ended\s+stray light",
                    row), row


def test_words_never_written_are_not_calibrated_not_errors(runs):
    """shuttle-free-flyer-sunset aborts in Mode 5 (orbit night): the yaw words stay power-on."""
    code, report, summary, _ = runs("shuttle-free-flyer-sunset")
    assert code == 1 and summary["modes"][-1]["mode"] == "5"
    assert summary["calibration"]["scale_factor"]["yaw"] == 1.0  # the power-on word
    never = verdict.unwritten(summary)
    assert set(never) == {("scale_factor", "yaw"), ("cross_coupling", "yaw_into_pitch"),
                          ("cross_coupling", "yaw_into_roll")}
    assert set(never.values()) == {"not calibrated (Mode 5 aborted)"}
    lines = {ln.split()[2] if ln.startswith("  scale factor") else ln.split()[0]: ln
             for ln in report.splitlines() if ln.startswith(("  scale factor", "  yaw_into",
                                                             "  roll_into"))}
    assert "not calibrated (Mode 5 aborted)" in lines["yaw"] and "ppm" not in lines["yaw"]
    assert "ppm" in lines["roll"]
    assert "not calibrated (Mode 5 aborted)" in lines["yaw_into_pitch"]
    assert "not calibrated" not in lines["roll_into_pitch"]
    page = flight_html(summary)
    assert page.count("not calibrated (Mode 5 aborted)") == 3
    assert "ABORTED" not in page and ">aborted<" in page


def test_the_notebook_repr_is_amber_with_the_first_warning(runs):
    _, _, summary, _ = runs("gyro-failure-to-target")
    page = flight_html(summary)
    assert f'color: {verdict.COLOURS["amber"]}">complete, as the sequencer judged' in page
    assert summary["warnings"][0].replace("'", "&#x27;") in page
    assert verdict.COLOURS["ok"] not in page.split("Warnings")[0]


def test_fly_strict_raises_with_the_flight(runs):
    with pytest.raises(allsky.StrictError, match="as the sequencer judged") as caught:
        allsky.fly("gyro-failure-to-target", telemetry=False, progress=False, strict=True)
    flight = caught.value.flight
    assert flight.status == "complete" and caught.value.warnings == flight.summary["warnings"]
    assert "complete, as the sequencer judged" in repr(flight)
    assert "warning: Mode 6-2 declared" in repr(flight)


def test_the_wheel_vehicle_has_its_wheels_line(runs):
    code, report, summary, _ = runs("--set", 'actuators.kind="wheels"')
    assert code == 0 and "propellant used 0.000 kg" in report  # the wheels did the work
    w = summary["wheels"]
    unloads = sum(1 for e in summary["events"] if e["kind"] == "saturation"
                  and e["what"] == "wheel_unloading" and e["active"])
    line = next(ln for ln in report.splitlines() if ln.startswith("  wheels:"))
    assert line == (f"  wheels: peak momentum {100 * w['peak_momentum_fraction']:.1f} % of the "
                    f"limit, {unloads} unload{'s' * (unloads != 1)}, unloading propellant "
                    f"{w['unloading_propellant_kg']:.3f} kg")


def test_a_report_folds_to_a_narrower_width(runs):
    _, _, summary, _ = runs("gyro-failure-to-target")
    text = format_report(summary, width=72)
    rows = [ln for ln in text.splitlines() if ln.startswith(("   # target", "   1 Sirius"))]
    assert len(rows) == 2 and len(rows[0]) > 72  # the table keeps its columns
    assert all(len(ln) <= 72 for ln in text.splitlines() if ln not in rows)


def test_every_packaged_scenario_but_the_default_has_a_card(capsys):
    cards = scenario_cards()
    names = {e["name"] for e in packaged_scenarios()} - {"default"}
    assert set(cards) == names
    for name in sorted(names):
        assert cli.main(["scenarios", name]) == 0
        out = capsys.readouterr().out
        assert out.startswith(f"{name} \u2014 {cards[name]['title']}\n")
        for part in ("What happened.", "What the scenario flies.", "What it leaves out."):
            assert part in out, (name, part)
        assert max(map(len, out.splitlines())) <= WIDTH


def test_an_unknown_scenario_name_is_one_error_line(capsys):
    assert cli.main(["scenarios", "no-such-thing"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("allsky: error: scenario 'no-such-thing'")
    assert "voyager1-wrong-star" in err[0]
    assert cli.main(["scenarios", "a", "b"]) == 2
    assert capsys.readouterr().err.startswith("allsky: error: unrecognized arguments: b;")


def test_the_first_line_is_amber_on_a_terminal_only(runs, monkeypatch):
    from allsky.apps.report import coloured

    _, report, summary, _ = runs("gyro-failure-to-target")

    class Terminal:
        def isatty(self):
            return True

    monkeypatch.delenv("NO_COLOR", raising=False)
    text = coloured(report, summary, Terminal())
    assert text.startswith("\033[33mallsky mission: complete, as the sequencer judged")
    assert text.splitlines()[0].endswith("\033[0m") and text.splitlines()[1:] == \
        report.splitlines()[1:]
    assert coloured(report, summary) == report  # not a terminal: plain text
    monkeypatch.setenv("NO_COLOR", "1")
    assert coloured(report, summary, Terminal()) == report
