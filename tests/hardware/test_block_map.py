"""The block table (allsky.hardware.blocks, docs/blocks.md) against the patent and the package.

Truth: the reference numerals of US 4,012,018 as its text names them (seed
002; SPEC.md section 3): Fig. 2, the block diagram, blocks 1-36 and 39-41,
sun sensor 104, star tracker 105, computer 111, rate-command modules 120 and
128, contacts 121/125/127 (S7) and 124/126/128 (S8), selectors 122 and 123,
lines 130 and 131 and the dashed line 132; Fig. 1, the vehicle 100, ports
102/103, jets 106/107, gas tank 108, bulkhead 109 and control electronics
module 110. The patent numbers both the yaw rate-command module and the yaw
contact of S8 128. The table must name every numeral and every switch
S1-S19; every module it names must import and mention the numeral in its
docstring, and every function it names must exist, so neither side can drift.
docs/blocks.md is generated from the table (tests/apps/test_docgen.py keeps it
current); here it is checked to show every numeral.
"""

import importlib
import re
from pathlib import Path

import pytest

from allsky.hardware import blocks, wiring

BLOCKS_MD = Path(__file__).resolve().parents[2] / "docs" / "blocks.md"

PATENT_NUMERALS = (
    {str(k) for k in range(1, 37)} | {"39", "40", "41"}
    | {"100", "102", "103", "104", "105", "106", "107", "108", "109", "110", "111"}
    | {str(k) for k in range(120, 129)} | {"130", "131", "132"}
)
#: Numerals of the block-diagram figure's boxes (Fig. 2 and the vehicle).
DRAWN_NUMERALS = PATENT_NUMERALS - {"102", "103", "106", "107", "108", "109", "110",
                                    "121", "122", "123", "124", "125", "126", "127", "132"}
#: The one numeral the patent gives to two things (rate-command module, S8 contact).
USED_TWICE = {"128"}
SWITCHES = {f"S{k}" for k in range(1, 20)}
#: (numeral, module) whose module docstring does not yet name the numeral: the vehicle
#: drawing's numerals in modules written before the table named them.
def rows():
    """(numerals, modules, names) of the block table and of the wiring's switches."""
    out = [(b.numerals, b.modules, b.functions) for b in blocks.BLOCKS]
    out += [((f"S{s.number}",), ("allsky.hardware.switch_bank", "allsky.hardware.wiring"),
             ("SWITCHES",)) for s in wiring.SWITCHES]
    return out


ROWS = rows()


def mentions(doc: str, numeral: str) -> bool:
    """``numeral`` as a whole token in ``doc`` ("1" not in "14" nor in "0.1"; "S1" not in "S14")."""
    return re.search(rf"(?<![\w.]){re.escape(numeral)}(?!\w|\.\d)", doc) is not None


def test_every_patent_numeral_and_switch_is_mapped():
    mapped = {n for numerals, _, _ in ROWS for n in numerals}
    missing = (PATENT_NUMERALS | SWITCHES) - mapped
    assert not missing, sorted(missing, key=lambda s: (len(s), s))
    assert mapped <= PATENT_NUMERALS | SWITCHES, mapped - PATENT_NUMERALS - SWITCHES


def test_no_numeral_is_mapped_twice_except_the_patents_double_use():
    mapped = [n for numerals, _, _ in ROWS for n in numerals]
    assert {n for n in mapped if mapped.count(n) > 1} == USED_TWICE
    assert [b.name.split()[0] for b in blocks.by_numeral("128")] == ["rate-command", "contacts"]


def test_rows_without_code_say_why():
    for b in blocks.BLOCKS:
        assert b.modules or b.io.startswith("no code"), b
        assert b.numerals or b.kind == "undrawn", b


def _checks():
    out = []
    for numerals, modules, _ in ROWS:
        for module in modules:
            for n in numerals:
                out.append(pytest.param(n, module, id=f"{n}-{module}"))
    return out


@pytest.mark.parametrize("numeral, module", _checks())
def test_module_docstring_names_the_numeral(numeral, module):
    doc = importlib.import_module(module).__doc__ or ""
    assert mentions(doc, numeral), f"{module} docstring does not mention {numeral}"


@pytest.mark.parametrize("numerals, modules, names", ROWS,
                         ids=[",".join(r[0]) or "-".join(r[1]) for r in ROWS])
def test_named_functions_exist(numerals, modules, names):
    imported = [importlib.import_module(m) for m in modules]
    for name in names:
        assert any(hasattr(mod, name) for mod in imported), f"no {name} in {modules}"


def test_the_page_shows_every_numeral_and_module():
    page = BLOCKS_MD.read_text(encoding="utf-8")
    first_cells = [line.split("|")[1].strip() for line in page.splitlines()
                   if line.startswith("| ") and not line.startswith("| numeral")]
    shown = {n for cell in first_cells for n in re.findall(r"S\d+|\d+", cell)}
    assert PATENT_NUMERALS | SWITCHES <= shown
    for name in set(re.findall(r"`(allsky(?:\.\w+)+)`", page)):
        resolve(name)


def resolve(name: str):
    """The module, or the module's attribute, that a dotted name names."""
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError:
        module, _, attr = name.rpartition(".")
        return getattr(importlib.import_module(module), attr)


def test_mentions_is_a_whole_token_match():
    assert mentions("gyros 1, 2, 3", "1") and mentions("lines 130/131.", "131")
    assert not mentions("counters 14, 16", "1") and not mentions("0.1 arcsec", "1")
    assert mentions("S1-S19", "S1") and not mentions("S14", "S1")
