"""The frame loop compiles once per machine: processes starting together share one compile."""

import os
import subprocess
import sys
import textwrap

import numba
import pytest

from allsky.sim import warm_up

needs_jit = pytest.mark.skipif(numba.config.DISABLE_JIT, reason="about compiled code")

_WORKER = textwrap.dedent("""
    import os, sys, time
    sys.path.insert(0, sys.argv[1])
    import tiny_block
    from allsky.sim import warm_up
    while not os.path.exists(os.path.join(sys.argv[1], "go")):  # start together
        time.sleep(0.005)
    print(int(warm_up.compile_once(lambda: tiny_block.f(1.0), [tiny_block.f])))
""")


@needs_jit
def test_workers_sharing_a_fresh_cache_directory_compile_once(tmp_path):
    (tmp_path / "tiny_block.py").write_text(
        "import numba\n\n\n@numba.njit(cache=True)\ndef f(x):\n    return x * 2.0 + 1.0\n")
    (tmp_path / "worker.py").write_text(_WORKER)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    workers = [subprocess.Popen([sys.executable, str(tmp_path / "worker.py"), str(tmp_path)],
                                stdout=subprocess.PIPE, text=True, env=env) for _ in range(3)]
    (tmp_path / "go").touch()
    compiled = [int(w.communicate(timeout=300)[0].split()[-1]) for w in workers]
    assert sorted(compiled) == [0, 0, 1]  # one compiled; the others loaded its cache


@needs_jit
def test_nothing_to_compile_once_loaded(default_cfg):
    from allsky.sim.mission import Mission

    Mission(default_cfg, telemetry=False).run()
    assert warm_up.needs_compiling() is False
    assert warm_up.warm_up() is False


def test_warm_up_command_says_what_it_did(capsys):
    from allsky.apps import cli

    assert cli.main(["warm-up", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("frame loop ") and out.count("\n") == 1


_STAMP = textwrap.dedent("""
    import sys
    sys.path.insert(0, sys.argv[1])
    from allsky import sources
    print(sources.source_stamp(sources.PACKAGE_DIR + "/sim/frame_loop.py"))
""")


def _copy_package(dst):
    import shutil

    import allsky

    src = os.path.dirname(allsky.__file__)
    shutil.copytree(src, dst / "allsky", ignore=shutil.ignore_patterns("*.pyc"))
    return dst / "allsky"


def _stamp_of(root):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    return subprocess.run([sys.executable, "-c", _STAMP, str(root)], capture_output=True,
                          text=True, check=True, env=env).stdout.strip()


def test_the_cache_key_covers_every_block_the_loop_reaches(tmp_path):
    """An edited block in another file makes the loop's cache stale; a copy elsewhere does not."""
    from allsky import sources

    reached = {os.path.relpath(p, sources.PACKAGE_DIR) for p in sources.source_closure(
        os.path.join(sources.PACKAGE_DIR, "sim", "frame_loop.py"))}
    assert {"hardware/gyro.py", "hardware/vfc.py", "gauss.py", "vehicle/plant.py",
            "sequencer/watch.py", "jit.py"} <= {p.replace(os.sep, "/") for p in reached}
    assert not any(p.startswith("apps") for p in reached)  # front ends are not compiled

    pkg = _copy_package(tmp_path)
    here = sources.source_stamp(os.path.join(sources.PACKAGE_DIR, "sim", "frame_loop.py"))
    assert _stamp_of(tmp_path) == here  # relocatable: an installed copy matches its build
    with open(pkg / "apps" / "plots.py", "a") as f:
        f.write("\n# a front end edited\n")
    assert _stamp_of(tmp_path) == here
    with open(pkg / "hardware" / "vfc.py", "a") as f:
        f.write("\n# a block edited\n")
    assert _stamp_of(tmp_path) != here


@needs_jit
def test_a_copy_of_the_package_with_its_cache_starts_without_compiling(tmp_path):
    """What an install does with the loop its build compiled (setup.py): no compile on first use."""
    if numba.config.CACHE_DIR:
        pytest.skip("the compiled loop is under NUMBA_CACHE_DIR, not beside the sources")
    warm_up.warm_up()  # loads it, or compiles it beside the sources
    _copy_package(tmp_path)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "NUMBA_CACHE_DIR")}
    code = ("import sys; sys.path.insert(0, sys.argv[1]); import allsky; "
            "from allsky.sim import warm_up; print(allsky.__file__, warm_up.needs_compiling())")
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True,
                         text=True, check=True, env=env).stdout.split()
    assert out[0].startswith(str(tmp_path)) and out[1] == "False"


def test_the_cache_keys_quick_import_scan_finds_every_import_the_parser_finds():
    """The regular-expression scan (run at every start) misses no import that ast finds."""
    from pathlib import Path

    from allsky import layers, sources

    for path in sorted(Path(sources.PACKAGE_DIR).rglob("*.py")):
        scanned = {layers.module_name(Path(p)) for p in sources._read_module(str(path))[1]}
        missed = layers.imports_of(path) - scanned
        assert not missed, f"{path.name}: {sorted(missed)}"


def _installed_from_a_wheel():
    """The installed allsky's files per its RECORD, or None for an editable or source tree."""
    import importlib.metadata as md
    import json

    import allsky

    try:
        dist = md.distribution("allsky")
    except md.PackageNotFoundError:
        return None
    direct = json.loads(dist.read_text("direct_url.json") or "{}")
    if direct.get("dir_info", {}).get("editable"):
        return None
    files = {str(f): f for f in dist.files or ()}
    init = files.get("allsky/__init__.py")
    if init is None or os.path.realpath(init.locate()) != os.path.realpath(allsky.__file__):
        return None
    return files


@needs_jit
def test_the_installed_wheel_carried_the_compiled_loop_and_nothing_compiled_it_again():
    """pip install . built the wheel with the loop compiled (setup.py), and it was used as is.

    The loop's cache index is in the wheel's RECORD with its hash; numba rewrites an index
    when it compiles a new entry, so an unchanged hash means no process of this install has
    compiled the loop: every mission of the test suite loaded the build's.
    """
    import base64
    import hashlib

    files = _installed_from_a_wheel()
    if files is None:
        pytest.skip("allsky is not installed from a wheel here (editable or source tree)")
    if os.environ.get("ALLSKY_BUILD_COMPILE") == "0" or numba.config.CACHE_DIR:
        pytest.skip("the build was told not to compile, or the cache is elsewhere")
    warm_up.warm_up(warm_up.LOOPS)
    for loop in ("_run_leg_plain", "_run_leg_any"):
        index = [f for name, f in files.items()
                 if name.startswith(f"allsky/sim/__pycache__/frame_loop.{loop}-")
                 and name.endswith(".nbi")]
        assert len(index) == 1, f"the wheel carries no compiled {loop}"
        shipped = index[0].hash
        data = index[0].locate().read_bytes()
        now = base64.urlsafe_b64encode(hashlib.new(shipped.mode, data).digest()).rstrip(b"=")
        assert now.decode() == shipped.value, f"{loop} was compiled again after the install"


# -- the build and the compile messages -------------------------------------------------------

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _setup_constants():
    """The constants setup.py defines (read with ast: setup.py runs setup() on import)."""
    import ast

    with open(os.path.join(ROOT, "setup.py"), encoding="utf-8") as f:
        tree = ast.parse(f.read())
    out = {}
    for node in tree.body:
        if isinstance(node, ast.Assign):
            try:
                value = ast.literal_eval(node.value)
            except ValueError:
                continue
            for target in node.targets:
                if isinstance(target, ast.Name):
                    out[target.id] = value
                elif isinstance(target, ast.Tuple):
                    out.update({t.id: v for t, v in zip(target.elts, value, strict=True)})
    return out


def test_every_compile_time_said_is_the_measured_one():
    """The build, warm-up, its help and the pages say the times of warm_up.COMPILE_S."""
    import re

    from allsky.apps import cli

    t = warm_up.COMPILE_S
    consts = _setup_constants()
    assert consts["BUILD_TIME"] == f"about {t['build']} s"
    assert consts["FIRST_COMPILE"] == f"about {t['first use']} s"
    help_text = cli._parser()._subparsers._group_actions[0].choices["warm-up"].description
    assert f"about {t['warm-up']} s" in help_text
    pages = {"README.md": t["build"], "docs/getting_started.md": t["build"]}
    for page, seconds in pages.items():
        with open(os.path.join(ROOT, page), encoding="utf-8") as f:
            text = " ".join(f.read().split())
        said = re.findall(r"\(about (\d+) s of the install\)", text)
        assert said and all(int(s) == seconds for s in said), (page, said)
    with open(os.path.join(ROOT, "docs/montecarlo.md"), encoding="utf-8") as f:
        text = " ".join(f.read().split())
    assert f"compiles, about {t['first use']} s," in text


def test_setup_and_the_package_give_the_same_hints():
    from allsky import aot

    consts = _setup_constants()
    assert consts["COMPILER_HINT"] == aot.COMPILER_HINT
    assert consts["WITHOUT_AOT"] == aot.WITHOUT_AOT
    assert consts["NOTE"] == os.path.basename(aot.NOTE)


def test_an_installed_wheel_is_tagged_for_its_platform():
    """A wheel carrying the compiled loop is a platform wheel, installed in platlib."""
    import importlib.metadata as md
    import sysconfig

    files = _installed_from_a_wheel()
    if files is None:
        pytest.skip("allsky is not installed from a wheel here (editable or source tree)")
    if os.environ.get("ALLSKY_BUILD_COMPILE") == "0":
        pytest.skip("the build was told not to compile: a pure wheel")
    wheel = md.distribution("allsky").read_text("WHEEL")
    assert "Root-Is-Purelib: false" in wheel
    tag = sys.implementation.cache_tag.replace("cpython-", "cp")
    platform = sysconfig.get_platform().replace("-", "_").replace(".", "_")
    assert f"Tag: {tag}-{tag}-{platform}" in wheel, wheel


def test_the_build_note_is_said_once(tmp_path, monkeypatch, capsys):
    """What the install could not build is said by the first command that flies, once."""
    import json

    from allsky import aot
    from allsky.apps import cli

    note = tmp_path / "_build_note.json"
    note.write_text(json.dumps({"missing": "the loop built ahead of time",
                                "reason": "no C compiler (cc not found)",
                                "hint": aot.COMPILER_HINT, "effect": aot.WITHOUT_AOT}))
    monkeypatch.setattr(aot, "NOTE", str(note))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    cli.build_note_once()
    first = capsys.readouterr().err
    assert first.count("\n") == 1 and first.startswith("allsky: note: this install has no "
                                                       "the loop built ahead of time")
    assert "conda install -c conda-forge c-compiler" in first and "0.6 s" in first
    cli.build_note_once()
    assert capsys.readouterr().err == ""
    (tmp_path / "_build_note.shown").unlink()  # the package read-only: the user's cache
    os.chmod(tmp_path, 0o555)
    try:
        if os.access(tmp_path, os.W_OK):  # root writes anyway: nothing more to see
            return
        cli.build_note_once()
        assert capsys.readouterr().err == first
        cli.build_note_once()
        assert capsys.readouterr().err == ""
    finally:
        os.chmod(tmp_path, 0o755)


def test_the_compile_lock_taken_again_inside_its_block_is_the_one_held():
    """A warm-up's mission compiles its loop under the lock the warm-up holds: no wait."""
    import threading

    from allsky import compiles

    loop = warm_up.entry_points()[0]

    def nested():
        with compiles.compile_lock(loop), compiles.compile_lock(loop):
            pass

    t = threading.Thread(target=nested, daemon=True)
    t.start()
    t.join(timeout=30)
    assert not t.is_alive(), "a second flock of the same file waited for the first"
    assert compiles._held == {}


def test_a_leg_that_compiles_says_so_and_holds_the_lock(default_cfg, monkeypatch):
    """run_leg's compile is announced (True, then False) and runs under the machine's lock."""
    from allsky import compiles
    from allsky.sim import frame_loop
    from allsky.sim.mission import Mission

    heard, locked = [], []
    real = frame_loop.leg_entry

    def leg_entry(p):
        loop = real(p)

        def fly(*args):
            locked.append(bool(compiles._held))
            return loop(*args)

        return fly

    monkeypatch.setattr(frame_loop, "leg_entry", leg_entry)
    monkeypatch.setattr(frame_loop, "_LOADED", set())
    monkeypatch.setattr(frame_loop, "needs_compiling", lambda entries: not heard)
    monkeypatch.setattr(compiles, "ON_COMPILE", [lambda on: heard.append(on)])
    Mission(default_cfg, telemetry=False).run_mode()
    assert heard == [True, False]  # the first leg only: it compiled
    assert locked[0] and not any(locked[1:])  # under the lock, and later legs not
