"""Only the front ends print, draw or write files; library code returns data.

Read from the source with ``ast`` (nothing is imported): every module of
``allsky`` outside ``allsky/apps/`` is searched for calls that print, ask
the terminal, show a progress bar, draw a figure or write a file, and for
file reads outside the few places where a library must read. The front
ends (``allsky/apps/``) present what the library returns.
"""

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "allsky"
FRONT_ENDS = SRC / "apps"

#: Library modules that must read a file, and why (reading anywhere else is refused).
READERS = {
    "allsky.config.toml_io": "a scenario or --disperse file is a TOML file the user names; "
                             "load_scenario(path) reads it because loading it is the job",
    "allsky.config.schema": "the packaged default scenario (package data) that every "
                            "scenario is merged over",
    "allsky.config.meanings": "the packaged default scenario again, for its comments: they "
                              "are the keys' meanings that config show and the docs print",
    "allsky.layers": "the package's own source, parsed for its imports (the layer order "
                     "that tests/test_layers.py holds and docs/architecture.md draws)",
    "allsky.aot": "the manifest of the functions built ahead of time at install, and "
                  "/proc/cpuinfo for the CPU they were built for",
    "allsky.sources": "the package's own sources, hashed (with the allsky modules each one "
                  "imports) into the key of numba's on-disk cache",
    "allsky.vehicle.ephemeris": "the DE421 ephemeris's coefficient arrays, the de421 "
                                "package's data files, memory-mapped",
    "allsky.jit_cache": "numba's cache files, hashed to check them before numba loads them",
    "allsky.compiles": "the frame loop's own source, opened read-only to hold an flock "
                       "on it: the machine's compile lock (one process compiles, the "
                       "others wait and load its cache)",
}
#: Library modules that say one line on stderr (and tidy the files they own) because the
#: issue they meet has no front end between it and the user, and why.
WRITERS = {
    "allsky.jit_cache": "a damaged numba cache file is set aside (removed) and said in one "
                        "line when numba loads it, and each cache file's digest is written "
                        "beside it: numba calls the cache directly, no front end is between",
    "allsky.aot": "a damaged ahead-of-time manifest is said in one line and bypassed, where "
                  "the extension is imported",
    "allsky.config.toml_io": "an input FIFO with no writer yet is said in one line after a "
                             "second, then waited for, where the file is opened",
}
#: What a module of WRITERS may do (and nothing else of the writes the test finds).
WRITER_CALLS = {"print()", "sys.stderr", "open()", "os.unlink()", "os.replace()",
                "os.rename()"}
#: Packages a library module must not import, and what they are for.
FRONT_END_PACKAGES = {"tqdm": "progress bars", "matplotlib": "figures"}
#: Calls of a builtin that talk to the terminal.
TERMINAL_BUILTINS = {"print", "input"}
#: Methods that write a file or make one (Path, NumPy, Matplotlib, pyarrow, json, pickle).
WRITE_METHODS = {"write_text", "write_bytes", "save", "savez", "savez_compressed", "savetxt",
                 "savefig", "tofile", "write_table", "to_csv", "to_parquet", "dump", "mkdir",
                 "makedirs", "touch", "unlink", "fsync"}
#: Methods that read a file (Path, NumPy, json, pickle, tomllib, pyarrow).
READ_METHODS = {"read_text", "read_bytes", "load", "loadtxt", "genfromtxt", "fromfile",
                "read_table", "read_csv", "read_parquet"}
#: Modules whose ``open(file, mode)`` takes the mode second, like the builtin.
OPEN_LIKE_BUILTIN = {"io", "gzip", "bz2", "lzma", "codecs"}


def _module_name(path: Path) -> str:
    parts = path.relative_to(SRC.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _dotted(node) -> str:
    """``a.b.c`` for a chain of names and attributes ("" for anything else)."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        head = _dotted(node.value)
        return f"{head}.{node.attr}" if head else ""
    return ""


def _open_writes(call: ast.Call) -> bool:
    """Does this ``open`` call open for writing? (A mode that is not a literal counts as yes.)"""
    func = call.func
    if isinstance(func, ast.Attribute) and _dotted(func.value) == "os":
        return True  # os.open takes flags: a low-level open is for writing here
    if isinstance(func, ast.Name) or (isinstance(func, ast.Attribute)
                                      and _dotted(func.value) in OPEN_LIKE_BUILTIN):
        mode_at = 1  # open(file, mode)
    else:
        mode_at = 0  # Path.open(mode)
    mode = next((k.value for k in call.keywords if k.arg == "mode"),
                call.args[mode_at] if len(call.args) > mode_at else None)
    if mode is None:
        return False  # default mode "r"
    if not (isinstance(mode, ast.Constant) and isinstance(mode.value, str)):
        return True
    return any(c in mode.value for c in "wax+")


def findings(tree: ast.AST) -> tuple[list, list]:
    """(writes, reads) in a module: ``(line, what)`` for each call or import found."""
    writes, reads = [], []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import | ast.ImportFrom):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""])
            for name in names:
                top = name.split(".")[0]
                if top in FRONT_END_PACKAGES:
                    writes.append((node.lineno, f"import {name} ({FRONT_END_PACKAGES[top]})"))
        elif isinstance(node, ast.Attribute) and _dotted(node) in (
                "sys.stdout", "sys.stderr", "sys.__stdout__", "sys.__stderr__"):
            writes.append((node.lineno, _dotted(node)))
        elif isinstance(node, ast.Call):
            func = node.func
            name = func.id if isinstance(func, ast.Name) else (
                func.attr if isinstance(func, ast.Attribute) else "")
            shown = _dotted(func) or name
            if isinstance(func, ast.Name) and name in TERMINAL_BUILTINS:
                writes.append((node.lineno, f"{name}()"))
            elif name == "open":
                (writes if _open_writes(node) else reads).append((node.lineno, f"{shown}()"))
            elif isinstance(func, ast.Attribute) and (
                    name in WRITE_METHODS or name == "write" and _dotted(func.value) in (
                        "os", "sys.stdout", "sys.stderr")):
                writes.append((node.lineno, f"{shown}()"))
            elif isinstance(func, ast.Attribute) and name in READ_METHODS:
                reads.append((node.lineno, f"{shown}()"))
    return sorted(writes), sorted(reads)


LIBRARY = {_module_name(p): p for p in sorted(SRC.rglob("*.py"))
           if FRONT_ENDS not in p.parents}
FOUND = {m: findings(ast.parse(p.read_text(encoding="utf-8"))) for m, p in LIBRARY.items()}


def test_the_library_is_every_module_outside_apps():
    assert "allsky.sim.mission" in LIBRARY and "allsky.studies.montecarlo" in LIBRARY
    assert not any(m.startswith("allsky.apps") for m in LIBRARY)


@pytest.mark.parametrize("module", sorted(LIBRARY))
def test_library_module_does_not_print_draw_or_write(module):
    writes, _ = FOUND[module]
    if module in WRITERS:
        writes = [(n, what) for n, what in writes if what not in WRITER_CALLS]
    assert not writes, (f"{module} prints, draws or writes (return the data and let "
                        "allsky.apps present it): "
                        + "; ".join(f"line {n}: {what}" for n, what in writes))


@pytest.mark.parametrize("module", sorted(LIBRARY))
def test_library_module_reads_files_only_where_it_must(module):
    _, reads = FOUND[module]
    if module not in READERS:
        assert not reads, (f"{module} reads a file (take the data as an argument, or add the "
                           "module to READERS with the reason): "
                           + "; ".join(f"line {n}: {what}" for n, what in reads))


@pytest.mark.parametrize("module", sorted(READERS))
def test_every_allowed_reader_exists_and_reads(module):
    assert module in LIBRARY, f"{module}: no such library module; drop it from READERS"
    # an opener that may also write (a FIFO-aware open) counts among the writes
    opens = [w for w in FOUND[module][0] if w[1] == "open()"] if module in WRITERS else []
    assert FOUND[module][1] or opens, f"{module} reads no file any more; drop it from READERS"


# -- the checker itself ------------------------------------------------------------------------

def _found(code):
    return findings(ast.parse(code))


@pytest.mark.parametrize("code", [
    "print('x')",
    "input('> ')",
    "open(p, 'w')",
    "open(p, mode='ab')",
    "open(p, 'r+')",
    "open(p, m)",
    "path.open('wb')",
    "path.open(mode='x')",
    "io.open(p, 'w')",
    "os.open(p, os.O_WRONLY | os.O_APPEND)",
    "p.write_text('x')",
    "p.write_bytes(b'x')",
    "np.save(p, a)",
    "np.savez(f, **arrays)",
    "numpy.savez_compressed(f, a=a)",
    "np.savetxt(p, a)",
    "fig.savefig(p)",
    "json.dump(d, f)",
    "pq.write_table(t, p)",
    "out.mkdir(parents=True)",
    "os.fsync(fd)",
    "os.write(fd, b'x')",
    "sys.stdout.write('x')",
    "sys.stderr.write('x')",
    "f(file=sys.stderr)",
    "from tqdm import tqdm",
    "import tqdm",
    "def f():\n    import matplotlib.pyplot as plt",
])
def test_the_checker_sees_a_write(code):
    writes, _ = _found(code)
    assert writes, code


@pytest.mark.parametrize("code", [
    "open(p)",
    "open(p, 'rb')",
    "path.open()",
    "path.open(newline='')",
    "p.read_text(encoding='utf-8')",
    "p.read_bytes()",
    "np.load(p, allow_pickle=False)",
    "json.load(f)",
    "tomllib.load(f)",
])
def test_the_checker_sees_a_read_and_no_write(code):
    writes, reads = _found(code)
    assert reads and not writes, code


def test_the_checker_lets_data_work_pass():
    code = ("s = text.replace('a', 'b'); leg = leg._replace(resume=1); j = json.dumps(d)\n"
            "t = tomllib.loads(text); buf = io.StringIO(); buf.write('x'); n = len(rows)\n"
            "def in_open(lo, hi):\n    return lo < hi\n")
    assert _found(code) == ([], [])
