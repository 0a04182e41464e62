"""Build ahead of time what a mission calls from Python (:mod:`allsky.aot`).

The package build runs :func:`build` after the loop has been compiled just
in time in the same process; it needs numba's ``pycc``, a C compiler and
Python's headers.
"""

import importlib
import json

from allsky import aot, jit


def _exported(qualified: str):
    module, name = qualified.rsplit(".", 1)
    return importlib.import_module(module), name


def sample_arguments() -> dict:
    """Fly the default mission (numba loaded); the first arguments of each export."""
    from allsky.config.scenario import load_scenario
    from allsky.sim.mission import Mission

    jit.load_numba()
    captured, patched = {}, []
    for qualified in aot.EXPORTS:
        module, name = _exported(qualified)
        dispatcher = getattr(module, name)

        def record(*args, _d=dispatcher, _q=qualified):
            captured.setdefault(_q, args)
            return _d(*args)

        setattr(module, name, record)
        patched.append((module, name, dispatcher))
    try:
        m = Mission(load_scenario(), telemetry=True)
        m.run()
        m.summary()
    finally:
        for module, name, dispatcher in patched:
            setattr(module, name, dispatcher)
    missing = [q for q in aot.EXPORTS if q not in captured]
    if missing:
        raise RuntimeError(f"the default mission never called {', '.join(missing)}")
    return captured


def build() -> str:
    """Compile :data:`allsky.aot.EXPORTS` into the package directory; the module path.

    Writes the extension module and its manifest (:data:`allsky.aot.MANIFEST`)
    beside the package's sources, for this machine's CPU.
    """
    import os

    import llvmlite.binding as llvm
    from numba.pycc import CC

    numba = jit.load_numba()
    args = sample_arguments()
    cc = CC(aot.MODULE.rsplit(".", 1)[1])
    cc.output_dir = os.path.dirname(aot.MANIFEST)
    cc.target_cpu = llvm.get_host_cpu_name()
    exports = {}
    for qualified in aot.EXPORTS:
        module, name = _exported(qualified)
        dispatcher = getattr(module, name)
        a = args[qualified]
        types = tuple(numba.typeof(x) for x in a)
        cc.export(aot.export_name(qualified), dispatcher.overloads[types].signature)(
            dispatcher.py_func)
        exports[qualified] = [aot.structure(x) for x in a]
    cc.compile()
    built = os.path.join(cc.output_dir, cc.output_file)
    manifest = {"stamp": aot.stamp(), "cpu": aot.cpu_fingerprint(),
                "cache_tag": __import__("sys").implementation.cache_tag, "exports": exports,
                "extension": {"file": cc.output_file, **aot.file_digest(built)}}
    with open(aot.MANIFEST, "w", encoding="utf-8") as f:
        json.dump(manifest, f)
    return os.path.join(cc.output_dir, cc.output_file)
