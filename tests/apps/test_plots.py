"""Mission figures: the panels each figure has, what they show, and the PNG files.

Truth: the default mission's telemetry and summary (flown once per session,
conftest.py); the figure content is checked against that data (mode spans
against the summary's timeline, calibration errors against summary
differences), not only the files' existence.
"""

import json
import struct

import numpy as np
import pytest

from allsky.apps import plots, telemetry_files
from allsky.apps.cli import main
from allsky.sim import mission, telemetry

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def flown(saved_states):
    m = saved_states["mission"]
    return m.telemetry(), m.summary()


@pytest.fixture(scope="module")
def files(tmp_path_factory, flown):
    """Telemetry (CSV and Parquet) and summary files of the default mission."""
    d = tmp_path_factory.mktemp("flown")
    table, summary = flown
    (d / "summary.json").write_text(json.dumps(summary))
    telemetry_files.write(d / "tlm.parquet", table)
    telemetry_files.write(d / "tlm.csv", table)
    return d


def png_size(path):
    """(width, height) [px] from a PNG's IHDR chunk; asserts the PNG signature."""
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC and data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def titles(fig):
    return [ax.get_title(loc="left") or ax.get_title() for ax in fig.axes]


def texts(ax):
    return [t.get_text() for t in ax.texts]


def test_mode_codes_agree_with_the_mission():
    assert plots.MODE_CODE == mission.MODE_CODE


def test_mode_spans_follow_the_timeline(flown):
    table, summary = flown
    spans = plots.mode_spans(table)
    assert [s[0] for s in spans] == [r["mode"] for r in summary["modes"]]
    dt = table[1, 0] - table[0, 0]
    for (name, t0, t1), r in zip(spans, summary["modes"]):
        assert t0 == pytest.approx(r["start_s"], abs=1.01 * dt), name
        assert t1 == pytest.approx(r["end_s"], abs=1.01 * dt), name


def test_with_a_summary_the_spans_and_switch_edges_are_the_journal_s(flown):
    """The record's exact frames; the telemetry's rows agree with them where they sample."""
    from allsky.apps.events import switch_edges
    from allsky.hardware import switch_bank

    table, summary = flown
    spans = plots.mode_spans(table, summary)
    assert spans == [(r["mode"], r["start_s"], r["end_s"]) for r in summary["modes"]]
    t = table[:, 0]
    for k in range(1, switch_bank.N_SWITCHES + 1):
        if k in switch_bank.SELECTORS:
            continue
        edges = switch_edges(summary["events"], k)
        if not edges:
            assert not telemetry.switch_closed(table, k).any(), f"S{k}"
            continue
        # a row is written at the end of its frame, before the switch step of that frame:
        # the state in force is the last edge strictly before the row's time
        when = np.array([te for te, _ in edges])
        state = np.array([c for _, c in edges], dtype=bool)
        idx = np.searchsorted(when, t, side="left") - 1
        from_journal = np.where(idx >= 0, state[np.maximum(idx, 0)], False)
        assert np.array_equal(from_journal, telemetry.switch_closed(table, k)), f"S{k}"


POINTING_TITLE = "Pointing error: CPU 22's estimate beside the truth"


def test_attitude_errors_has_three_axes_with_units_and_mode_names(flown):
    fig = plots.attitude_errors(flown[0])
    assert titles(fig) == ["Roll error", "Pitch error", "Yaw error", POINTING_TITLE]
    for ax, axis in zip(fig.axes, plots.AXES):
        assert ax.get_ylabel() == f"{axis} error [arcsec]"
        assert ax.get_yscale() == "symlog"
    assert fig.axes[-1].get_xlabel() == "mission time [s]"
    assert texts(fig.axes[0]) == ["1", "2", "3", "4", "5", "6-1", "6-2"]
    labels = [t.get_text() for t in fig.axes[1].get_legend().get_texts()]
    assert labels == ["sun sensor pitch 104", "star tracker pitch 105", "CPU 22 pitch error"]
    # CPU errors are drawn only in Modes 6-1/6-2.
    t, cpu_roll = fig.axes[0].lines[1].get_data()
    assert np.all(np.isnan(cpu_roll[t < flown[1]["modes"][5]["start_s"] - 0.5]))
    assert np.isfinite(cpu_roll[-1])


def test_the_pointing_row_draws_the_truth_beside_the_computer_s_belief(flown):
    """In Modes 6-1, 6-2: CPU 22's error and the telemetry's true error, row for row."""
    table, _ = flown
    ax = plots.attitude_errors(table).axes[3]
    believed, truth = ax.lines[0].get_ydata(), ax.lines[1].get_ydata()
    assert ax.lines[1].get_label() == "true error, roll axis to target"
    cpu = np.isin(table[:, telemetry.INDEX["mode"]], [6.1, 6.2])
    assert np.array_equal(truth[cpu], table[cpu, telemetry.INDEX["true_error"]])
    assert np.isnan(truth[~cpu]).all()
    # At the end the computer's errors have settled; the truth has not gone to zero with them.
    assert believed[-1] < 50.0 and truth[-1] > 1.0 and abs(truth[-1] - believed[-1]) > 1.0


@pytest.fixture(scope="module")
def dithered(default_cfg):
    """Telemetry and summary of the default vehicle flying the dither plan."""
    m = mission.Mission(default_cfg, plan=mission.DITHER_PLAN)
    summary = m.run()
    assert summary["status"] == "complete", summary["abort_reason"]
    return m.telemetry(), summary


def test_attitude_errors_marks_the_true_final_pointing_error(flown):
    table, summary = flown
    truth = summary["end"]["true_pointing_error_arcsec"]
    assert truth == summary["target"]["pointing_error_arcsec"]  # one target, no hold
    fig = plots.attitude_errors(table, summary)
    assert titles(fig)[:3] == ["Roll error", "Pitch error", "Yaw error"]
    ax = fig.axes[3]
    assert ax.get_title(loc="left").startswith("Pointing error")
    assert ax.get_ylabel() == "pointing error [arcsec]" and ax.get_yscale() == "log"
    # The marker sits at the end of the record, at the summary's value.
    (star,) = [line for line in ax.lines if line.get_label().startswith("true final")]
    assert star.get_xdata()[0] == table[-1, telemetry.INDEX["time"]]
    assert star.get_ydata()[0] == truth
    assert f"true final pointing error {truth:.1f}″" in texts(ax)
    # The telemetry cannot give it: CPU 22's own estimate at the end is another number.
    _, believed = ax.lines[0].get_data()
    assert abs(believed[-1] - truth) > 1.0
    assert fig.axes[-1].get_xlabel() == "mission time [s]"


def test_attitude_errors_without_any_truth_has_no_pointing_row(flown):
    """Telemetry of format 1 (no true error) and no summary: nothing true to draw."""
    table, _ = flown
    old = table.copy()
    old[:, telemetry.INDEX["true_error"]:] = np.nan
    assert titles(plots.attitude_errors(old, None)) == ["Roll error", "Pitch error",
                                                       "Yaw error"]


def test_write_plots_passes_the_summary_to_the_attitude_figure(tmp_path, flown, monkeypatch):
    seen = []
    real = plots.attitude_errors

    def spy(table, summary=None):
        seen.append(summary)
        return real(table, summary)

    monkeypatch.setattr(plots, "USES_SUMMARY", (spy,))
    monkeypatch.setitem(plots.TELEMETRY_FIGURES, "attitude_errors", ("attitude_errors.png", spy))
    plots.write_plots(flown[0], tmp_path, flown[1])
    assert seen == [flown[1]]


def test_dither_hold_is_drawn_on_a_linear_scale(dithered, default_cfg):
    table, summary = dithered
    (hold,) = [r for r in summary["modes"] if r["mode"] == "dither"]
    fig = plots.attitude_errors(table)
    assert len(fig.axes) == 5  # roll, pitch, yaw, pointing, and the dither hold
    ax = fig.axes[4]
    assert ax.get_yscale() == "linear" and "linear" in ax.get_title(loc="left")
    dt = table[1, 0] - table[0, 0]
    assert ax.get_xlim() == pytest.approx((hold["start_s"], hold["end_s"]), abs=1.01 * dt)
    # Equal steps of error are equal steps on the page (symlog would bend them at 10").
    px = ax.transData.transform([(hold["start_s"], y) for y in (-20.0, 0.0, 20.0)])[:, 1]
    assert px[1] - px[0] == pytest.approx(px[2] - px[1])
    # The drawn yaw trace is the sun sensor's, and holds the commanded sinusoid:
    # amplitude A = 100 urad = 20.6" at 25.6 s (docs/comparison.md: seen at 1.03 A).
    (yaw,) = [line for line in ax.lines if line.get_label().startswith("yaw")]
    t, y = yaw.get_data()
    keep = (table[:, 0] >= t[0]) & (table[:, 0] <= t[-1])
    assert np.array_equal(y, table[keep, telemetry.INDEX["sun_yaw"]])
    rec = t > hold["start_s"] + default_cfg.dither.lead_in_s
    w = 2.0 * np.pi / default_cfg.dither.period_s[2]
    basis = np.column_stack([np.sin(w * t[rec]), np.cos(w * t[rec]), np.ones(rec.sum())])
    coef, *_ = np.linalg.lstsq(basis, y[rec], rcond=None)
    amplitude_arcsec = default_cfg.dither.amplitude_urad[2] * 1e-6 * plots.RAD2ARCSEC
    assert np.hypot(*coef[:2]) == pytest.approx(amplitude_arcsec, rel=0.1)


def test_legacy_mission_has_no_dither_row(flown):
    assert plots.dither_span(flown[0]) is None
    axes = plots.attitude_errors(flown[0]).axes
    assert [ax.get_yscale() for ax in axes] == ["symlog"] * 3 + ["log"]


def test_switch_timing_shows_the_selector_share_on_each_contact(flown, default_cfg):
    table, summary = flown
    fig = plots.switch_timing(table)
    ax = fig.axes[0]
    stairs = {p.get_label(): p.get_data() for p in ax.patches if p.get_label().startswith("S7")}
    assert list(stairs) == ["S7/S8 on roll", "S7/S8 on pitch", "S7/S8 on yaw"]
    height = 0.7
    shares = np.stack([(d.values - d.baseline) / height for d in stairs.values()], axis=1)
    edges = stairs["S7/S8 on roll"].edges
    assert np.allclose(shares.sum(axis=1), 1.0)  # stacked, every window full
    modes = {r["mode"]: (r["start_s"], r["end_s"]) for r in summary["modes"]}

    def within(mode):
        t0, t1 = modes[mode]
        return (edges[:-1] >= t0 + 1.0) & (edges[1:] <= t1 - 1.0)

    # Mode 5 counts the yaw turn: S7/S8 rests on yaw.
    assert np.allclose(shares[within("5")], [0.0, 0.0, 1.0])
    # Mode 6-2: computer sequencer 21 steps every computer_step_frames frames over the
    # three axes, so each contact holds a third of the time.
    assert default_cfg.electronics.computer_step_frames == 1
    assert np.allclose(shares[within("6-2")], 1.0 / 3.0)
    labels = [t.get_text() for t in ax.get_yticklabels()]
    assert labels[6].startswith("S7/S8 selected axis,\nshare per")
    assert "share of telemetry samples on each contact" in fig.legends[0].get_title().get_text()


def test_selector_shares_count_samples_per_window():
    table = np.zeros((12, len(telemetry.COLUMNS)))
    table[:, telemetry.INDEX["time"]] = np.arange(12) * 0.1
    table[:, telemetry.INDEX["s7_s8"]] = [0, 1, 2, 0, 1, 2, 2, 2, 2, 2, 2, 2]
    edges, shares = plots.selector_shares(table, windows=2)
    assert edges == pytest.approx([0.0, 0.6, 1.2])  # six samples of 0.1 s each
    assert np.allclose(shares, [[1 / 3, 1 / 3, 1 / 3], [0.0, 0.0, 1.0]])


def test_switch_timing_has_a_trace_per_switch(flown):
    table, _ = flown
    fig = plots.switch_timing(table)
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    labels = [t.get_text() for t in ax.get_yticklabels()]
    assert len(labels) == 18  # S1-S19, S7 and S8 on one trace
    assert [lab.split()[0] for lab in labels] == [
        *(f"S{k}" for k in range(1, 7)), "S7/S8", *(f"S{k}" for k in range(9, 20))]
    assert "roll drift DAC 7 → sum amp 4" in labels[0]
    assert ax.get_xlabel() == "mission time [s]"
    assert "S1–S19" in fig.get_suptitle()
    # The S4 trace (row 4 from the top) is high exactly where the bitmask has S4 closed.
    _, y = ax.lines[3].get_data()
    base = len(labels) - 4
    assert np.array_equal(y > base + 0.1, telemetry.switch_closed(table, 4))


def test_counters_figure(flown):
    fig = plots.counters(flown[0])
    assert titles(fig) == ["Up/down counters 14, 16, 18", "Drift counters 13, 15, 17"]
    assert all(ax.get_ylabel() == "count [pulses]" for ax in fig.axes)
    drift = fig.axes[1]
    assert [line.get_label() for line in drift.lines] == [
        "drift counter13 (roll)", "drift counter15 (pitch)", "drift counter17 (yaw)"]
    assert drift.lines[0].get_ydata()[-1] == flown[0][-1, telemetry.INDEX["drift_counter13"]]


def test_jets_figure(flown):
    table, summary = flown
    fig = plots.jets(table)
    t = titles(fig)
    assert len(t) == 4
    assert t[0].startswith("Roll: modulator 34 → jets 39")
    assert t[2].startswith("Yaw: modulator 36 → jets 41")
    assert fig.axes[3].get_ylabel() == "propellant [kg]"
    used = table[0, telemetry.INDEX["propellant"]] - table[-1, telemetry.INDEX["propellant"]]
    assert f"used {used:.3f} kg" in t[3]
    assert used == pytest.approx(summary["propellant_kg"], abs=0.01)


def test_calibration_figure_shows_stored_truth_and_errors(flown):
    summary = flown[1]
    fig = plots.calibration(summary)
    assert [ax.get_title() for ax in fig.axes] == [
        "Drift (drift DACs 7, 9, 11)", "Scale factor − 1 (register 23)",
        "Cross-coupling (register 23)"]
    assert [ax.get_ylabel() for ax in fig.axes] == [
        "drift [deg/h]", "scale factor − 1 [ppm]", "cross-coupling [arcsec]"]
    cal, truth = summary["calibration"], summary["truth"]
    err_ppm = 1e6 * (cal["scale_factor"]["roll"] - truth["scale_factor"]["roll"])
    assert f"error\n{err_ppm:+.1f} ppm" in texts(fig.axes[1])
    err_drift = cal["drift_deg_h"]["yaw"] - truth["drift_deg_h"]["yaw"]
    assert f"error\n{err_drift:+.4f} deg/h" in texts(fig.axes[0])
    # Bars: truth then stored, per term.
    heights = [p.get_height() for p in fig.axes[2].patches]
    names = list(truth["cross_coupling"])
    assert heights[:4] == pytest.approx([truth["cross_coupling"][n] * plots.RAD2ARCSEC
                                         for n in names])
    assert heights[4:] == pytest.approx([cal["cross_coupling"][n] * plots.RAD2ARCSEC
                                         for n in names])


def test_calibration_figure_needs_a_calibration(flown):
    with pytest.raises(ValueError, match="no calibration"):
        plots.calibration({**flown[1], "calibration": None})


def test_write_plots_refuses_an_empty_table(tmp_path):
    with pytest.raises(ValueError, match="no rows"):
        plots.write_plots(np.empty((0, len(telemetry.COLUMNS))), tmp_path)


# -- the command line ---------------------------------------------------------------------

def test_plot_command_writes_and_lists_readable_pngs(tmp_path, capsys, files):
    out_dir = tmp_path / "new" / "figs"
    assert main(["plot", str(files / "tlm.parquet"), "--summary", str(files / "summary.json"),
                 "--out", str(out_dir)]) == 0
    out = capsys.readouterr().out.splitlines()
    names = ["attitude_errors.png", "switches.png", "counters.png", "jets.png",
             "calibration.png"]
    assert out == [f"plot: {out_dir / f}" for f in names]
    assert sorted(p.name for p in out_dir.iterdir()) == sorted(names)
    for f in names:
        w, h = png_size(out_dir / f)
        assert w >= 1000 and h >= 700, f  # report size at 120 dpi


def test_plot_command_without_summary_skips_calibration(tmp_path, capsys, files):
    assert main(["plot", str(files / "tlm.csv"), "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "plot: skipped calibration.png: no mission summary (give --summary" in out
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "attitude_errors.png", "counters.png", "jets.png", "switches.png"]


@pytest.mark.parametrize("args, message", [
    (["plot", "tlm.txt"], "suffix '.txt'; use .csv or .parquet"),
    (["plot", "no_such_file.parquet"], "no_such_file.parquet"),
])
def test_plot_command_usage_errors_exit_2(tmp_path, capsys, args, message):
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("allsky: error: ") and message in err
    assert len(err.strip().splitlines()) == 1


def test_plot_command_refuses_a_file_missing_a_column(tmp_path, capsys, files):
    first, *lines = (files / "tlm.csv").read_text().splitlines()
    cut = [",".join(line.split(",")[:-1]) for line in lines[:10]]
    (tmp_path / "cut.csv").write_text(first + "\n" + "\n".join(cut) + "\n")
    assert main(["plot", str(tmp_path / "cut.csv")]) == 2
    err = capsys.readouterr().err
    assert "missing column 'gyro_yaw [arcsec/s]' of telemetry format 3" in err


def test_plot_command_refuses_a_summary_that_is_not_one(tmp_path, capsys, files):
    (tmp_path / "s.json").write_text('{"status": "complete"}')
    assert main(["plot", str(files / "tlm.parquet"), "--summary", str(tmp_path / "s.json"),
                 "--out", str(tmp_path)]) == 2
    assert "not an allsky mission summary" in capsys.readouterr().err


def test_run_with_plots_writes_the_five_figures(tmp_path, capsys):
    assert main(["run", "--plots", str(tmp_path / "figs")]) == 0
    out = capsys.readouterr().out
    assert "final true pointing error" in out
    assert sorted(p.name for p in (tmp_path / "figs").iterdir()) == [
        "attitude_errors.png", "calibration.png", "counters.png", "jets.png", "switches.png"]
