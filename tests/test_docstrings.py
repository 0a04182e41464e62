"""Every public function, class and method is documented, with a short summary line.

python-control keeps its API honest with meta-tests like this one: read the
source with ``ast``, find each public definition (no leading underscore) of
every module, and check that it has a docstring whose first line is a
one-line summary of at most :data:`SUMMARY_MAX` characters.
"""

import ast

import pytest

from allsky.layers import SRC

#: [characters] longest summary line (numpydoc: one line that fits the screen).
SUMMARY_MAX = 80


def _definitions(path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    yield "module", tree
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)) and not node.name.startswith("_"):
            yield node.name, node
            if isinstance(node, ast.ClassDef):
                for sub in node.body:
                    if isinstance(sub, ast.FunctionDef) and not sub.name.startswith("_"):
                        yield f"{node.name}.{sub.name}", sub


FILES = sorted(SRC.rglob("*.py"))


@pytest.mark.parametrize("path", FILES, ids=[str(p.relative_to(SRC)) for p in FILES])
def test_public_definitions_have_a_short_summary(path):
    problems = []
    for name, node in _definitions(path):
        doc = ast.get_docstring(node)
        if not doc:
            problems.append(f"{name}: no docstring")
        elif len(doc.splitlines()[0]) > SUMMARY_MAX:
            problems.append(f"{name}: summary of {len(doc.splitlines()[0])} characters")
    assert not problems, "; ".join(problems)
