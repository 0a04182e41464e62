"""Caches that heal: a damaged numba cache file is set aside in one line and compiled again.

Each way of damage is made on a small cached function's files (numba's own
index ``.nbi`` and data ``.nbc``, the classes every cached allsky function
uses too), in a fresh process as a later command would meet it: the answer
is the same, one line says what was set aside, and the next run loads the
rebuilt cache silently.
"""

import os
import random
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"

PROGRAM = """
import sys
from allsky import jit_cache
jit_cache.install()
import numba

@numba.njit(cache=True)
def f(x):
    return x * 2.5 + 1.0

print(repr(f(3.0)))
"""


def _run(workdir: Path):
    env = {**os.environ, "PYTHONPATH": str(SRC), "NUMBA_CACHE_DIR": str(workdir / "cache")}
    return subprocess.run([sys.executable, str(workdir / "prog.py")], capture_output=True,
                          text=True, env=env, timeout=300, check=False)


def _files(workdir, suffix):
    return sorted((workdir / "cache").rglob(f"*{suffix}"))


def _random_bytes(path):
    data = bytearray(path.read_bytes())
    rng = random.Random(str(path.name))
    for _ in range(max(8, len(data) // 50)):
        data[rng.randrange(len(data))] = rng.randrange(256)
    path.write_bytes(bytes(data))


def _truncate(path):
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


@pytest.mark.parametrize("suffix", [".nbi", ".nbc"])
@pytest.mark.parametrize("damage", [_random_bytes, _truncate])
def test_a_damaged_cache_file_heals_on_the_next_run(tmp_path, suffix, damage):
    (tmp_path / "prog.py").write_text(PROGRAM)
    first = _run(tmp_path)
    assert first.returncode == 0 and first.stdout == "8.5\n", first.stderr
    (target,) = _files(tmp_path, suffix)
    damage(target)
    healed = _run(tmp_path)
    assert healed.returncode == 0, healed.stderr
    assert healed.stdout == first.stdout  # the same bits
    notes = [line for line in healed.stderr.splitlines() if line.strip()]
    assert len(notes) == 1 and notes[0].startswith("allsky: note: numba's cache file"), notes
    assert "damaged" in notes[0] and "Traceback" not in healed.stderr
    again = _run(tmp_path)  # the rebuilt cache loads, silently
    assert again.returncode == 0 and again.stdout == first.stdout and again.stderr == ""


def test_warm_up_check_names_what_is_damaged_and_changes_nothing(tmp_path):
    from allsky.apps.warm import cache_problems

    (tmp_path / "prog.py").write_text(PROGRAM)
    assert _run(tmp_path).returncode == 0
    (directory,) = {p.parent for p in _files(tmp_path, ".nbi")}
    assert cache_problems(directory) == (2, [])
    (nbc,) = _files(tmp_path, ".nbc")
    _truncate(nbc)
    files, damaged = cache_problems(directory)
    assert files == 2 and len(damaged) == 1 and str(nbc) in damaged[0]
    assert nbc.exists()  # the check sets nothing aside


def test_warm_up_check_reports_in_lines(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    r = subprocess.run([sys.executable, "-m", "allsky", "warm-up", "--check"],
                       capture_output=True, text=True, env=env, timeout=300, check=False)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0].startswith("allsky ") and lines[1].startswith("ahead of time: ")
    assert lines[2].startswith("frame loop: ") and "Traceback" not in r.stderr
