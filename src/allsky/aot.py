"""What a mission calls from Python, built ahead of time: no numba at run time.

A mission calls three compiled functions from Python (:data:`EXPORTS`): the
plain frame loop (the patent's vehicle without faults), CPU 22's target
step and the body-from-inertial matrix. ``pip install`` builds them
(:func:`allsky.apps.aot_build.build`, run by ``setup.py``) into an extension
module ``allsky._aot`` with numba's ahead-of-time compiler, for this
machine's CPU, beside a manifest ``allsky/_aot.json``. While numba is not
loaded, :class:`allsky.jit.CompiledFunction` calls the module's function
(:func:`entry`) when the manifest matches: the same sources
(:func:`allsky.sources.source_stamp`), the same CPU (:func:`cpu_fingerprint`),
the same Python, and arguments of the structure it was compiled for
(:func:`structure`). Then neither numba, LLVM nor SciPy is loaded; the code
is what numba compiles just in time, so the results are the same bits.
Anything else (edited sources, another machine, the general loop, a build
without a C compiler) goes to numba.
"""

import functools
import hashlib
import importlib
import json
import os
import sys
import threading

from allsky.sources import PACKAGE_DIR, source_stamp

#: The extension module and its manifest.
MODULE = "allsky._aot"
MANIFEST = os.path.join(PACKAGE_DIR, "_aot.json")
#: What the build could not compile, and why (written by the build; None when it could).
NOTE = os.path.join(PACKAGE_DIR, "_build_note.json")
#: What to do about a build without a C compiler, in the words of the tools that install one.
COMPILER_HINT = ("install a C compiler and Python's headers (Debian/Ubuntu: apt install gcc "
                 "python3-dev; conda: conda install -c conda-forge c-compiler), then "
                 "pip install --force-reinstall --no-deps allsky")
#: What a command pays without the functions built ahead of time (docs/design.md).
WITHOUT_AOT = "every command loads numba's compiled loop instead, about 0.6 s more"
#: The compiled functions a mission calls from Python, by module and name.
EXPORTS = ("allsky.sim.frame_loop._run_leg_plain", "allsky.computer.cpu.target_step",
           "allsky.vehicle.quaternion.dcm_body_from_inertial")


def export_name(qualified: str) -> str:
    """The extension module's name for the function ``qualified`` (module.name)."""
    return qualified.replace(".", "__")


def stamp() -> str:
    """The key of the exported functions: the sources of every module they reach."""
    h = hashlib.sha256()
    for qualified in EXPORTS:
        module = qualified.rsplit(".", 1)[0]
        path = os.path.join(os.path.dirname(PACKAGE_DIR), *module.split(".")) + ".py"
        h.update(source_stamp(path).encode())
    return h.hexdigest()


@functools.lru_cache(maxsize=1)
def cpu_fingerprint():
    """What the compiled code assumes of the CPU: vendor, family, model, flags (Linux).

    None where ``/proc/cpuinfo`` cannot be read; the loop is then never
    compiled ahead of time.
    """
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
            text = f.read()
    except OSError:
        return None
    first = text.split("\n\n", 1)[0]
    keep = [line for line in first.splitlines()
            if line.split(":")[0].strip() in ("vendor_id", "cpu family", "model", "flags")]
    if not keep:
        return None
    return hashlib.sha256("\n".join(" ".join(k.split()) for k in keep).encode()).hexdigest()


def structure(x):
    """The shape of an argument as numba types it: nested tuples, array kinds, scalars.

    ``x`` is one argument of a compiled call: a NamedTuple or tuple (read
    field by field), an array, a Python or NumPy scalar, or None. Two
    arguments of the same structure get the same numba type, so code compiled
    for one reads the other correctly.
    """
    fields = getattr(x, "_fields", None)
    if fields is not None:
        return ["tuple", type(x).__qualname__, list(fields), [structure(v) for v in x]]
    if isinstance(x, tuple):
        return ["tuple", "", [], [structure(v) for v in x]]
    if x is None:
        return ["none"]
    if isinstance(x, bool):
        return ["bool"]
    if isinstance(x, int):
        return ["int"]
    if isinstance(x, float):
        return ["float"]
    flags = getattr(x, "flags", None)
    if flags is not None and hasattr(x, "ndim"):
        layout = "C" if flags.c_contiguous else ("F" if flags.f_contiguous else "A")
        return ["array", x.dtype.str, x.ndim, layout, bool(flags.writeable),
                bool(flags.aligned)]
    if hasattr(x, "dtype"):  # a NumPy scalar
        return ["scalar", x.dtype.str]
    return ["other", type(x).__qualname__]


def file_digest(path) -> dict:
    """``{"size": bytes, "sha256": hex}`` of the file at ``path``."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return {"size": os.path.getsize(path), "sha256": h.hexdigest()}


def manifest_problem(m) -> str | None:
    """What makes ``m`` not a manifest of the shape the build writes, or None."""
    if not isinstance(m, dict):
        return "not a JSON object"
    for key in ("stamp", "cache_tag"):
        if not isinstance(m.get(key), str):
            return f"{key} is not text"
    if m.get("cpu") is not None and not isinstance(m["cpu"], str):
        return "cpu is not text"
    exports = m.get("exports")
    if not isinstance(exports, dict) or not all(
            isinstance(k, str) and isinstance(v, list) for k, v in exports.items()):
        return "exports is not an object of argument lists"
    ext = m.get("extension")
    if ext is not None and not (isinstance(ext, dict) and isinstance(ext.get("file"), str)
                                and os.sep not in ext["file"]
                                and type(ext.get("size")) is int
                                and isinstance(ext.get("sha256"), str)):
        return "extension is not {file, size, sha256}"
    return None


def _note(text):
    print(f"allsky: note: {text}; {WITHOUT_AOT}", file=sys.stderr)


@functools.lru_cache(maxsize=1)
def read_manifest():
    """The built extension's manifest, its shape checked; None if absent or damaged.

    A damaged one is said in one line and bypassed (the missions use numba's loop).
    """
    try:
        with open(MANIFEST, encoding="utf-8") as f:
            m = json.load(f)
    except FileNotFoundError:
        return None
    except (OSError, ValueError, RecursionError) as e:
        _note(f"the manifest {MANIFEST} cannot be read ({type(e).__name__}): bypassed")
        return None
    why = manifest_problem(m)
    if why is not None:
        _note(f"the manifest {MANIFEST} is damaged ({why}): bypassed")
        return None
    return m


def extension_problem(m) -> str | None:
    """Why the extension module the manifest ``m`` names cannot be loaded, or None.

    A manifest that records the file's size and sha256 has them checked (a
    truncated extension whose header is intact would kill the process with
    SIGBUS when loaded); one written before that, by a load in a child
    process, so that a bad file ends the child rather than the command.
    """
    ext = m.get("extension")
    if ext is not None:
        path = os.path.join(PACKAGE_DIR, ext["file"])
        try:
            found = file_digest(path)
        except OSError as e:
            return f"{path}: {e.strerror or e}"
        if found != {"size": ext["size"], "sha256": ext["sha256"]}:
            return (f"{path} is not the file built ({found['size']} bytes, "
                    f"{ext['size']} when built)")
        return None
    import subprocess

    try:
        r = subprocess.run([sys.executable, "-c", f"import {MODULE}"], capture_output=True,
                           timeout=60, check=False,
                           env={**os.environ, "PYTHONPATH": os.path.dirname(PACKAGE_DIR)})
    except (OSError, subprocess.SubprocessError) as e:
        return f"it could not be loaded in a child process ({type(e).__name__})"
    if r.returncode != 0:
        how = (f"killed by signal {-r.returncode}" if r.returncode < 0
               else f"exit {r.returncode}")
        return f"loading it in a child process failed ({how})"
    return None


@functools.cache
def _module_if_valid():
    """The extension module when its manifest matches this tree and CPU and its file is
    whole (:func:`extension_problem`); else None."""
    m = read_manifest()
    if (m is None or os.environ.get("ALLSKY_AOT", "1") == "0"
            or os.environ.get("NUMBA_DISABLE_JIT", "0") not in ("", "0")
            or m.get("cache_tag") != sys.implementation.cache_tag
            or m.get("stamp") != stamp() or m.get("cpu") != cpu_fingerprint()):
        return None
    why = extension_problem(m)
    if why is not None:
        _note(f"the ahead-of-time extension is damaged: {why}; bypassed (allsky warm-up "
              "--check says more; pip install --force-reinstall --no-deps allsky rebuilds "
              "it)")
        return None
    try:
        return importlib.import_module(MODULE)
    except ImportError:
        return None


#: Named tuples whose structure was checked: id -> (the tuple, its structure).
_seen = {}


def _structure_of(a):
    if getattr(a, "_fields", None) is None:
        return structure(a)
    seen = _seen.get(id(a))
    if seen is None or seen[0] is not a:  # the parameters and state: once a mission
        if len(_seen) > 64:
            _seen.clear()
        seen = _seen[id(a)] = (a, structure(a))
    return seen[1]


def entry(qualified: str, args):
    """The function ``qualified`` built ahead of time if it can take ``args``, or None.

    Only on the main thread: the functions built ahead of time hold Python's
    global lock while they run, where numba's release it (``nogil``), so
    threads (a Dask worker's) keep numba's and fly in parallel.
    """
    if threading.current_thread() is not threading.main_thread():
        return None
    module = _module_if_valid()
    if module is None:
        return None
    want = read_manifest()["exports"].get(qualified)
    if want is None or len(want) != len(args):
        return None
    if any(_structure_of(a) != w for a, w in zip(args, want, strict=True)):
        return None
    return getattr(module, export_name(qualified))


def build_note():
    """What the install could not compile: ``{"missing", "reason", "hint"}``, or None."""
    try:
        with open(NOTE, encoding="utf-8") as f:
            note = json.load(f)
    except (OSError, ValueError):
        return None
    if not isinstance(note, dict) or not all(isinstance(note.get(k), str)
                                             for k in ("missing", "reason", "hint")):
        return None
    return note


def available() -> bool:
    """Whether the functions built ahead of time are there and fit this tree and CPU."""
    return _module_if_valid() is not None
