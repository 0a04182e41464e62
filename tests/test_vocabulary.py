"""One vocabulary (allsky.vocabulary): every mode, fault kind, axis and action named once.

Read from the source with ``ast`` where the question is where a name is
written: a tuple of the three axis names, a table keyed by every fault kind
or by every mode is written in ``vocabulary.py`` and nowhere else in the
package; the readers (config, sequencer, sim, apps) take them from there.
"""

import ast
from pathlib import Path

from allsky import vocabulary
from allsky.config import faults as config_faults
from allsky.sequencer import master_sequencer as ms
from allsky.sequencer import modes
from allsky.sim import faults as sim_faults
from allsky.studies import faults as fault_matrix

SRC = Path(__file__).resolve().parents[1] / "src" / "allsky"
VOCABULARY = SRC / "vocabulary.py"


def _sources():
    for path in sorted(SRC.rglob("*.py")):
        if path != VOCABULARY:
            yield path, ast.parse(path.read_text())


def _constant_strings(node) -> tuple:
    return tuple(e.value for e in node.elts) if all(
        isinstance(e, ast.Constant) and isinstance(e.value, str) for e in node.elts) else ()


def test_the_vocabulary_needs_nothing_but_the_standard_library():
    tree = ast.parse(VOCABULARY.read_text())
    imported = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import)
                for a in n.names}
    imported |= {n.module.split(".")[0] for n in ast.walk(tree)
                 if isinstance(n, ast.ImportFrom) and n.module}
    assert imported <= {"typing"}, imported


def test_the_axes_are_written_once():
    found = []
    for path, tree in _sources():
        for node in ast.walk(tree):
            if isinstance(node, ast.Tuple) and _constant_strings(node) == vocabulary.AXES:
                found.append(f"{path.relative_to(SRC)}:{node.lineno}")
    assert not found, f"the axes written again: {found}"


def test_no_other_table_lists_every_fault_kind_or_every_mode():
    kinds = {k.name for k in vocabulary.FAULT_KINDS}
    names = {m.name for m in vocabulary.MODES}
    found = []
    for path, tree in _sources():
        for node in ast.walk(tree):
            if isinstance(node, ast.Dict):
                keys = {k.value for k in node.keys
                        if isinstance(k, ast.Constant) and isinstance(k.value, str)}
                if keys >= kinds and path.name != "faults.py" or keys >= names:
                    found.append(f"{path.relative_to(SRC)}:{node.lineno}")
    # The fault matrix (studies/faults.py) says what each row flies: a table of its own, held
    # to the vocabulary by the test below. config/faults.py words each kind (describe).
    assert not found, f"tables of every kind or mode outside the vocabulary: {found}"


def test_the_modes_of_the_table_are_the_vocabulary_s():
    assert tuple(m.name for m in modes.MODE_TABLE) == tuple(w.name for w in vocabulary.MODES)
    for m in modes.MODE_TABLE:
        assert (m.code, m.title) == (vocabulary.MODE_CODE[m.name],
                                     vocabulary.MODE_TITLE[m.name])
    assert len(set(vocabulary.MODE_CODE.values())) == len(vocabulary.MODES)
    assert modes.LEGACY_PLAN == vocabulary.PATENT_MODES


def test_fault_kinds_have_one_code_and_every_reader_knows_each():
    codes = [k.code for k in vocabulary.FAULT_KINDS]
    assert sorted(codes) == list(range(1, len(codes) + 1))  # 0 is an empty slot
    assert config_faults.KINDS == {k.name: k.fields for k in vocabulary.FAULT_KINDS}
    assert sim_faults.KIND_CODE == vocabulary.FAULT_CODE
    assert set(fault_matrix.MATRIX_FAULTS) == set(vocabulary.FAULT_KIND)
    for kind, fields in config_faults.KINDS.items():
        # Every required field, and optional ones only where the kind needs one of them
        # (a leak gives its torque or its vent).
        given = set(fault_matrix.MATRIX_FAULTS[kind]) - {"duration_s"}
        assert given - set(config_faults.OPTIONAL[kind]) == set(fields), kind
        assert config_faults.describe({"kind": kind, **fault_matrix.MATRIX_FAULTS[kind]})


def test_every_action_word_has_one_documented_function():
    assert list(ms.ACTIONS) == list(vocabulary.ACTIONS)
    for name, f in ms.ACTIONS.items():
        assert f.__name__ == name and f.__doc__, name
    used = {s.action for m in modes.MODE_TABLE for s in m.steps if isinstance(s, modes.Do)}
    assert used <= set(vocabulary.ACTIONS)


def test_journal_kinds_are_unique():
    names = [k.name for k in vocabulary.EVENT_KINDS]
    codes = [k.code for k in vocabulary.EVENT_KINDS]
    assert len(set(names)) == len(names) and len(set(codes)) == len(codes)
    assert set(names) >= {"mode_start", "mode_end", "switch", "action", "register",
                          "star_lock", "saturation", "fault", "abort"}
