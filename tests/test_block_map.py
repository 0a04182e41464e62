"""docs/blocks.md against the patent's block list (SPEC sec. 3) and the package itself.

Truth: the numerals of the block diagram of US 4,012,018 as read in SPEC.md
section 3 (listed below). The map must name every one of them; every module
it names must import and mention the numeral (or switch) in its docstring,
and every function it names must exist, so neither side can drift.
"""

import importlib
import re
from pathlib import Path

import pytest

BLOCKS_MD = Path(__file__).resolve().parents[1] / "docs" / "blocks.md"

# SPEC.md section 3: gyros; summing amplifiers; drift DACs; VFCs; drift counters;
# counters; calibration, master and computer sequencers; CPU; registers 23-27;
# DACs 28-30; control amplifiers; PWPF modulators; jets; sun sensor; star
# tracker; computer; rate-command modules; lines 130/131.
PATENT_NUMERALS = {
    "1", "2", "3", "4", "5", "6", "7", "9", "11", "8", "10", "12", "13", "15", "17",
    "14", "16", "18", "19", "20", "21", "22", "23", "24", "25", "26", "27", "28", "29",
    "30", "31", "32", "33", "34", "35", "36", "39", "40", "41", "104", "105", "111",
    "120", "128", "130", "131",
}
SWITCHES = {f"S{k}" for k in range(1, 20)}


def rows():
    """(numerals, modules, names) of every table row of docs/blocks.md."""
    out = []
    for line in BLOCKS_MD.read_text(encoding="utf-8").splitlines():
        if not line.startswith("|") or set(line) <= set("|- "):
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if cells[0] == "numeral":
            assert cells[2:4] == ["module", "function"], line
            continue
        numerals = re.findall(r"S\d+|\d+", cells[0])
        assert numerals or cells[0] == "—", f"row without numeral or '—': {line}"
        modules = re.findall(r"`(allsky(?:\.\w+)+)`", cells[2])
        names = re.findall(r"`(\w+)`", cells[3])
        assert modules, f"row without module: {line}"
        out.append((tuple(numerals), tuple(modules), tuple(names)))
    return out


ROWS = rows()


def mentions(doc: str, numeral: str) -> bool:
    """``numeral`` as a whole token in ``doc`` ("1" not in "14" nor in "0.1"; "S1" not in "S14")."""
    return re.search(rf"(?<![\w.]){re.escape(numeral)}(?!\w|\.\d)", doc) is not None


def test_every_patent_numeral_and_switch_is_mapped():
    mapped = [n for numerals, _, _ in ROWS for n in numerals]
    assert PATENT_NUMERALS | SWITCHES <= set(mapped), \
        sorted(PATENT_NUMERALS | SWITCHES - set(mapped), key=lambda s: (len(s), s))


def test_no_numeral_is_mapped_twice():
    mapped = [n for numerals, _, _ in ROWS for n in numerals]
    assert sorted(n for n in set(mapped) if mapped.count(n) > 1) == []


@pytest.mark.parametrize("numerals, modules, names", ROWS,
                         ids=[",".join(r[0]) or "-".join(r[1]) for r in ROWS])
def test_row_points_at_code_that_names_it(numerals, modules, names):
    imported = [importlib.import_module(m) for m in modules]
    for mod in imported:
        doc = mod.__doc__ or ""
        missing = [n for n in numerals if not mentions(doc, n)]
        assert not missing, f"{mod.__name__} docstring does not mention {missing}"
    for name in names:
        assert any(hasattr(mod, name) for mod in imported), f"no {name} in {modules}"


def test_every_module_named_in_prose_exists():
    for name in set(re.findall(r"`(allsky(?:\.\w+)+)`", BLOCKS_MD.read_text(encoding="utf-8"))):
        importlib.import_module(name)


def test_mentions_is_a_whole_token_match():
    assert mentions("gyros 1, 2, 3", "1") and mentions("lines 130/131.", "131")
    assert not mentions("counters 14, 16", "1") and not mentions("0.1 arcsec", "1")
    assert mentions("S1-S19", "S1") and not mentions("S14", "S1")
