"""The generated reference pages match the code, and every key is documented."""

import re
from pathlib import Path

import pytest

from allsky.apps import docgen
from allsky.config import schema as config

DOCS = Path(__file__).resolve().parents[2] / "docs"


@pytest.mark.parametrize("name", sorted(docgen.PAGES))
def test_committed_page_is_what_the_code_generates(name):
    committed = (DOCS / name).read_text()
    assert committed == docgen.PAGES[name](), (
        f"docs/{name} is out of date: run `python -m allsky.apps.docgen docs`")


def test_every_key_has_a_meaning_a_rule_text_and_a_default_column():
    meanings, _ = docgen.key_comments(docgen.default_toml_text())
    meanings = {**docgen.UNSET_KEY_MEANINGS, **meanings}
    page = docgen.config_reference()
    for key in config.RULES:
        assert meanings.get(key), f"{key}: no comment beside it in default.toml"
        assert config.allowed(key)
        assert f"| `{key.split('.', 1)[1]}` |" in page


@pytest.mark.parametrize("key, unit", [
    ("gyro.drift_deg_h", "deg/h"), ("gyro.arw_deg_rt_h", "deg/sqrt(h)"),
    ("gyro.rrw_deg_h_rt_h", "deg/h/sqrt(h)"), ("vehicle.inertia_kg_m2", "kg m^2"),
    ("control.rate_gain_v_per_arcsec_s", "V/(arcsec/s)"), ("jets.thrust_n", "N"),
    ("electronics.counter_bits", "bit"), ("dither.amplitude_urad", "urad"),
    ("sequencer.mode1_slew_gain_per_s", "1/s"), ("mission.seed", "-"),
])
def test_unit_from_the_key_suffix(key, unit):
    assert docgen.unit_of(key) == unit


def test_units_are_known_for_every_key_with_a_unit_suffix():
    unitless = {"mission.seed", "ejection.attitude", "pwpf.filter_gain",
                "electronics.counter_overflow", "calibration.apply", "dither.feedforward",
                "dither.inertia_estimate_scale", "dither.estimator", "dither.detector",
                "dither.store_cross_coupling", "target.star", "star_tracker.reference_star",
                "actuators.kind", "wheels.axes", "wheels.unload_fraction",
                "wheels.unload_end_fraction", "wheels.allocation", "sequencer.recovery",
                "sequencer.between_targets", "target.sequence", "star_tracker.bright_gate",
                "star_tracker.moving_bodies",
                "jets.supply", "orbit.kind", "orbit.j2", "orbit.tle_line1", "orbit.tle_line2",
                "orbit.gravity_gradient", "orbit.aerodynamic", "orbit.drag_coefficient",
                "orbit.solar_pressure", "orbit.srp_reflectivity"}
    for key in config.RULES:
        if key not in unitless:
            assert docgen.unit_of(key) != "-", key


def test_cli_page_has_every_command():
    page = docgen.cli_reference()
    for command in ("run", "step", "compare", "config show", "config check"):
        assert f"## allsky {command}\n" in page


@pytest.mark.parametrize("page, section", [(p, n) for p, secs in sorted(docgen.SECTIONS.items())
                                           for n in secs])
def test_committed_section_is_what_the_code_generates(page, section):
    committed = (DOCS / page).read_text()
    expected = docgen.fill_sections(committed, {section: docgen.SECTIONS[page][section]})
    assert committed == expected, (
        f"section {section!r} of docs/{page} is out of date: run "
        "`python -m allsky.apps.docgen docs`")


def test_a_page_without_its_section_markers_is_refused():
    with pytest.raises(ValueError, match="modes"):
        docgen.fill_sections("no markers here", {"modes": docgen.mode_reference})


def test_mode_page_shows_every_mode_code_and_switch_action():
    from allsky.sequencer import modes

    page = docgen.mode_reference()
    for mode in modes.MODE_TABLE:
        assert f"### Mode {mode.name}: {mode.title}" in page
        assert f"| {mode.name} | {mode.code:.1f} | {mode.title} |" in page
    # SPEC section 4, Mode 2: close S16+S18; on the hand-over open them and close S12.
    assert "| close S16+S18; open S16+S18, close S12 | S12, S14, S15 |" in page


def test_block_diagram_draws_every_numeral_and_an_existing_module(tmp_path):
    import importlib

    from allsky.apps import diagram_layout
    from tests.hardware.test_block_map import DRAWN_NUMERALS

    fig = docgen.block_diagram(tmp_path / "d.png")
    assert (tmp_path / "d.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    texts = " ".join(t.get_text() for t in fig.axes[0].texts)
    drawn = set(re.findall(r"\d+", texts))
    assert DRAWN_NUMERALS <= drawn, DRAWN_NUMERALS - drawn
    for numeral in diagram_layout.BOXES:
        block = docgen._block(numeral)
        importlib.import_module(block.modules[0])
    for k in range(1, 20):
        if k in (7, 8):
            assert f"S{k}" in texts
        else:
            assert any(f"S{a}-S{b}" in texts and a <= k <= b for a in range(1, 20)
                       for b in range(a, 20)) or f"S{k}" in texts, k


def test_switch_labels_come_from_the_wiring_table():
    # SPEC section 3: drift DACs 7/9/11 -> amplifiers 4/5/6 through S1-S3; converters
    # -> drift counters through S4-S6; counters -> CPU through S7; lines 130/131 via S18/S19.
    assert docgen.arrow_label("7", "4") == "S1-S3"
    assert docgen.arrow_label("8", "13") == "S4-S6"
    assert docgen.arrow_label("14", "22") == "S7"
    assert docgen.arrow_label("105", "31") == "S12, S13"
    assert docgen.arrow_label("4", "31") == "lines 130, 131 via S18, S19"
    assert docgen.arrow_label("1", "4") == ""


def test_every_command_help_shows_examples():
    page = docgen.cli_reference()
    sections = page.split("\n## ")[1:]
    assert len(sections) >= 9
    for section in sections:
        name = section.splitlines()[0]
        if name == "allsky config":  # a group: its actions carry the examples
            continue
        assert "examples:\n  allsky" in section, name
