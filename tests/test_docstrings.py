"""Every public function, class and method is documented: a short summary, every parameter.

python-control keeps its API honest with meta-tests like this one
(``docstrings_test.py``): read the source with ``ast`` (nothing is imported),
find each public definition of every module, and check its docstring.

*Public* means a module-level function or class whose name has no leading
underscore, and the methods of such a class whose names have none, plus the
class's constructor (``__init__``). Each must have a docstring whose first
line is a one-line summary of at most :data:`SUMMARY_MAX` characters.

Each parameter must be documented (:func:`documented`): its name quoted in
the docstring, alone between double (or single) backticks, or given an entry
``name : type`` in its numpydoc ``Parameters`` (or ``Other Parameters``)
section, where ``a, b : float`` documents both. What counts as a parameter:

- positional, keyword-only and positional-only parameters, except a method's
  first (``self`` or ``cls``; a ``@staticmethod`` has none);
- ``*args`` and ``**kwargs`` with their stars, quoted or as an entry, as
  python-control does: what they accept and pass on is part of the
  interface;
- a constructor's parameters may be documented in the class docstring (the
  numpydoc place) or in ``__init__``'s own;
- the fields of a ``NamedTuple`` or ``@dataclass`` are its constructor's
  parameters. They are documented where the house style puts them, by a
  ``#:`` comment (with text) at the end of the field's line or on the line
  just above it (the comments Sphinx autodoc reads), which this test reads
  from the source lines beside the ``ast`` node; an entry in the class
  docstring's ``Attributes`` (or ``Parameters``) section, or a quoted
  mention there, counts as well.

Files in :data:`PENDING` are checked but allowed to fail: an expected failure
(``-ra`` prints the file, the reason and how many parameters are missing). A
pending file that already passes simply passes; its entry goes when the work
it waits for lands, and no other file may join the set.

The public API (``allsky.__all__``) is held to more: each of its functions and
classes has a numpydoc ``Examples`` section, and its examples run as doctests
(those marked ``# doctest: +SKIP`` fly many missions and are shown, not run).
These tests import allsky.
"""

import ast
import doctest
import inspect
import re

import pytest

import allsky
from allsky.layers import SRC

#: [characters] longest summary line (numpydoc: one line that fits the screen).
SUMMARY_MAX = 80

#: Files (relative to ``src/allsky``) whose parameters the check lets go: none. Every
#: public parameter is documented; a file joins this set only while it is rewritten,
#: with the reason, and leaves it when it lands.
PENDING: dict = {}

#: numpydoc section headers whose entries document parameters.
PARAMETER_SECTIONS = ("Parameters", "Other Parameters")
#: ... and those whose entries document the fields of a NamedTuple or dataclass.
FIELD_SECTIONS = ("Attributes", "Parameters")

_ENTRY = re.compile(r"((?:\\?\*){0,2}\w+(?:\s*,\s*(?:\\?\*){0,2}\w+)*)\s*(?::\s|:$|$)")


def _sections(doc):
    """Numpydoc sections of ``doc``: ``{header: [lines]}`` (a header is underlined by dashes)."""
    lines = doc.splitlines()
    found, header = {}, None
    for i, line in enumerate(lines):
        underlined = i + 1 < len(lines) and re.fullmatch(r"\s*-{3,}\s*", lines[i + 1])
        if line.strip() and underlined:
            header = line.strip()
            found.setdefault(header, [])
        elif header is not None and not re.fullmatch(r"\s*-{3,}\s*", line):
            found[header].append(line)
    return found


def entries(doc, sections=PARAMETER_SECTIONS):
    """Names given entries in ``doc``'s ``sections`` (``a, b : float`` gives both)."""
    names = set()
    for header, lines in _sections(doc).items():
        body = [line for line in lines if line.strip()]
        if header not in sections or not body:
            continue
        indent = min(len(line) - len(line.lstrip()) for line in body)
        for line in body:
            match = _ENTRY.match(line.strip())
            if len(line) - len(line.lstrip()) == indent and match:
                names.update(n.strip().replace("\\", "") for n in match.group(1).split(","))
    return names


def documented(name, doc, sections=PARAMETER_SECTIONS):
    """Whether ``doc`` documents parameter ``name`` (stars included for ``*args``, ``**kw``).

    ``name`` is quoted in ``doc``, or has an entry in one of its ``sections``.
    """
    quoted = r"(?<![`\w*])``?" + re.escape(name) + r"``?(?![`\w])"
    return name in entries(doc, sections) or re.search(quoted, doc) is not None


def parameters(fn, method):
    """Names of ``fn``'s parameters as a caller sees them (a method's ``self``/``cls`` left out)."""
    args = fn.args
    positional = args.posonlyargs + args.args
    static = any(isinstance(d, ast.Name) and d.id == "staticmethod" for d in fn.decorator_list)
    if method and not static:
        positional = positional[1:]
    names = [a.arg for a in positional]
    if args.vararg:
        names.append("*" + args.vararg.arg)
    names += [a.arg for a in args.kwonlyargs]
    if args.kwarg:
        names.append("**" + args.kwarg.arg)
    return names


def _is_record(node):
    """Whether class ``node`` is a NamedTuple or a dataclass (its fields are its parameters)."""
    bases = {ast.unparse(b) for b in node.bases}
    decorators = {ast.unparse(d).split("(")[0] for d in node.decorator_list}
    return bool(bases & {"NamedTuple", "typing.NamedTuple"}
                or decorators & {"dataclass", "dataclasses.dataclass"})


def _field_comment(node, lines):
    """Text of the ``#:`` comment beside field ``node`` (end of its line, or the line above)."""
    after = lines[node.end_lineno - 1][node.end_col_offset:].strip()
    above = lines[node.lineno - 2].strip() if node.lineno > 1 else ""
    for comment in (after, above):
        if comment.startswith("#:") and comment[2:].strip():
            return comment[2:].strip()
    return ""


def _definitions(tree):
    yield "module", tree
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)) and not node.name.startswith("_"):
            yield node.name, node
            if isinstance(node, ast.ClassDef):
                for sub in node.body:
                    if isinstance(sub, ast.FunctionDef) and not sub.name.startswith("_"):
                        yield f"{node.name}.{sub.name}", sub


def undocumented(path):
    """``name: parameter`` for every public parameter of ``path`` its docstrings leave out."""
    text = path.read_text(encoding="utf-8")
    lines, missing = text.splitlines(), []
    for name, node in _definitions(ast.parse(text)):
        if isinstance(node, ast.FunctionDef):
            doc = ast.get_docstring(node) or ""
            method = "." in name
            missing += [f"{name}: {p}" for p in parameters(node, method)
                        if not documented(p, doc)]
        elif isinstance(node, ast.ClassDef):
            doc = ast.get_docstring(node) or ""
            for sub in node.body:
                if isinstance(sub, ast.FunctionDef) and sub.name == "__init__":
                    both = doc + "\n" + (ast.get_docstring(sub) or "")
                    missing += [f"{name}(): {p}" for p in parameters(sub, True)
                                if not documented(p, both)]
                elif (isinstance(sub, ast.AnnAssign) and isinstance(sub.target, ast.Name)
                      and _is_record(node) and not _field_comment(sub, lines)
                      and not documented(sub.target.id, doc, FIELD_SECTIONS)):
                    missing.append(f"{name} field: {sub.target.id}")
    return missing


FILES = sorted(SRC.rglob("*.py"))
IDS = [p.relative_to(SRC).as_posix() for p in FILES]


@pytest.mark.parametrize("path", FILES, ids=IDS)
def test_public_definitions_have_a_short_summary(path):
    problems = []
    for name, node in _definitions(ast.parse(path.read_text(encoding="utf-8"))):
        doc = ast.get_docstring(node)
        if not doc:
            problems.append(f"{name}: no docstring")
        elif len(doc.splitlines()[0]) > SUMMARY_MAX:
            problems.append(f"{name}: summary of {len(doc.splitlines()[0])} characters")
    assert not problems, "; ".join(problems)


@pytest.mark.parametrize("path", FILES, ids=IDS)
def test_every_parameter_is_documented(path):
    missing = undocumented(path)
    rel = path.relative_to(SRC).as_posix()
    if rel in PENDING and missing:
        pytest.xfail(f"{rel}: {PENDING[rel]} ({len(missing)} undocumented)")
    assert not missing, "undocumented parameters: " + "; ".join(missing)


def test_pending_files_exist():
    assert not [rel for rel in PENDING if not (SRC / rel).is_file()]


# The checker itself, on docstrings written to test it.
@pytest.mark.parametrize("doc, missing", [
    ("Use ``a``, `b`, ``*args``, ``c`` and ``**kwargs``.", []),
    ("Parameters\n----------\na, b : float\n*args\n    More.\nc : int\n\\**kwargs : dict",
     []),
    ("Uses ``a`` and ``ab``, ``args`` and ``*c``; ``kwargs``.", ["b", "*args", "c", "**kwargs"]),
    (("Parameters\n----------\na : float\n    Not b : float, nor ``c.x``.\n\n"
      "Returns\n-------\nb : float"), ["b", "*args", "c", "**kwargs"]),
])
def test_the_checker_reads_mentions_and_entries(doc, missing):
    fn = ast.parse("def _f(a, b, *args, c=1, **kwargs):\n    pass").body[0]
    assert [p for p in parameters(fn, False) if not documented(p, doc)] == missing


def test_the_checker_reads_field_comments(tmp_path):
    path = tmp_path / "m.py"
    path.write_text('"""M."""\nfrom typing import NamedTuple\n\n\nclass P(NamedTuple):\n'
                    '    """P, with ``c``.\n\n    Attributes\n    ----------\n    f : int\n'
                    '        F.\n    """\n\n    a: float  #: [s] a\n    #: [m] b\n'
                    '    b: float\n    c: float\n    d: float  #:\n    e: int  # not a doc\n'
                    '    f: int\n\n\n'
                    'class Q:\n    """Q of ``x``.\n\n    Attributes\n    ----------\n    w : int\n'
                    '        W.\n    """\n\n    def __init__(self, x, y, w):\n'
                    '        """Q; ``y``."""\n\n    def go(self, z):\n        """Go."""\n\n'
                    '    @staticmethod\n    def make(v, u):\n        """Made of ``u``."""\n')
    # A record's field may be an Attributes entry, a constructor's parameter may not; a
    # static method's first parameter is a parameter.
    assert undocumented(path) == ["P field: d", "P field: e", "Q(): w", "Q.go: z", "Q.make: v"]


# -- the public API: examples, and examples that run ---------------------------------------

#: The public functions and classes (``allsky.__all__`` less its constants).
PUBLIC = [name for name in allsky.__all__
          if inspect.isfunction(getattr(allsky, name)) or inspect.isclass(getattr(allsky, name))]
#: doctest options: ``...`` stands for any text (a page's size, a long line's end).
DOCTEST_FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def test_every_public_function_and_class_has_examples():
    lacking = [name for name in PUBLIC
               if "Examples" not in _sections(inspect.cleandoc(getattr(allsky, name).__doc__
                                                               or ""))]
    assert not lacking, "no Examples section: " + ", ".join(lacking)


@pytest.mark.parametrize("name", PUBLIC)
def test_the_public_examples_run(name, tmp_path, monkeypatch):
    """Each example gives the output shown (run in an empty folder: a save writes there)."""
    monkeypatch.chdir(tmp_path)
    obj = getattr(allsky, name)
    tests = doctest.DocTestFinder().find(obj, f"allsky.{name}", globs={})
    runner = doctest.DocTestRunner(optionflags=DOCTEST_FLAGS)
    for test in tests:
        runner.run(test)
    assert any(test.examples for test in tests), f"allsky.{name}: no examples found"
    failed = runner.summarize(verbose=False).failed
    assert failed == 0, f"allsky.{name}: {failed} examples failed (printed above)"
