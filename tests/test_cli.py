"""The command line: exit codes, no tracebacks for bad input, outputs.

Property test: scenario files mutated at random (deleted keys, wrong types,
NaN/inf, negative or huge numbers, garbage lines, unknown keys) never make
``allsky config check`` raise: it answers 0 or 2 with a one-line error.
"""

import json
import subprocess
import sys
import tomllib

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from allsky.cli import main
from allsky.config import DEFAULT_SCENARIO_PATH

DEFAULT_TEXT = DEFAULT_SCENARIO_PATH.read_text()
DEFAULT = tomllib.loads(DEFAULT_TEXT)
KEYS = [(s, k) for s, t in DEFAULT.items() for k in t]

junk_values = st.one_of(
    st.just("nan"), st.just("inf"), st.just("-inf"), st.just("-1.0"), st.just("0"),
    st.just("1e308"), st.just("true"), st.just('"text"'), st.just("[]"), st.just("[1, 2]"),
    st.just("[[1,2],[3,4]]"), st.just("{ a = 1 }"), st.just("1979-01-01T00:00:00Z"),
    st.integers(-10**12, 10**12).map(str),
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
    st.text(alphabet="abc[]{}=\"'., 0123", max_size=12),
)


@st.composite
def mutated_scenarios(draw):
    lines = DEFAULT_TEXT.splitlines()
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["value", "delete", "garbage", "unknown", "section"]))
        if kind == "value":
            sec, key = draw(st.sampled_from(KEYS))
            lines.append(f"[{sec}]")
            lines.append(f"{key} = {draw(junk_values)}")
        elif kind == "delete" and lines:
            del lines[draw(st.integers(0, len(lines) - 1))]
        elif kind == "garbage":
            lines.insert(draw(st.integers(0, len(lines))), draw(st.text(max_size=20)))
        elif kind == "unknown":
            lines.append(f"[{draw(st.sampled_from(list(DEFAULT)))}]")
            lines.append(f"{draw(st.from_regex(r'[a-z_]{1,12}', fullmatch=True))} = 1")
        else:
            lines.append(f"[{draw(st.from_regex(r'[a-z_]{1,10}', fullmatch=True))}]")
    return "\n".join(lines)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                   HealthCheck.function_scoped_fixture])
@given(text=mutated_scenarios())
def test_mutated_files_never_raise(tmp_path, capsys, text):
    p = tmp_path / "s.toml"
    p.write_bytes(text.encode("utf-8", errors="replace"))
    code = main(["config", "check", str(p)])
    out, errtext = capsys.readouterr()
    assert code in (0, 2)
    if code == 2:
        assert errtext.startswith("allsky: error: ") and errtext.count("\n") == 1
    else:
        assert out.startswith("ok:")


def test_config_show_prints_loadable_toml(capsys):
    assert main(["config", "show", "--set", "mission.seed=3"]) == 0
    data = tomllib.loads(capsys.readouterr().out)
    assert data["mission"]["seed"] == 3


def test_bad_override_exit_2(capsys):
    assert main(["run", "--set", "gyro.arw_deg_rt_h=-1"]) == 2
    assert "gyro.arw_deg_rt_h = -1.0: must be >= 0" in capsys.readouterr().err


def test_subprocess_bad_file_no_traceback(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("[vehicle]\ninertia_kg_m2 = [[1,0,0],[0,-1,0],[0,0,1]]\n")
    r = subprocess.run([sys.executable, "-m", "allsky", "config", "check", str(p)],
                       capture_output=True, text=True, timeout=120, check=False)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr and "positive definite" in r.stderr
    r = subprocess.run([sys.executable, "-m", "allsky", "frobnicate"], capture_output=True,
                       text=True, timeout=120, check=False)
    assert r.returncode == 2 and "Traceback" not in r.stderr


def test_run_writes_json_and_telemetry(tmp_path, capsys):
    js, tl = tmp_path / "s.json", tmp_path / "t.csv"
    assert main(["run", "--json", str(js), "--telemetry", str(tl)]) == 0
    report = capsys.readouterr().out
    assert "Mode timeline" in report and "final pointing error" in report
    s = json.loads(js.read_text())
    assert s["status"] == "complete" and s["abort_reason"] is None
    assert [m["mode"] for m in s["modes"]] == ["1", "2", "3", "4", "5", "6-1", "6-2"]
    for part in ("calibration", "truth"):
        assert set(s[part]) == {"drift_deg_h", "scale_factor", "cross_coupling"}
        assert set(s[part]["cross_coupling"]) == {"roll_into_pitch", "roll_into_yaw",
                                                  "yaw_into_pitch", "yaw_into_roll"}
    assert set(s["target"]) >= {"programmed_roll_deg", "programmed_yaw_deg",
                                "pointing_error_arcsec"}
    assert s["propellant_kg"] > 0
    header = tl.read_text().splitlines()[0]
    assert header.startswith("time [s],mode [-],q_w")


def test_aborted_mission_exit_1(capsys):
    assert main(["run", "--set", "jets.propellant_kg=0.05"]) == 1
    assert "aborted" in capsys.readouterr().out


def test_unwritable_output_exit_2(tmp_path, capsys):
    assert main(["run", "--json", str(tmp_path / "no" / "such" / "dir.json")]) == 2
