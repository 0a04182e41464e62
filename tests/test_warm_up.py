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
