"""The Python API's contract: allsky.fly, Flight, compare and montecarlo.

The numbers are the command line's (the same scenario and seed give the
same --json); the tables carry the documented columns and units; the
kernel's interrupt (SIGINT, sent at a deterministic point) keeps what
finished. A Jupyter kernel, where installed, shows a Flight, its figures,
its replay and a progress bar, and is interrupted the way Jupyter does it.
"""

import json
import math
import os
import signal
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure

import allsky
from allsky.apps import api, campaign, cli, telemetry_files
from allsky.apps.output import OutputError
from allsky.config import ConfigError, load_scenario
from allsky.sim import frame_loop, mission, recorder
from allsky.studies import compare as compare_study
from allsky.studies import montecarlo as mc_study
from allsky.studies.montecarlo import CampaignError

SCENARIO = {"target.star": "Vega", "mission.seed": 7}


def _signal_after(monkeypatch, module, name, n, when="after"):
    """Wrap ``module.name`` so that its ``n``-th call sends SIGINT to this process."""
    original = getattr(module, name)
    calls = [0]

    def wrapped(*args, **kwargs):
        calls[0] += 1
        if when == "before" and calls[0] == n:
            os.kill(os.getpid(), signal.SIGINT)
        result = original(*args, **kwargs)
        if when == "after" and calls[0] == n:
            os.kill(os.getpid(), signal.SIGINT)
        return result

    monkeypatch.setattr(module, name, wrapped)
    return calls


def _cli_json(tmp_path, argv):
    out = tmp_path / "cli.json"
    assert cli.main([*argv, "--json", str(out), "--quiet"]) in (0, 1)
    return json.loads(out.read_text())


@pytest.fixture(scope="module")
def flight():
    return allsky.fly(set=SCENARIO, progress=False)


# -- fly: the CLI's numbers --------------------------------------------------------------

def test_fly_gives_the_summary_allsky_run_writes(flight, tmp_path, capsys):
    cli_summary = _cli_json(tmp_path, ["run", "--set", "target.star=Vega",
                                       "--set", "mission.seed=7"])
    # the file carries its format; the summary object is the rest
    assert cli_summary.pop("format") == 1
    assert json.loads(json.dumps(flight.summary)) == cli_summary
    assert flight.status == "complete" and not flight.interrupted


def test_fly_by_packaged_name_and_by_file(tmp_path):
    # docs/faults.md: on 2026-09-01 the tracker locks Rigil Kentaurus, not Canopus.
    voyager = allsky.fly("voyager1-wrong-star", telemetry=False, progress=False)
    assert voyager.summary["locked_star"] == "Rigil Kentaurus"
    path = tmp_path / "my.toml"
    path.write_text('[target]\nstar = "Vega"\n[mission]\nseed = 7\n')
    from_file = allsky.fly(path, telemetry=False, progress=False)
    assert from_file.summary["end"] == allsky.fly(set=SCENARIO, telemetry=False,
                                                  progress=False).summary["end"]


def test_set_takes_python_values_as_toml():
    cfg = api._scenario(None, {"gyro.scale_factor_error_ppm": np.array([800, -300, 1500]),
                               "calibration.apply": False, "target.star": "Vega",
                               "faults": [{"kind": "gyro_dead", "axis": "roll",
                                           "start_mode": "6-2"}]})
    assert cfg == load_scenario(None, ["gyro.scale_factor_error_ppm=[800,-300,1500]",
                                       "calibration.apply=false", 'target.star="Vega"',
                                       ('faults=[{kind="gyro_dead", axis="roll", '
                                        'start_mode="6-2"}]')])


def test_bad_input_is_refused_naming_the_key():
    with pytest.raises(ConfigError, match="gyro.drift_deg_hh"):
        allsky.fly(set={"gyro.drift_deg_hh": [0, 0, 0]}, progress=False)
    with pytest.raises(ConfigError, match="no-such-scenario"):
        allsky.fly("no-such-scenario", progress=False)
    with pytest.raises(ValueError, match="plan"):
        allsky.fly(plan="turns", progress=False)
    with pytest.raises(TypeError, match="scenario"):
        allsky.fly(42, progress=False)


# -- the tables ------------------------------------------------------------------------

def test_telemetry_is_indexed_by_time_with_the_documented_columns_and_units(flight):
    tlm = flight.telemetry
    assert tlm.index.name == "time"
    assert list(tlm.columns) == [c.name for c in recorder.COLUMNS[1:]]
    assert tlm.attrs["units"] == {c.name: c.unit for c in recorder.COLUMNS}
    assert tlm.attrs["units"]["time"] == "s" and tlm.attrs["units"]["true_error"] == "arcsec"
    assert tlm.index.is_monotonic_increasing and tlm.index.is_unique
    table = flight.table
    np.testing.assert_array_equal(tlm.index.to_numpy(), table[:, 0])
    np.testing.assert_array_equal(tlm.to_numpy(dtype=float), table[:, 1:])
    for c in recorder.COLUMNS[1:]:
        integer = c.kind in (recorder.INTEGER, recorder.FLAG, recorder.SET, recorder.BITMASK)
        assert (tlm[c.name].dtype == np.int64) == integer, c.name
    # Physics: the attitude quaternion stays a unit quaternion.
    norm = np.sqrt((tlm[["q_w", "q_x", "q_y", "q_z"]] ** 2).sum(axis=1))
    np.testing.assert_allclose(norm, 1.0, atol=1e-9)
    # The last row is the end of the flight: its true error is the summary's.
    end = flight.summary["end"]
    assert tlm.index[-1] == pytest.approx(end["t_s"], abs=0.1)
    assert tlm["true_error"].iloc[-1] == pytest.approx(end["true_pointing_error_arcsec"],
                                                       rel=0.05)


def test_events_are_the_journal_one_row_per_entry(flight):
    events = flight.events
    journal = flight.summary["events"]
    assert list(events.columns[:4]) == ["t_s", "mode", "kind", "description"]
    assert len(events) == len(journal)
    assert events["t_s"].is_monotonic_increasing
    assert events.attrs["units"]["t_s"] == "s"
    assert list(events["kind"]) == [e["kind"] for e in journal]
    starts = events[events["kind"] == "mode_start"]
    assert list(starts["mode"]) == [r["mode"] for r in flight.summary["modes"]]
    locks = events[events["kind"] == "star_lock"]
    assert "Canopus" in set(locks["star"])  # the default tracker star, first to cross
    switch = events[events["kind"] == "switch"].iloc[0]
    assert switch["description"].startswith("switches: close S14, S15")


def test_timeline_covers_the_flight_without_gaps(flight):
    timeline = flight.timeline
    assert list(timeline["mode"]) == ["1", "2", "3", "4", "5", "6-1", "6-2"]
    assert timeline["start_s"].iloc[0] == 0.0
    np.testing.assert_array_equal(timeline["start_s"].iloc[1:], timeline["end_s"].iloc[:-1])
    assert timeline["duration_s"].sum() == pytest.approx(flight.summary["mission_time_s"])


def test_units_from_the_names():
    assert api.units_of(["scale_factor_error_ppm.roll", "mode_end_4_s", "gyro.drift_deg_h[0]",
                         "mode_time_s.4", "propellant_kg", "status", "faults.1.present",
                         "tracking_ratio.roll"]) == {
        "scale_factor_error_ppm.roll": "ppm", "mode_end_4_s": "s",
        "gyro.drift_deg_h[0]": "deg/h", "mode_time_s.4": "s", "propellant_kg": "kg",
        "status": "-", "faults.1.present": "-", "tracking_ratio.roll": "-"}


# -- figures, replay, files, how it shows itself -------------------------------------------

def test_every_figure_of_the_flight(flight):
    for name in ("attitude", "switches", "counters", "jets", "calibration"):
        fig = flight.plot(name)
        assert isinstance(fig, Figure) and fig.axes, name
    with pytest.raises(ValueError, match="held no target"):
        flight.plot("hold")
    with pytest.raises(ValueError, match="unknown figure"):
        flight.plot("attitude_errors")


def test_every_figure_file_has_a_name():
    from allsky.apps import plots

    files = {f for f, _ in plots.TELEMETRY_FIGURES.values()} | {plots.CALIBRATION_FILE,
                                                               plots.HOLD_FILE}
    assert set(api.FIGURES.values()) == files


def test_hold_figure_and_no_telemetry():
    held = allsky.fly(set={"target.hold_s": 120.0}, progress=False)
    assert isinstance(held.plot("hold"), Figure)
    bare = allsky.fly(telemetry=False, progress=False)
    assert bare.telemetry.empty and bare.status == "complete"
    with pytest.raises(ValueError, match="no telemetry"):
        bare.replay()
    with pytest.raises(ValueError, match="no telemetry"):
        bare.plot("jets")


class _Frames(HTMLParser):
    def __init__(self):
        super().__init__()
        self.frames = []

    def handle_starttag(self, tag, attrs):
        if tag == "iframe":
            self.frames.append(dict(attrs))


def test_replay_is_an_inline_frame_holding_the_whole_page(flight):
    replay = flight.replay()
    parser = _Frames()
    parser.feed(replay._repr_html_())
    [frame] = parser.frames
    assert frame["srcdoc"] == replay.html  # the attribute unescapes to the page itself
    # Not sandboxed: Chromium's renderer hung on the site's page with a sandboxed one
    # (docs/design.md); the page's own CSP keeps it from making any request.
    assert "sandbox" not in frame
    page = replay.html
    assert page.startswith("<!DOCTYPE html>")
    assert "default-src 'none'" in page and "connect-src 'none'" in page
    assert "http://" not in page.replace("http://www.w3.org/2000/svg", "") and \
        "https://" not in page


def test_save_writes_what_allsky_run_writes(flight, tmp_path):
    written = flight.save(tmp_path / "run", telemetry="csv")
    assert json.loads(written["summary"].read_text()) == {
        "format": 1, **json.loads(json.dumps(flight.summary))}
    table, _ = telemetry_files.read(written["telemetry"])
    np.testing.assert_array_equal(table, flight.table)
    assert {p.name for p in written["figures"]} == {"attitude_errors.png", "switches.png",
                                                    "counters.png", "jets.png",
                                                    "calibration.png"}
    assert written["replay"].read_text() == flight.replay().html
    assert "allsky mission: complete" in written["report"].read_text()
    # The scenario saved flies the same mission again.
    assert load_scenario(written["scenario"]) == flight.scenario
    assert not [p for p in (tmp_path / "run").iterdir() if ".tmp" in p.name]
    with pytest.raises(ValueError, match="telemetry="):
        flight.save(tmp_path / "other", telemetry="xlsx")


class _Balanced(HTMLParser):
    VOID = frozenset({"br", "hr", "img", "meta", "input", "link"})

    def __init__(self):
        super().__init__()
        self.stack, self.text = [], []

    def handle_starttag(self, tag, attrs):
        if tag not in self.VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag):
        assert self.stack and self.stack.pop() == tag, tag

    def handle_data(self, data):
        self.text.append(data)


def test_flight_shows_status_timeline_calibration_end_and_warnings(flight):
    page = flight._repr_html_()
    parser = _Balanced()
    parser.feed(page)
    assert parser.stack == []
    text = " ".join(parser.text)
    assert "complete" in text and "Vega" in text
    for record in flight.summary["modes"]:
        assert f"Mode {record['mode']}:" in page  # the strip's tooltip
    assert "scale factor roll" in text and "truth" in text
    assert f"{flight.summary['end']['true_pointing_error_arcsec']:.1f} arcsec" in text
    assert "Flight complete" in repr(flight)


def test_flight_view_escapes_what_it_shows(flight):
    summary = {**flight.summary, "warnings": ["<script>alert(1)</script> & more"],
               "status": "aborted", "abort_reason": "Mode 4: a < b"}
    page = api.flight_html(summary)
    assert "<script>" not in page and "&lt;script&gt;" in page
    assert "Mode 4: a &lt; b" in page and "Warnings (1)" in page


def test_flight_from_a_stepped_mission(default_cfg, flight):
    m = allsky.Mission(default_cfg)
    m.run_mode()
    part = allsky.Flight(m)
    assert part.status == "running" and list(part.timeline["mode"]) == ["1"]
    assert "not finished" in part._repr_html_()


# -- the kernel's interrupt keeps what finished ------------------------------------------------

def test_fly_interrupted_keeps_the_part_flown(monkeypatch):
    monkeypatch.setattr(mission, "SLICE_FRAMES", 5000)  # slices of 50 s: a leg is cut
    _signal_after(monkeypatch, frame_loop, "run_leg", 3)
    with pytest.warns(api.InterruptedWarning, match="mission stopped at"):
        f = allsky.fly(progress=False)
    assert f.interrupted and f.status == "running"
    assert 0 < f.summary["mission_time_s"] < 300
    assert f.telemetry.index[-1] == pytest.approx(f.summary["mission_time_s"], abs=0.5)
    assert "interrupted" in f._repr_html_()


# -- compare --------------------------------------------------------------------------

def test_compare_rows_are_the_cli_rows_one_per_seed_and_method(tmp_path):
    df = allsky.compare(runs=2, workers=1, progress=False)
    data = _cli_json(tmp_path, ["compare", "--runs", "2", "--workers", "1"])
    assert list(zip(df["seed"], df["method"])) == [(1, "legacy"), (1, "dither"),
                                                    (2, "legacy"), (2, "dither")]
    for (_, row), (seed, method) in zip(df.iterrows(), zip(df["seed"], df["method"])):
        flown = next(r for r in data["rows"] if r["seed"] == seed)[method]
        assert row["status"] == flown["status"]
        assert row["scale_factor_error_ppm.roll"] == flown["scale_factor_error_ppm"]["roll"]
        assert row["mode_time_s.4" if method == "legacy" else "mode_time_s.dither"] == \
            flown["mode_time_s"]["4" if method == "legacy" else "dither"]
        assert row["pointing_error_arcsec"] == flown["pointing_error_arcsec"]
    assert df.attrs["units"]["scale_factor_error_ppm.yaw"] == "ppm"
    assert df.attrs["units"]["time_s"] == "s"
    assert df.attrs["comparison"]["legacy"] == data["legacy"]
    assert df.attrs["interrupted"] is False


def test_compare_with_the_kalman_filter_has_four_methods():
    df = allsky.compare(runs=1, methods=["legacy", "dither", "kalman"], progress=False)
    assert list(df["method"]) == ["legacy", "dither", "kalman", "kalman_dither"]
    assert {"nees", "filter_sigma.scale_factor_ppm.roll"} <= set(df.columns)


def test_compare_methods_are_checked():
    with pytest.raises(ValueError, match="unknown method 'ekf'"):
        allsky.compare(methods=["legacy", "dither", "ekf"])
    with pytest.raises(ValueError, match="always compared"):
        allsky.compare(methods=["legacy", "kalman"])


def test_compare_interrupted_keeps_the_seeds_finished(monkeypatch):
    _signal_after(monkeypatch, compare_study, "fly_pair", 2, when="before")
    with pytest.warns(api.InterruptedWarning, match="after 1 of 3 seeds"):
        df = allsky.compare(runs=3, workers=1, progress=False)
    assert df.attrs["interrupted"] is True
    assert list(df["seed"]) == [1, 1] and list(df["method"]) == ["legacy", "dither"]


# -- montecarlo -----------------------------------------------------------------------

def test_montecarlo_rows_are_the_campaign_record(tmp_path):
    out = tmp_path / "mc"
    df = allsky.montecarlo(runs=3, workers=1, out=out, progress=False)
    cfg = load_scenario()
    assert list(df.columns) == mc_study.columns(cfg)
    assert list(df["run"]) == [0, 1, 2] and list(df["seed"]) == [1, 2, 3]
    recorded = sorted(campaign.read_rows(out), key=lambda r: r["run"])
    for row, rec in zip(df.to_dict("records"), recorded):
        for col in df.columns:
            a, b = row[col], rec[col]
            assert (b is None and (a is None or (isinstance(a, float) and math.isnan(a)))) \
                or a == b, col
    assert df.attrs["summary"]["complete"] == 3
    assert df.attrs["summary"]["outcomes"] == {"complete": {"runs": 3, "probability": 1.0}}
    assert df.attrs["units"]["mode_end_4_s"] == "s"
    for name in (campaign.SUMMARY_TEXT, campaign.SUMMARY_JSON, campaign.HISTOGRAMS):
        assert (out / name).exists(), name
    # Resumed and extended, as --resume: only the runs it lacks are flown.
    more = allsky.montecarlo(runs=5, workers=1, out=out, resume=True, progress=False)
    assert list(more["run"]) == [0, 1, 2, 3, 4]
    assert more.iloc[:3].equals(df)


def test_montecarlo_arguments_are_checked(tmp_path):
    with pytest.raises(ValueError, match="resume=True needs out=DIR"):
        allsky.montecarlo(runs=2, resume=True)
    with pytest.raises(ValueError, match="runs=0"):
        allsky.montecarlo(runs=0)
    (tmp_path / "file").write_text("")
    with pytest.raises(OutputError, match="not a directory"):
        allsky.montecarlo(runs=2, out=tmp_path / "file" / "mc")
    # batch means what --batch means: runs per Dask task, nothing without a scheduler
    with pytest.raises(CampaignError, match="batches are for a Dask cluster"):
        allsky.montecarlo(runs=2, batch=3)


def test_montecarlo_interrupted_keeps_the_runs_finished(monkeypatch):
    _signal_after(monkeypatch, mc_study, "fly_one", 3, when="before")
    with pytest.warns(api.InterruptedWarning, match="after 2 of 6 runs"):
        df = allsky.montecarlo(runs=6, workers=1, progress=False)
    assert df.attrs["interrupted"] is True and list(df["run"]) == [0, 1]


# -- import allsky stays light; the names are declared ------------------------------------

def test_import_allsky_and_its_api_names_load_neither_numpy_nor_pandas():
    code = ("import sys, allsky\n"
            "names = [allsky.fly, allsky.Flight, allsky.compare, allsky.montecarlo]\n"
            "print(sorted(m for m in ('numpy', 'pandas', 'matplotlib', 'numba') "
            "if m in sys.modules))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    assert done.stdout.strip() == "[]"


def test_the_stub_declares_every_public_name_where_it_lives():
    import ast

    stub = ast.parse((Path(allsky.__file__).parent / "__init__.pyi").read_text())
    declared = {}
    for node in stub.body:
        if isinstance(node, ast.ImportFrom):
            for alias in node.names:
                assert alias.asname == alias.name  # re-exported explicitly
                declared[alias.name] = node.module
        elif isinstance(node, ast.Assign) and node.targets[0].id == "__all__":
            assert ast.literal_eval(node.value) == allsky.__all__
    assert declared == allsky._EXPORTS
    assert set(allsky.__all__) == set(declared) | {"__version__"}
    for name in allsky.__all__:
        assert getattr(allsky, name) is not None
        assert name in dir(allsky)
    assert (Path(allsky.__file__).parent / "py.typed").exists()


def test_the_public_functions_are_annotated_and_document_every_parameter():
    import inspect

    for f in (allsky.fly, allsky.compare, allsky.montecarlo):
        sig = inspect.signature(f)
        assert sig.return_annotation is not inspect.Signature.empty, f.__name__
        params = f.__doc__.split("Parameters\n    ----------\n", 1)[1].split("Returns\n")[0]
        for name, p in sig.parameters.items():
            assert p.annotation is not inspect.Parameter.empty, (f.__name__, name)
            assert f"\n    {name} : " in "\n" + params, (f.__name__, name)


# -- in a Jupyter kernel ------------------------------------------------------------------

def _kernel():
    pytest.importorskip("ipykernel", reason="pip install '.[docs]' (a Jupyter kernel)")
    jupyter_client = pytest.importorskip("jupyter_client")
    km = jupyter_client.KernelManager(kernel_name="python3")
    km.start_kernel(extra_arguments=["--HistoryManager.enabled=False"])
    kc = km.client()
    kc.start_channels()
    kc.wait_for_ready(timeout=120)
    return km, kc


def _run(kc, code, on_output=None, timeout=300):
    """Execute ``code``; return {mime: data} of its results and the stream text."""
    msg_id = kc.execute(code)
    data, stream = {}, []
    while True:
        msg = kc.get_iopub_msg(timeout=timeout)
        if msg["parent_header"].get("msg_id") != msg_id:
            continue
        kind, content = msg["msg_type"], msg["content"]
        if kind in ("execute_result", "display_data"):
            data.update(content["data"])
        elif kind == "stream":
            stream.append(content["text"])
            if on_output is not None:
                on_output("".join(stream))
        elif kind == "error":
            raise AssertionError("\n".join(content["traceback"]))
        elif kind == "status" and content["execution_state"] == "idle":
            return data, "".join(stream)


def test_in_jupyter_a_flight_shows_itself_its_figure_replay_and_progress_bar():
    km, kc = _kernel()
    try:
        data, _ = _run(kc, "import allsky\nf = allsky.fly()\nf")
        assert "allsky mission: <span" in data["text/html"]
        has_widgets = _run(kc, "import importlib.util\n"
                               "print(importlib.util.find_spec('ipywidgets') is not None)")[1]
        if has_widgets.strip() == "True":  # the progress bar is tqdm's notebook widget
            assert "application/vnd.jupyter.widget-view+json" in _run(
                kc, "g = allsky.fly(telemetry=False)")[0]
        data, _ = _run(kc, "f.plot('attitude')")
        assert data["image/png"]
        data, _ = _run(kc, "f.replay()")
        assert data["text/html"].startswith('<iframe class="allsky-replay"')
    finally:
        kc.stop_channels()
        km.shutdown_kernel(now=True)


def test_the_kernels_interrupt_keeps_the_runs_finished():
    """Jupyter's interrupt (SIGINT to the kernel) in the middle of a campaign.

    The kernel flies in-process (one worker); after its third run a wrapped
    run says so and waits; the client then interrupts the kernel, as the
    notebook's stop button does.
    """
    km, kc = _kernel()
    try:
        _run(kc, "import sys, time, allsky\n"
                 "from allsky.studies import montecarlo as m\n"
                 "fly_one, done = m.fly_one, []\n"
                 "def slow(*a):\n"
                 "    if len(done) == 3:\n"
                 "        print('three runs done', flush=True); time.sleep(120)\n"
                 "    done.append(fly_one(*a)); return done[-1]\n"
                 "m.fly_one = slow\n")
        asked = []

        def interrupt(text):
            if "three runs done" in text and not asked:
                asked.append(True)
                km.interrupt_kernel()

        _, text = _run(kc, "import warnings\n"
                           "with warnings.catch_warnings(record=True) as caught:\n"
                           "    warnings.simplefilter('always')\n"
                           "    df = allsky.montecarlo(runs=8, workers=1)\n"
                           "print(len(df), df.attrs['interrupted'], "
                           "[w.category.__name__ for w in caught])", on_output=interrupt)
        assert asked
        assert text.strip().splitlines()[-1] == "3 True ['InterruptedWarning']"
    finally:
        kc.stop_channels()
        km.shutdown_kernel(now=True)
