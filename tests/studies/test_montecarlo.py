"""Monte Carlo campaigns (allsky.studies.montecarlo), their durable record
(allsky.apps.campaign) and dispersions (allsky.config.dispersions).

Draws against their declared distributions; the same rows with 1 or 2
worker processes and on a Dask cluster; a campaign killed part way and
resumed equals an uninterrupted one; a campaign row equals the single
``allsky run`` of its seed; bad dispersion specs are refused naming the key.
"""

import json
import os
import signal
import subprocess
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from allsky.apps.campaign import MANIFEST, RESULTS, read_rows, run_recorded
from allsky.apps.cli import main
from allsky.config import ConfigError, dispersions, load_scenario
from allsky.studies import montecarlo
from allsky.studies.montecarlo import columns, row_from_summary, run_campaign, summarize

SRC = Path(__file__).resolve().parents[2] / "src"
#: A spec touching every kind of entry that still flies in a few seconds.
SPEC = """\
[dispersions]
gyro.drift_deg_h = { dist = "normal", sigma = 0.5 }
gyro.scale_factor_error_ppm = { dist = "normal", mean = 0, sigma = [1000, 2000, 1000] }
gyro.misalignment_arcsec = { dist = "uniform", half_width = 100 }
vehicle.inertia_kg_m2 = { dist = "normal", sigma = 0.05, relative = true, shared = true }
"jets.thrust_n" = { dist = "uniform", low = 0.2, high = 0.3 }
mission.date_utc = { dist = "uniform", low = 2026-01-01T00:00:00Z, high = 2027-01-01T00:00:00Z }
target = { dist = "choice", stars = ["Vega", "Arcturus", "Rigel"] }
"""
RUNS = 4


def write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def spec_path(tmp_path_factory):
    return write(tmp_path_factory.mktemp("spec") / "disperse.toml", SPEC)


@pytest.fixture(scope="module")
def spec_cfg(spec_path):
    return load_scenario(disperse=spec_path, overrides=["mission.seed=100"])


@pytest.fixture(scope="module")
def reference(tmp_path_factory, spec_cfg):
    """The campaign flown in this process (1 worker), recorded in a directory."""
    out = tmp_path_factory.mktemp("mc") / "ref"
    result = run_recorded(spec_cfg, runs=RUNS, workers=1, out=out)
    assert result["flown"] == RUNS and not result["interrupted"]
    return out, result


def dispersed(key, entry):
    """The default scenario with one dispersion (``entry`` in TOML inline-table syntax)."""
    return load_scenario(overrides=[f"dispersions.{key}={entry}"])


def draws(cfg, key, n=3000):
    """``n`` draws of ``key`` over seeds 0..n-1 (no mission flown)."""
    return [dispersions.draw(cfg, seed)[key] for seed in range(n)]


# -- the draws follow their declared distributions -------------------------------------

def test_normal_about_the_scenario_value_elementwise():
    cfg = dispersed("gyro.drift_deg_h", '{dist="normal",sigma=0.5}')
    x = np.array(draws(cfg, "gyro.drift_deg_h"))
    n = len(x)
    for i, mean in enumerate((1.2, -0.8, 1.5)):  # the default scenario's drift
        assert abs(x[:, i].mean() - mean) < 4 * 0.5 / np.sqrt(n)
        assert abs(x[:, i].std(ddof=1) / 0.5 - 1) < 4 / np.sqrt(2 * n)
        assert stats.kstest(x[:, i], "norm", args=(mean, 0.5)).pvalue > 1e-3
    assert abs(np.corrcoef(x[:, 0], x[:, 1])[0, 1]) < 4 / np.sqrt(n)  # drawn independently


def test_normal_with_mean_and_sigma_per_element():
    cfg = dispersed("gyro.scale_factor_error_ppm", '{dist="normal",mean=0,sigma=[100,2000,0]}')
    x = np.array(draws(cfg, "gyro.scale_factor_error_ppm"))
    assert stats.kstest(x[:, 0], "norm", args=(0, 100)).pvalue > 1e-3
    assert stats.kstest(x[:, 1], "norm", args=(0, 2000)).pvalue > 1e-3
    assert np.all(x[:, 2] == 0.0)


def test_uniform_low_high_bounds_and_shape():
    cfg = dispersed("jets.thrust_n", '{dist="uniform",low=0.2,high=0.3}')
    x = np.array(draws(cfg, "jets.thrust_n"))
    assert np.all((x >= 0.2) & (x <= 0.3))
    for i in range(3):
        assert stats.kstest(x[:, i], "uniform", args=(0.2, 0.1)).pvalue > 1e-3


def test_uniform_half_width_keeps_the_misalignment_diagonal_zero():
    cfg = dispersed("gyro.misalignment_arcsec", '{dist="uniform",half_width=50}')
    m0 = np.array(cfg.gyro.misalignment_arcsec)
    x = np.array(draws(cfg, "gyro.misalignment_arcsec", n=2000))
    assert np.all(x[:, [0, 1, 2], [0, 1, 2]] == 0.0)
    off = ~np.eye(3, dtype=bool)
    dev = (x - m0)[:, off]
    assert np.all(np.abs(dev) <= 50.0)
    assert stats.kstest(dev[:, 0], "uniform", args=(-50, 100)).pvalue > 1e-3


def test_relative_shared_scale_keeps_the_inertia_symmetric_and_its_axes():
    cfg = dispersed("vehicle.inertia_kg_m2", '{dist="normal",sigma=0.05,relative=true,shared=true}')
    j0 = np.array(cfg.vehicle.inertia_kg_m2)
    x = np.array(draws(cfg, "vehicle.inertia_kg_m2", n=2000))
    factor = x[:, 0, 0] / j0[0, 0]
    np.testing.assert_allclose(x, factor[:, None, None] * j0, rtol=1e-14)
    assert stats.kstest(factor, "norm", args=(1.0, 0.05)).pvalue > 1e-3


def test_relative_elementwise_inertia_draws_the_upper_triangle_and_mirrors_it():
    cfg = dispersed("vehicle.inertia_kg_m2", '{dist="uniform",half_width=0.01,relative=true}')
    x = np.array(draws(cfg, "vehicle.inertia_kg_m2", n=500))
    assert np.all(x == np.transpose(x, (0, 2, 1)))
    ratio = x / np.array(cfg.vehicle.inertia_kg_m2)
    assert np.all(np.abs(ratio - 1) <= 0.01 + 1e-15)
    assert np.std(ratio[:, 0, 0] - ratio[:, 1, 1]) > 0  # elements drawn independently


def test_date_uniform_over_a_span():
    lo, hi = datetime(2026, 1, 1, tzinfo=UTC), datetime(2027, 1, 1, tzinfo=UTC)
    cfg = dispersed("mission.date_utc", '{dist="uniform",low=2026-01-01T00:00:00Z,'
                    'high=2027-01-01T00:00:00Z}')
    t = np.array([(datetime.fromisoformat(d) - lo).total_seconds()
                  for d in draws(cfg, "mission.date_utc", n=2000)])
    span = (hi - lo).total_seconds()
    assert np.all((t >= 0) & (t <= span))
    assert stats.kstest(t, "uniform", args=(0, span)).pvalue > 1e-3


def test_target_uniform_over_the_sphere():
    cfg = dispersed("target", '{dist="sphere"}')
    d = draws(cfg, "target")
    ra = np.array([x["ra_deg"] for x in d])
    sin_dec = np.sin(np.radians([x["dec_deg"] for x in d]))
    assert np.all((ra >= 0) & (ra < 360))
    assert stats.kstest(ra, "uniform", args=(0, 360)).pvalue > 1e-3
    assert stats.kstest(sin_dec, "uniform", args=(-1, 2)).pvalue > 1e-3


def test_target_choice_among_stars_equally_likely():
    cfg = dispersed("target", '{dist="choice",stars=["vega","Arcturus","Rigel"]}')
    names = [x["star"] for x in draws(cfg, "target")]
    counts = [names.count(s) for s in ("Vega", "Arcturus", "Rigel")]
    assert sum(counts) == len(names)
    assert stats.chisquare(counts).pvalue > 1e-3


def test_draws_depend_on_seed_and_key_only(spec_cfg):
    """Adding a dispersion leaves the others' draws unchanged; the seed alone decides."""
    alone = load_scenario(overrides=['dispersions.gyro.drift_deg_h={dist="normal",sigma=0.5}',
                                     "mission.seed=100"])
    for seed in (0, 7, 2**32 - 1):
        assert (dispersions.draw(alone, seed)["gyro.drift_deg_h"]
                == dispersions.draw(spec_cfg, seed)["gyro.drift_deg_h"])
    assert dispersions.draw(spec_cfg, 7) != dispersions.draw(spec_cfg, 8)


# -- the syntax: spellings, merging, round trip ----------------------------------------

def test_quoted_and_nested_keys_and_removal(tmp_path):
    cfg = load_scenario(write(tmp_path / "s.toml", SPEC))
    assert list(dispersions.spec(cfg)) == [
        "gyro.drift_deg_h", "gyro.scale_factor_error_ppm", "gyro.misalignment_arcsec",
        "vehicle.inertia_kg_m2", "jets.thrust_n", "mission.date_utc", "target"]
    # A --disperse file and --set merge by key; dist = "none" removes an entry.
    extra = write(tmp_path / "d.toml", '[dispersions]\n"gyro.drift_deg_h" = { dist = "none" }\n'
                  'jets.thrust_n = { dist = "normal", sigma = 0.01 }\n')
    cfg2 = load_scenario(tmp_path / "s.toml", ['dispersions.target={dist="sphere"}'],
                         disperse=extra)
    spec = dispersions.spec(cfg2)
    assert "gyro.drift_deg_h" not in spec
    assert spec["jets.thrust_n"] == {"dist": "normal", "sigma": 0.01}
    assert spec["target"] == {"dist": "sphere"}


def test_scenario_with_dispersions_round_trips(tmp_path, spec_cfg):
    again = load_scenario(write(tmp_path / "r.toml", spec_cfg.to_toml()))
    assert again == spec_cfg
    assert json.loads(json.dumps(spec_cfg.as_dict()))["dispersions"] == \
        dispersions.spec(spec_cfg)


def test_default_scenario_has_no_dispersions():
    cfg = load_scenario()
    assert dispersions.spec(cfg) == {}
    assert dispersions.disperse(cfg) == (cfg, {})


@pytest.mark.parametrize("entry, key, words", [
    ('gyro.drfit_deg_h = { dist = "normal", sigma = 1 }', "dispersions.gyro.drfit_deg_h",
     "nearest: gyro.drift_deg_h"),
    ('gyro.drift_deg_h = { dist = "normal", sigma = -1 }', "dispersions.gyro.drift_deg_h.sigma",
     "must be >= 0"),
    ('gyro.drift_deg_h = { dist = "normal" }', "dispersions.gyro.drift_deg_h", "needs sigma"),
    ('gyro.drift_deg_h = { dist = "gauss", sigma = 1 }', "dispersions.gyro.drift_deg_h.dist",
     '"normal" or "uniform"'),
    ('gyro.drift_deg_h = { sigma = 1 }', "dispersions.gyro.drift_deg_h.dist", "missing"),
    ('gyro.drift_deg_h = { dist = "normal", sigma = [1, 2] }',
     "dispersions.gyro.drift_deg_h.sigma", "array of 3 numbers"),
    ('gyro.drift_deg_h = { dist = "normal", sigma = 1, sd = 2 }',
     "dispersions.gyro.drift_deg_h.sd", "unknown parameter"),
    ('gyro.drift_deg_h = { dist = "uniform", low = 1, high = 0 }',
     "dispersions.gyro.drift_deg_h.high", "must be >= low"),
    ('gyro.drift_deg_h = { dist = "uniform", low = 0, high = 1, half_width = 1 }',
     "dispersions.gyro.drift_deg_h", "not both"),
    ('gyro.drift_deg_h = 0.5', "dispersions.gyro.drift_deg_h", "must be a table"),
    ('mission.seed = { dist = "normal", sigma = 1 }', "dispersions.mission.seed",
     "cannot be dispersed"),
    ('electronics.counter_bits = { dist = "normal", sigma = 1 }',
     "dispersions.electronics.counter_bits", "cannot be dispersed"),
    ('mission.date_utc = { dist = "normal", sigma = 1 }', "dispersions.mission.date_utc.dist",
     '"uniform"'),
    ('mission.date_utc = { dist = "uniform", low = 1850-01-01, high = 2027-01-01 }',
     "dispersions.mission.date_utc.low", "ephemeris range"),
    ('target = { dist = "choice", stars = ["Sirus"] }', "dispersions.target.stars",
     "nearest: Sirius"),
    ('target = { dist = "choice", stars = [] }', "dispersions.target.stars", "non-empty"),
    # the default date is 27067.4 days before the last start of its 4500 s mission
    ('mission.date_utc = { dist = "uniform", half_width_days = 1e6 }',
     "dispersions.mission.date_utc.half_width_days", "must be <= 27067.4: the drawn dates"),
    ('mission.date_utc = { dist = "uniform", half_width_days = 1e10 }',
     "dispersions.mission.date_utc.half_width_days", "must be <= 27067.4"),
    ('mission.date_utc = { dist = "uniform", low = 2100-01-01, high = 2100-12-31T23:00:00Z }',
     "dispersions.mission.date_utc.high", "must be <= 2100-12-31T22:44:59.999999Z"),
])
def test_bad_spec_exit_2_naming_the_key(tmp_path, capsys, entry, key, words):
    spec = write(tmp_path / "bad.toml", f"[dispersions]\n{entry}\n")
    assert main(["montecarlo", "--runs", "2", "--disperse", str(spec), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"allsky: error: {key}") and words in err and err.count("\n") == 1
    assert main(["run", "--disperse", str(spec)]) == 2  # the same check for allsky run
    assert capsys.readouterr().err == err


def test_disperse_file_holds_only_dispersions(tmp_path, capsys):
    spec = write(tmp_path / "x.toml", "[gyro]\narw_deg_rt_h = 0.1\n[dispersions]\n")
    assert main(["montecarlo", "--runs", "1", "--disperse", str(spec)]) == 2
    assert "holds only a [dispersions] table, not 'gyro'" in capsys.readouterr().err


def test_a_draw_breaking_a_rule(capsys):
    bad = 'dispersions.jets.thrust_n={dist="uniform",low=-1,high=-0.5}'
    result = run_campaign(load_scenario(overrides=[bad]), runs=2, workers=1)
    assert [r["status"] for r in result["rows"]] == ["invalid", "invalid"]
    assert "jets.thrust_n" in result["rows"][0]["abort_reason"]
    assert result["summary"]["invalid"] == 2
    assert main(["run", "--set", bad]) == 2
    err = capsys.readouterr().err
    assert err.startswith("allsky: error: jets.thrust_n = ") and "mission.seed = 1" in err


def test_every_date_of_an_accepted_span_flies():
    """The widest half-width accepted: every draw is a date the ephemeris serves to the end."""
    cfg = dispersed("mission.date_utc", '{ dist = "uniform", half_width_days = 27067 }')
    dates = [dispersions.disperse(cfg, seed)[0].mission.date_utc for seed in range(300)]
    assert max(dates) > datetime(2100, 1, 1, tzinfo=UTC) > datetime(1900, 1, 1, tzinfo=UTC)


def test_a_draw_that_cannot_be_made_gives_an_invalid_row():
    """A spec no loader accepts (a Scenario built without validation) still gives a row."""
    from allsky.config import Scenario

    ok = load_scenario(overrides=["mission.seed=100"])
    sections = {name: dict(getattr(ok, name)._values) for name in ok._sections
                if name != "faults"}  # the faults are a tuple, not a section
    sections["dispersions"] = {"mission.date_utc": {"dist": "uniform", "half_width_days": 1e6}}
    row = montecarlo.fly_one(Scenario(sections), 3, 103)
    assert (row["run"], row["seed"], row["status"]) == (3, 103, "invalid")
    assert "past the calendar" in row["abort_reason"] and row["mission.date_utc"] is None


# -- identical rows whatever flies them --------------------------------------------------

def test_reference_campaign_rows(reference, spec_cfg):
    out, result = reference
    rows = read_rows(out)
    assert rows == result["rows"]  # the file gives back the very floats
    assert [r["run"] for r in rows] == list(range(RUNS))
    assert [r["seed"] for r in rows] == [100 + i for i in range(RUNS)]
    assert all(list(r) == columns(spec_cfg) for r in rows)
    assert all(r["status"] == "complete" for r in rows)
    assert len({r["gyro.drift_deg_h[0]"] for r in rows}) == RUNS  # each run its own draw


def test_two_workers_give_the_same_rows(reference, spec_cfg, tmp_path):
    run_recorded(spec_cfg, runs=RUNS, workers=2, out=tmp_path / "w2")
    assert read_rows(tmp_path / "w2") == reference[1]["rows"]


def test_rows_go_to_the_callback_as_they_finish_and_done_runs_are_not_flown(reference,
                                                                            spec_cfg):
    """A campaign given rows already flown flies only the others, handing each to ``on_row``."""
    ref = reference[1]["rows"]
    seen, progress = [], []
    result = run_campaign(spec_cfg, runs=RUNS, workers=1, done=ref[:2], on_row=seen.append,
                          on_progress=lambda done, total: progress.append((done, total)))
    assert seen == ref[2:] and result["flown"] == RUNS - 2
    assert progress == [(2, RUNS), (3, RUNS), (4, RUNS)]
    assert result["rows"] == ref and result["summary"] == reference[1]["summary"]


def test_dask_cluster_gives_the_same_rows(reference, spec_cfg):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        result = run_campaign(spec_cfg, runs=RUNS, scheduler=cluster.scheduler_address)
    assert result["rows"] == reference[1]["rows"]


def test_unreachable_scheduler_exit_2(capsys, monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.setattr(montecarlo, "DASK_CONNECT_TIMEOUT_S", 1.0)
    assert main(["montecarlo", "--runs", "1", "--scheduler", "tcp://127.0.0.1:9",
                 "--quiet"]) == 2
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in capsys.readouterr().err


def test_campaign_row_equals_the_single_run(reference, spec_cfg, spec_path, tmp_path, capsys):
    row = reference[1]["rows"][2]
    js = tmp_path / "s.json"
    assert main(["run", "--disperse", str(spec_path), "--set", f"mission.seed={row['seed']}",
                 "--json", str(js)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"Dispersions drawn for mission.seed = {row['seed']}\n")
    summary = json.loads(js.read_text())
    inputs = dispersions.flat_inputs(spec_cfg, summary["dispersions"])
    assert row_from_summary(2, row["seed"], inputs, summary) == row


# -- durability: crash, Ctrl-C, resume -----------------------------------------------------

def _cli(*args):
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    return subprocess.Popen([sys.executable, "-m", "allsky", "montecarlo", *args, "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


def _wait_rows(out: Path, n: int, proc, timeout_s=120):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        path = out / RESULTS
        if path.exists() and path.read_bytes().count(b"\n") >= n + 1:
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    raise AssertionError("campaign too slow")


def test_killed_campaign_resumed_equals_the_uninterrupted_one(reference, spec_path, tmp_path,
                                                              capsys):
    out = tmp_path / "crash"
    proc = _cli("--disperse", str(spec_path), "--set", "mission.seed=100", "--runs", str(RUNS),
                "--workers", "1", "--out", str(out))
    _wait_rows(out, 2, proc)
    proc.kill()  # SIGKILL: no chance to tidy up
    proc.communicate()
    assert 2 <= len(read_rows(out)) < RUNS
    with (out / RESULTS).open("ab") as f:  # as if killed in the middle of writing a row
        f.write(b"3,103,complete,,0.123")
    assert main(["montecarlo", "--disperse", str(spec_path), "--set", "mission.seed=100",
                 "--out", str(out), "--resume", "--quiet"]) == 0
    assert read_rows(out) == reference[1]["rows"]
    lines = (out / RESULTS).read_text().splitlines()
    assert len(lines) == RUNS + 1 and b"0.123\n" not in (out / RESULTS).read_bytes()
    assert "Monte Carlo campaign: 4 of 4 runs recorded" in capsys.readouterr().out


def test_ctrl_c_saves_what_finished_and_exits_130(spec_path, tmp_path, monkeypatch, capsys):
    """SIGINT sent the moment the first row is on disk, with 200 runs to go: always 130."""
    from allsky.apps import campaign

    write = campaign.ResultsFile.write
    sent = []

    def write_then_interrupt(self, row):
        write(self, row)
        if not sent:
            sent.append(row["run"])
            os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(campaign.ResultsFile, "write", write_then_interrupt)
    out = tmp_path / "sigint"
    code = main(["montecarlo", "--disperse", str(spec_path), "--runs", "200", "--workers", "2",
                 "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 130, err
    assert "Traceback" not in err and f"continue with --resume --out {out}" in err
    rows = read_rows(out)
    # Every row is a finished run (a dispersed draw may abort: a weak yaw couple can leave
    # the Sun inside the hand-over threshold when Mode 5's blanking ends).
    assert 1 <= len(rows) < 200 and all(r["status"] in ("complete", "aborted") for r in rows)
    assert (out / RESULTS).read_bytes().endswith(b"\n")


def test_resume_refuses_another_campaign(reference, spec_path, capsys):
    out = reference[0]
    args = ["montecarlo", "--disperse", str(spec_path), "--out", str(out), "--quiet"]
    assert main([*args, "--set", "mission.seed=100", "--runs", "4"]) == 2
    assert "already holds a campaign" in capsys.readouterr().err
    assert main([*args, "--resume", "--set", "mission.seed=100",
                 "--set", "gyro.arw_deg_rt_h=0.01"]) == 2
    err = capsys.readouterr().err
    assert "different scenario: gyro.arw_deg_rt_h = 0.001 there, 0.01 here" in err
    assert main([*args, "--resume", "--set", "mission.seed=100", "--runs", "2"]) == 2
    assert "would shorten it" in capsys.readouterr().err
    assert main([*args, "--resume", "--set", "mission.seed=100"]) == 0  # already complete
    assert json.loads((out / MANIFEST).read_text())["runs"] == RUNS


def test_resume_needs_a_campaign(tmp_path, capsys):
    assert main(["montecarlo", "--out", str(tmp_path / "none"), "--resume"]) == 2
    assert "no campaign to resume" in capsys.readouterr().err
    assert main(["montecarlo"]) == 2
    assert "--runs N is needed" in capsys.readouterr().err
    assert main(["montecarlo", "--runs", "2", "--set", f"mission.seed={2**32 - 1}"]) == 2
    assert "pass the largest mission.seed (4294967295)" in capsys.readouterr().err


# -- a damaged campaign record is refused, in one line naming the file and the line ------------

@pytest.fixture()
def copied(reference, tmp_path):
    """A copy of the reference campaign directory, and the arguments that resume it."""
    import shutil

    out = tmp_path / "copy"
    shutil.copytree(reference[0], out)
    return out


def _resume(capsys, out, spec_path):
    code = main(["montecarlo", "--disperse", str(spec_path), "--set", "mission.seed=100",
                 "--out", str(out), "--resume", "--workers", "1", "--quiet"])
    out_text, err = capsys.readouterr()
    return code, out_text, err


def _refused(capsys, out, spec_path, words):
    """Exit 2 with one line naming the option, the file and ``words``."""
    code, _, err = _resume(capsys, out, spec_path)
    assert code == 2 and err.startswith("allsky: error: --resume: ") and err.count("\n") == 1, err
    assert words in err, err
    return err


@pytest.mark.parametrize("runs", ['"twelve"', "[]", "-3", "0", "true", "1.5", "4294967197"])
def test_resume_refuses_a_manifest_with_bad_runs(capsys, copied, spec_path, runs):
    m = copied / MANIFEST
    data = json.loads(m.read_text())
    m.write_text(json.dumps({**data, "runs": json.loads(runs)}))
    _refused(capsys, copied, spec_path, f"{m}: runs = {runs} is not a number of runs "
                                        "(1..4294967196 from base_seed 100)")


@pytest.mark.parametrize("content, words", [
    (b"{", "not JSON (Expecting property name"),
    (b"\xff{}", "not UTF-8 text (byte 0xff at offset 0)"),
    (b"[1, 2]", "not an allsky campaign manifest (format 1)"),
    (b"", "not JSON"),
])
def test_resume_refuses_a_manifest_that_is_not_one(capsys, copied, spec_path, content, words):
    (copied / MANIFEST).write_bytes(content)
    _refused(capsys, copied, spec_path, f"{copied / MANIFEST}: {words}")


def _lines(out):
    return (out / RESULTS).read_bytes().splitlines(keepends=True)


def _with_cell(line: bytes, col: str, text: str, cols) -> bytes:
    cells = line.rstrip(b"\n").split(b",")
    cells[cols.index(col)] = text.encode()
    return b",".join(cells) + b"\n"


def test_resume_refuses_results_without_a_header(capsys, copied, spec_path):
    """Rows once went on being appended without a header, and the next resume crashed."""
    path = copied / RESULTS
    rows = _lines(copied)[1:]
    path.write_bytes(b"")
    _refused(capsys, copied, spec_path, f"{path}: empty, no header line")
    assert path.read_bytes() == b""  # nothing appended to it
    path.write_bytes(b"".join(rows))
    _refused(capsys, copied, spec_path, f"{path}: line 1, the header: column 1 is '0', this "
                                        "campaign's is 'run'")


@pytest.mark.parametrize("edit, words", [
    (lambda line, cols: line[:5] + b"\xff" + line[5:], "line 3: not UTF-8 text (byte 0xff)"),
    (lambda line, cols: _with_cell(line, "pointing_error_arcsec", "abc", cols),
     "line 3, column 'pointing_error_arcsec': 'abc' is not a number"),
    (lambda line, cols: _with_cell(line, "run", "1.0", cols),
     "line 3, column 'run': '1.0' is not an integer"),
    (lambda line, cols: _with_cell(line, "run", "-1", cols),
     "line 3: run -1 of a campaign of 4 runs (0..3)"),
    (lambda line, cols: _with_cell(_with_cell(line, "run", "13", cols), "seed", "113", cols),
     "line 3: run 13 of a campaign of 4 runs (0..3)"),
    (lambda line, cols: _with_cell(line, "seed", "7", cols),
     "line 3: run 1 with seed 7; the campaign flies seed 101"),
    (lambda line, cols: _with_cell(line, "status", "done", cols),
     "line 3: status 'done' is not one of complete, aborted, invalid, error"),
    (lambda line, cols: line.rstrip(b"\n") + b",1\n", "line 3 has"),
])
def test_resume_refuses_a_damaged_row(capsys, copied, spec_path, spec_cfg, edit, words):
    lines = _lines(copied)
    lines[2] = edit(lines[2], columns(spec_cfg))
    (copied / RESULTS).write_bytes(b"".join(lines))
    _refused(capsys, copied, spec_path, f"{copied / RESULTS}: {words}")


def test_resume_drops_exact_duplicates_and_refuses_conflicting_rows(capsys, copied, spec_path,
                                                                   spec_cfg, reference):
    lines = _lines(copied)
    (copied / RESULTS).write_bytes(b"".join([*lines, lines[1], lines[3]]))
    code, _, err = _resume(capsys, copied, spec_path)
    assert code == 0 and err == (f"allsky: {copied / RESULTS}: 2 lines repeating another line "
                                 "for the same run left out\n")
    assert read_rows(copied) == reference[1]["rows"]
    changed = _with_cell(lines[1], "pointing_error_arcsec", "0.5", columns(spec_cfg))
    (copied / RESULTS).write_bytes(b"".join([*lines, changed]))
    _refused(capsys, copied, spec_path, f"{copied / RESULTS}: lines 2 and 6 record run 0 "
                                        "differently")


# -- outputs ---------------------------------------------------------------------------------

def test_aborted_missions_are_reported_and_exit_0(tmp_path, capsys):
    out = tmp_path / "abort"
    code = main(["montecarlo", "--runs", "2", "--workers", "1", "--set", "jets.propellant_kg=0.05",
                 "--out", str(out), "--json", "-", "--quiet"])
    assert code == 0
    s = json.loads(capsys.readouterr().out)
    assert (s["runs"], s["complete"], s["aborted"]) == (2, 0, 2)
    assert sum(s["abort_reasons"].values()) == 2
    assert all("propellant exhausted" in reason for reason in s["abort_reasons"])
    assert "Missions not complete" in (out / "summary.txt").read_text()
    assert (out / "histograms.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_summary_statistics():
    rows = [{"status": "complete", "abort_reason": None, "pointing_error_arcsec": float(x),
             "propellant_kg": 0.5} for x in range(1, 101)]
    rows.append({"status": "aborted", "abort_reason": "Mode 1: x", "pointing_error_arcsec": None})
    s = summarize(rows, runs=101, base_seed=1)
    pe = s["metrics"]["pointing_error_arcsec"]
    assert (s["complete"], s["aborted"], s["abort_reasons"]) == (100, 1, {"Mode 1: x": 1})
    assert pe["n"] == 100 and pe["mean"] == 50.5 and pe["p50"] == 50.5
    assert pe["p5"] == pytest.approx(5.95) and pe["p95"] == pytest.approx(95.05)
    assert pe["std"] == pytest.approx(np.std(np.arange(1, 101), ddof=1))
    assert s["metrics"]["propellant_kg"]["std"] == 0.0


def test_campaign_without_a_directory(spec_cfg):
    result = run_campaign(load_scenario(overrides=["mission.seed=100"]), runs=1, workers=1)
    assert result["rows"][0]["run"] == 0 and result["rows"][0]["seed"] == 100
    with pytest.raises(ConfigError):  # a scenario rule still applies to the base scenario
        load_scenario(overrides=["mission.seed=-1"])


def test_two_campaigns_on_one_dask_cluster_keep_their_own_scenario(spec_cfg):
    """Campaign B starts while A's scenario is on the cluster: each gets its own rows.

    A scenario scattered as a dict used to put its sections on the cluster under
    global keys ("gyro", "target", ...), so the second campaign silently flew
    the first one's scenario.
    """
    distributed = pytest.importorskip("distributed")
    cfg_b = load_scenario(overrides=["gyro.arw_deg_rt_h=0.01", "target.star='Vega'",
                                     "mission.seed=500"])
    local_a = run_campaign(spec_cfg, runs=2, workers=1)["rows"]
    local_b = run_campaign(cfg_b, runs=2, workers=1)["rows"]
    assert local_a != local_b
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        jobs = [(i, int(spec_cfg.mission.seed) + i) for i in range(2)]
        # A's scenario is scattered and held while B flies from start to end.
        stream_a, close_a = montecarlo._dask_stream(spec_cfg.as_dict(), jobs,
                                                     cluster.scheduler_address)
        try:
            rows_b = run_campaign(cfg_b, runs=2, scheduler=cluster.scheduler_address)["rows"]
            rows_a = sorted((r for chunk in stream_a for r in chunk), key=lambda r: r["run"])
        finally:
            close_a()
    assert rows_b == local_b
    assert rows_a == local_a
