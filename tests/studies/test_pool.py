"""WorkerPool: each job once, a dead worker replaced and its job flown again, Ctrl-C clean.

A worker is killed by SIGKILL from inside the job it is flying (the job
kills its own process), which is what the kernel's out-of-memory killer or
``kill -9`` does to a worker, at a moment that does not depend on timing.
"""

import os
import signal
import time
from pathlib import Path

import pytest

from allsky.studies.pool import Died, PoolError, WorkerPool


def _square(job):
    return job * job


def _kill_once(job):
    """Square the number; the first time job 3 is flown, SIGKILL the worker flying it."""
    number, marks = job
    if number == 3:
        mark = Path(marks) / "killed"
        if not mark.exists():
            mark.write_text("1")
            os.kill(os.getpid(), signal.SIGKILL)
    return number * number


def _kill_always(job):
    number, _ = job
    if number == 2:
        os.kill(os.getpid(), signal.SIGKILL)
    return number * number


def _raise(job):
    raise ValueError(f"job {job}")


def _fly(pool, jobs):
    try:
        return dict(pool.results((k, j) for k, j in jobs))
    finally:
        pool.close()


def test_every_job_once_in_any_order():
    pool = WorkerPool(_square, 2)
    assert _fly(pool, ((k, k) for k in range(20))) == {k: k * k for k in range(20)}
    assert pool.replaced == 0


def test_jobs_are_drawn_as_workers_come_free():
    """Never more than two jobs per worker ahead of the caller, however the workers race.

    Each worker holds one job; a wait collects at most one finished job per worker,
    and each free worker is handed its next before those are yielded. So at any
    yield, jobs drawn - results yielded <= 2 x workers: memory flat in the runs.
    """
    drawn, workers = [], 2

    def jobs():
        for k in range(200):
            drawn.append(k)
            yield k, k

    pool = WorkerPool(_square, workers)
    ahead = []
    for n, (key, result) in enumerate(pool.results(jobs()), start=1):
        assert result == key * key
        ahead.append(len(drawn) - n)
    pool.close()
    assert len(ahead) == 200 and max(ahead) <= 2 * workers - 1


def test_a_worker_killed_mid_job_is_replaced_and_the_job_flown_again(tmp_path):
    pool = WorkerPool(_kill_once, 2)
    out = _fly(pool, ((k, (k, str(tmp_path))) for k in range(8)))
    assert out == {k: k * k for k in range(8)}
    assert pool.replaced == 1


def test_a_job_that_kills_its_worker_twice_comes_back_died(tmp_path):
    pool = WorkerPool(_kill_always, 2)
    out = _fly(pool, ((k, (k, str(tmp_path))) for k in range(5)))
    assert isinstance(out[2], Died)
    assert out[2].exit_codes == (-signal.SIGKILL, -signal.SIGKILL)
    assert out[2].reason() == "its worker process died twice (SIGKILL, SIGKILL)"
    assert {k: v for k, v in out.items() if k != 2} == {0: 0, 1: 1, 3: 9, 4: 16}
    assert pool.replaced == 2


def test_an_exception_of_the_job_is_raised_in_the_parent():
    pool = WorkerPool(_raise, 2)
    with pytest.raises(ValueError, match="job 1"):
        _fly(pool, [(1, 1)])


def _broken_start():
    raise RuntimeError("cannot start")


def _exit_at_start():
    os._exit(7)


def test_an_initializer_that_raises_is_the_answer_to_every_job():
    pool = WorkerPool(_square, 2, initializer=_broken_start)
    with pytest.raises(RuntimeError, match="cannot start"):
        _fly(pool, [(1, 1), (2, 2)])


def test_workers_that_cannot_start_end_the_pool_in_one_error():
    pool = WorkerPool(_square, 2, initializer=_exit_at_start)
    with pytest.raises(PoolError, match="died before their first job"):
        _fly(pool, [(1, 1), (2, 2)])


def test_finish_lets_the_jobs_under_way_end():
    pool = WorkerPool(_square, 2)
    it = pool.results((k, k) for k in range(100))
    first = [next(it)]
    rest = pool.finish()  # as after a Ctrl-C: nothing more handed out
    pool.close()
    got = dict(first + rest)
    assert 1 <= len(got) <= 3 and all(v == k * k for k, v in got.items())


def test_no_worker_outlives_the_pool():
    pool = WorkerPool(_square, 2)
    it = pool.results((k, k) for k in range(4))
    next(it)
    processes = [w.process for w in [*pool._idle, *pool._busy.values()]]
    assert len(processes) == 2 and all(p.is_alive() for p in processes)
    list(it)
    pool.close()
    assert not any(p.is_alive() for p in processes)


def _compiling_or_gated(job):
    """Job "compile" says it compiles the frame loop and would take ten minutes; "gate"
    marks that it was taken, then ends after a moment; a number is squared."""
    if job == "compile":
        from allsky import compiles

        for tell in compiles.ON_COMPILE:  # as frame_loop.run_leg does before a compile
            tell(True)
        time.sleep(600)
    if isinstance(job, tuple):
        Path(job[1]).touch()
        time.sleep(0.5)
        return "flown"
    return job * job


def _wait_for(path):
    deadline = time.monotonic() + 60
    while not path.exists():
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.01)


def test_finish_ends_a_compiling_worker_at_once_and_waits_for_a_flying_one(tmp_path):
    """After a Ctrl-C a compile (a minute on an empty cache) is not waited for; a flight is."""
    taken = tmp_path / "taken"
    pool = WorkerPool(_compiling_or_gated, 2)
    it = pool.results([(0, "compile"), (1, 1), (2, ("gate", str(taken)))])
    assert next(it) == (1, 1)  # job 0 compiles on one worker; job 2 went to the other
    _wait_for(taken)
    compiling = [w.process for w in pool._busy.values() if w.key == 0]
    t0 = time.monotonic()
    rest = pool.finish()
    waited = time.monotonic() - t0
    pool.close()
    assert rest == [(2, "flown")]
    assert not compiling[0].is_alive()
    assert waited < 60  # liveness: the compile alone would take 600 s


def _slow_start(marks):
    try:
        os.close(os.open(Path(marks) / "slow", os.O_CREAT | os.O_EXCL))
    except FileExistsError:
        return  # the other worker: ready at once
    time.sleep(600)  # this one starts for ten minutes (its loop compiling in its initializer)


def test_finish_ends_a_worker_still_starting_at_once(tmp_path):
    """A job handed to a worker still in its initializer was never under way."""
    pool = WorkerPool(_square, 2, initializer=_slow_start, initargs=(str(tmp_path),))
    it = pool.results((k, k) for k in range(10))
    first = next(it)
    t0 = time.monotonic()
    rest = pool.finish()
    waited = time.monotonic() - t0
    pool.close()
    got = dict([first, *rest])
    assert all(v == k * k for k, v in got.items())
    assert waited < 60  # liveness: the slow start alone would take 600 s
