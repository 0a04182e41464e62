"""The command line around scenarios: ``allsky config show|check`` and ``run`` wiring.

Bad input of any kind answers exit code 2 and one line ``allsky: error: ...``
on stderr, never a traceback; a property test mutates the default scenario
file at random to try to make ``allsky config check`` raise.
"""

import math
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import allsky.apps.report
from allsky.apps.cli import main
from allsky.config import DEFAULT_SCENARIO_PATH, Scenario, load_scenario
from allsky.config.toml_io import toml_dumps

DEFAULT_TEXT = DEFAULT_SCENARIO_PATH.read_text()
DEFAULT = tomllib.loads(DEFAULT_TEXT)
SRC = Path(__file__).resolve().parents[2] / "src"


def run_main(capsys, argv):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


# -- config show -----------------------------------------------------------------

def test_config_show_prints_the_resolved_default_as_toml(capsys, tmp_path):
    code, out, err = run_main(capsys, ["config", "show"])
    assert (code, err) == (0, "")
    p = tmp_path / "resolved.toml"
    p.write_text(out)
    assert load_scenario(p) == load_scenario()


def test_config_show_a_file_with_overrides(capsys, tmp_path):
    p = tmp_path / "s.toml"
    p.write_text("[mission]\nseed = 3\n")
    code, out, _ = run_main(capsys, ["config", "show", str(p), "--set", "target.star=Vega",
                                     "--set", "gyro.drift_deg_h=[0,0,1]"])
    data = tomllib.loads(out)
    assert code == 0 and data["mission"]["seed"] == 3 and data["target"] == {"star": "Vega", "hold_s": 0.0}
    assert data["gyro"]["drift_deg_h"] == [0.0, 0.0, 1.0]
    assert data["gyro"]["arw_deg_rt_h"] == DEFAULT["gyro"]["arw_deg_rt_h"]  # every key shown


# -- config check ----------------------------------------------------------------

def test_config_check_ok(capsys, tmp_path):
    p = tmp_path / "s.toml"
    p.write_text("[jets]\npropellant_kg = 2.5\n")
    assert run_main(capsys, ["config", "check", str(p)]) == (0, f"ok: {p}\n", "")


@pytest.mark.parametrize("text, override, message", [
    ("[gyro]\narw_deg_rt_h = -1.0\n", [], "gyro.arw_deg_rt_h = -1.0: must be >= 0"),
    ("", ["--set", "gyro.arw_deg_rt_h=-1"], "gyro.arw_deg_rt_h = -1.0: must be >= 0"),
    ("[gyro]\ndrift_deg_hr = [0, 0, 0]\n", [], "gyro.drift_deg_hr: unknown key; nearest"),
    ("[mission]\nseed = 1\n[gyro\n", [], "TOML syntax error"),
    # once accepted: a frame that never ends, or crashes the compiled loop
    ("", ["--set", "mission.frame_s=1e-12"], "mission.frame_s = 1e-12: must be >= 0.0001"),
    ("", ["--set", "mission.frame_s=1e-300"], "mission.frame_s = 1e-300: must be >= 0.0001"),
    # once accepted: the ephemeris refused the Sun an hour after the start
    ("", ["--set", "mission.date_utc=2100-12-31T23:00:00Z"],
     "mission.date_utc = 2100-12-31T23:00:00+00:00: must be <= 2100-12-31T22:44:59.999999Z"),
    ("", ["--set", "mission.seed=" + "7" * 100_000],
     "digits): must be in [0, 4294967295] (2**32 - 1: 32-bit seeds)"),
    ("[mission]\nseed = " + "7" * 100_000 + "\n", [],
     "digits): must be in [0, 4294967295] (2**32 - 1: 32-bit seeds)"),
])
def test_config_check_bad_input_exit_2(capsys, tmp_path, text, override, message):
    p = tmp_path / "s.toml"
    p.write_text(text)
    code, out, err = run_main(capsys, ["config", "check", str(p), *override])
    assert (code, out) == (2, "")
    assert err.startswith("allsky: error: ") and message in err and err.count("\n") == 1
    if "syntax" in message:
        assert "line 3" in err


def test_config_check_missing_file(capsys, tmp_path):
    code, _, err = run_main(capsys, ["config", "check", str(tmp_path / "none.toml")])
    assert code == 2 and err == f"allsky: error: scenario file not found: {tmp_path}/none.toml\n"


def test_missing_disperse_file_is_named_as_such(capsys, tmp_path):
    code, _, err = run_main(capsys, ["run", "--disperse", str(tmp_path / "none.toml")])
    assert code == 2 and err == f"allsky: error: --disperse file not found: {tmp_path}/none.toml\n"
    (tmp_path / "dir.toml").mkdir()
    code, _, err = run_main(capsys, ["montecarlo", "--runs", "1", "--disperse",
                                     str(tmp_path / "dir.toml")])
    assert code == 2 and err == (f"allsky: error: cannot read --disperse file {tmp_path}/dir.toml: "
                                 "a directory, not a file\n")


@pytest.mark.parametrize("argv", [["config", "check"], ["config"], [], ["frobnicate"],
                                  ["config", "show", "--set"], ["run", "--bogus"]])
def test_usage_errors_exit_2(capsys, argv):
    code, _, err = run_main(capsys, argv)
    assert code == 2 and "usage: allsky" in err


def test_version_and_help_exit_0(capsys):
    assert run_main(capsys, ["--version"])[0] == 0
    code, out, _ = run_main(capsys, ["config", "--help"])
    assert code == 0 and "show" in out and "check" in out


def test_subprocess_bad_file_no_traceback(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("[vehicle]\ninertia_kg_m2 = [[1, 0, 0], [0, -1, 0], [0, 0, 1]]\n")
    r = subprocess.run([sys.executable, "-m", "allsky", "config", "check", str(p)],
                       capture_output=True, text=True, timeout=120, check=False,
                       env={"PYTHONPATH": str(SRC), "PATH": "/usr/bin:/bin"})
    assert r.returncode == 2 and r.stdout == ""
    assert "Traceback" not in r.stderr
    assert r.stderr.startswith("allsky: error: vehicle.inertia_kg_m2 = ")
    assert "positive definite" in r.stderr


# -- run: wired to the library, not flown here --------------------------------------

def test_run_passes_the_scenario_and_arguments(capsys, monkeypatch, tmp_path):
    seen = {}

    def fake_run_from_cli(cfg, args):
        seen.update(cfg=cfg, args=args)
        return 7

    monkeypatch.setattr(allsky.apps.report, "run_from_cli", fake_run_from_cli)
    code = main(["run", "--set", "mission.seed=5", "--json", str(tmp_path / "s.json"),
                 "--telemetry", str(tmp_path / "t.csv")])
    assert code == 7
    assert isinstance(seen["cfg"], Scenario) and seen["cfg"].mission.seed == 5
    assert seen["args"].json == str(tmp_path / "s.json")
    assert seen["args"].telemetry == str(tmp_path / "t.csv")


def test_run_with_a_bad_scenario_never_flies(capsys, monkeypatch):
    monkeypatch.setattr(allsky.apps.report, "run_from_cli", lambda cfg, args: pytest.fail("flown"))
    code, _, err = run_main(capsys, ["run", "--set", "jets.isp_s=nan"])
    assert code == 2 and err == "allsky: error: jets.isp_s = nan: must be finite (not nan or inf)\n"


# -- property: no input makes `config check` raise ---------------------------------------

KEYS = [(s, k) for s, t in DEFAULT.items() for k in t]
SECTIONS = list(DEFAULT)

junk = st.one_of(
    st.sampled_from([math.nan, math.inf, -math.inf, -1.0, 0.0, -0.0, 1e308, -1e308, 5e-324,
                     10**30, -(10**30), 2**32, 2**63 - 1, True, False, "", "random", "wrap",
                     "Vega", [], {}, {"1": 5.0}, [[1.0]], [math.nan] * 3]),
    st.floats(), st.integers(-(2**63), 2**63 - 1), st.text(max_size=12),
    st.lists(st.floats(), max_size=5),
    st.lists(st.lists(st.floats(-1e3, 1e3), min_size=2, max_size=4), min_size=2, max_size=4),
    st.datetimes().map(lambda d: d.isoformat()), st.dates(),
)


@st.composite
def mutated_scenario_files(draw):
    """Default scenario text mutated at the table level and then at the text level."""
    doc = {s: dict(t) for s, t in DEFAULT.items()}
    for _ in range(draw(st.integers(0, 4))):
        kind = draw(st.sampled_from(["value", "value", "value", "scale", "scale", "delete",
                                     "delete_section", "unknown_key", "unknown_section",
                                     "swap"]))
        sec, key = draw(st.sampled_from(KEYS))
        if kind == "value" and sec in doc:
            doc[sec][key] = draw(junk)
        elif kind == "scale" and sec in doc and isinstance(doc[sec].get(key), float):
            doc[sec][key] *= draw(st.sampled_from([-1.0, 0.0, 1e-9, 1e9, math.inf]))
        elif kind == "delete" and sec in doc:
            doc[sec].pop(key, None)
        elif kind == "delete_section":
            doc.pop(sec, None)
        elif kind == "unknown_key" and sec in doc:
            doc[sec][draw(st.from_regex(r"[a-z_]{1,14}", fullmatch=True))] = draw(junk)
        elif kind == "unknown_section":
            doc[draw(st.from_regex(r"[a-z_]{1,12}", fullmatch=True))] = {"x": 1}
        elif kind == "swap":
            other = draw(st.sampled_from(SECTIONS))
            if sec in doc and other in doc:
                doc[sec], doc[other] = doc[other], doc[sec]
    lines = toml_dumps(doc).splitlines()
    for _ in range(draw(st.sampled_from([0, 0, 0, 1, 2]))):  # mostly valid TOML
        kind = draw(st.sampled_from(["garbage", "drop", "duplicate"]))
        at = draw(st.integers(0, len(lines)))
        if kind == "garbage":
            lines.insert(at, draw(st.text(max_size=20)))
        elif kind == "drop" and at < len(lines):
            del lines[at]
        elif kind == "duplicate" and at < len(lines):
            lines.insert(at, lines[at])
    return "\n".join(lines)


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(text=mutated_scenario_files())
def test_config_check_never_raises(capsys, tmp_path, text):
    p = tmp_path / "mutated.toml"
    p.write_text(text, encoding="utf-8", errors="surrogatepass")
    code, out, err = run_main(capsys, ["config", "check", str(p)])
    assert code in (0, 2)
    if code == 2:
        assert err.startswith("allsky: error:") and err.count("\n") == 1 and out == ""
    else:  # ok, and at most the hand-over braking's warning (allsky.sim.braking)
        first, *rest = out.splitlines()
        assert first == f"ok: {p}" and err == ""
        assert len(rest) <= 1 and all(line.startswith("warning: the roll braking ")
                                      for line in rest)


def test_config_show_comments_every_key_and_loads_back(capsys, tmp_path):
    """Each key of `config show` has its meaning, unit and accepted values above it."""
    import tomllib

    from allsky.config import RULES, load_scenario

    assert main(["config", "show", "--set", "mission.seed=9"]) == 0
    text = capsys.readouterr().out
    lines = text.splitlines()
    shown = 0
    table = None
    for i, line in enumerate(lines):
        if line.startswith("["):
            table = line.strip("[]")
        elif "=" in line and not line.startswith("#") and table:
            key = f"{table}.{line.split('=')[0].strip()}"
            if key in RULES:
                shown += 1
                assert lines[i - 1].startswith("# ") and "accepts: " in lines[i - 1], key
    assert shown >= 40
    assert "# fixed simulation frame (100 Hz) [s]; accepts: a number" in text
    path = tmp_path / "shown.toml"
    path.write_text(text)
    assert tomllib.loads(text)["mission"]["seed"] == 9
    assert load_scenario(path) == load_scenario(overrides=["mission.seed=9"])
