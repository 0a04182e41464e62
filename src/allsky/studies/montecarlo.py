"""Monte Carlo campaigns: missions over seeds and dispersions, and statistics.

Run i of a campaign flies the scenario with ``mission.seed = base + i``
(base: the scenario's ``mission.seed``) and its ``[dispersions]`` drawn for
that seed (:mod:`allsky.config.dispersions`), so any run is reproduced alone by
``allsky run SCENARIO --set mission.seed=S`` with the same dispersions.

Each run gives one row of scalars (:func:`columns`): its index and seed,
the inputs drawn, the end time of each mode, the calibration errors
(stored - truth), the final pointing error, the propellant used, the
mission time, the status and the abort reason. Runs are flown on local
worker processes (default: one per core) or on an existing Dask
distributed cluster, with identical rows either way.

:func:`run_campaign` hands each finished row to a callback the moment it
arrives, so that a caller can make the campaign durable;
:mod:`allsky.apps.campaign` does (the campaign directory, ``--resume``,
the table and the histograms of ``allsky montecarlo``).
"""

import contextlib
import itertools
import json
import logging
import math
import os
import signal
import statistics
import time
from collections import Counter

import numpy as np

from allsky.config import ConfigError, dispersions, scenario_from_dict
from allsky.config.rules import RUNS_MAX
from allsky.sequencer.master_sequencer import MODES
from allsky.sim import results
from allsky.sim.faults import symptom
from allsky.sim.results import calibration_errors
from allsky.studies.pool import Died, PoolError, WorkerPool, worker_process_setup

__all__ = ["RUNS_MAX", "worker_process_setup"]  # worker_process_setup: allsky.studies.pool

AXES = results.AXES
SF_AXES = results.SCALE_FACTOR_AXES
CC_KEYS = results.CROSS_COUPLING_KEYS
#: Columns every campaign has, before the drawn inputs.
ID_COLUMNS = ("run", "seed", "status", "abort_reason")
#: Result columns, after the drawn inputs (units in the names).
RESULT_COLUMNS = (
    *(f"mode_end_{m}_s" for m in MODES),
    *(f"drift_error_{a}_deg_h" for a in AXES),
    *(f"scale_factor_error_{a}_ppm" for a in SF_AXES),
    *(f"cross_coupling_error_{k}_arcsec" for k in CC_KEYS),
    "pointing_error_arcsec", "propellant_kg", "mission_time_s",
)
#: Columns that hold text (the others are numbers; run and seed integers).
TEXT_COLUMNS = {"status", "abort_reason", "target.star", "mission.date_utc"}
#: Columns summarised (over the complete missions), with their labels.
METRICS = {
    "pointing_error_arcsec": "pointing error [arcsec]",
    **{f"drift_error_{a}_deg_h": f"drift error {a} [deg/h]" for a in AXES},
    **{f"scale_factor_error_{a}_ppm": f"scale-factor error {a} [ppm]" for a in SF_AXES},
    **{f"cross_coupling_error_{k}_arcsec": f"{k.replace('_', ' ')} error [arcsec]"
       for k in CC_KEYS},
    "propellant_kg": "propellant used [kg]",
    "mission_time_s": "mission time [s]",
    **{f"mode_end_{m}_s": f"end of Mode {m} [s]" for m in MODES[:-1]},
}
PERCENTILES = (5, 50, 95)
#: [s] A Dask task's overhead: the CPU time per trivial task of every process taking part
#: (client, scheduler, nannies, workers) with both workers of a ``LocalCluster`` of two
#: single-threaded worker processes busy, tasks submitted a window at a time and taken as
#: they complete, as a campaign's batches are: 5.0-6.7 ms measured on the 2-core
#: development machine (wall time per task 3.6-6.4 ms; ``benchmarks/dask_throughput.py``,
#: docs/montecarlo.md).
DASK_TASK_OVERHEAD_S = 0.005
#: Most of a batch's time its task's overhead may take (:func:`batch_size`).
BATCH_OVERHEAD_SHARE = 0.02
#: Most of the time the client and scheduler, which handle the tasks one after another,
#: may spend on them (:func:`batch_size`: the rule that binds on clusters of many threads).
SCHEDULER_SHARE = 0.5
#: [s] Longest a batch is meant to fly: its rows, and the progress, come back at least
#: this often from each worker thread.
BATCH_MAX_S = 0.5
#: Batches per worker thread at least, out of the runs left, so that the last ones end
#: together (at the end of a campaign the batches shrink).
BATCHES_PER_THREAD = 4
#: Batches timed for the mission time (:class:`_Batches`: the median of the last ones).
MISSION_TIMES_KEPT = 16
#: Dask batches in flight per worker thread (one flying, the others queued).
IN_FLIGHT_PER_WORKER = 4
#: [s] time allowed to reach a Dask scheduler
DASK_CONNECT_TIMEOUT_S = 10.0


class CampaignError(Exception):
    """A campaign that cannot start or go on (seeds, directory, resume, cluster)."""


class ClusterLost(CampaignError):
    """The Dask workers or scheduler went away in the middle of a campaign."""


# ---------------------------------------------------------------------------
# One run
# ---------------------------------------------------------------------------

def columns(cfg) -> list:
    """The row's columns for this scenario (its dispersions decide the input columns).

    Parameters
    ----------
    cfg : Scenario
        The campaign's scenario, with its ``[dispersions]``.

    Returns
    -------
    list of str
        :data:`ID_COLUMNS`, the drawn inputs' columns, :data:`RESULT_COLUMNS`.
    """
    return [*ID_COLUMNS, *dispersions.input_columns(cfg), *RESULT_COLUMNS]


def row_from_summary(run: int, seed: int, inputs: dict, summary: dict) -> dict:
    """A campaign row from a mission summary (:meth:`Mission.summary`).

    Values a mission did not reach (modes not flown, no calibration, no final
    pointing) are None.

    Parameters
    ----------
    run : int
        The run's index in the campaign.
    seed : int
        Its mission seed.
    inputs : dict
        The drawn values as flat columns
        (:func:`allsky.config.dispersions.flat_inputs`).
    summary : dict
        The mission's summary.

    Returns
    -------
    dict
        The row, by column (:func:`columns`).
    """
    row = {"run": int(run), "seed": int(seed), "status": summary["status"],
           "abort_reason": summary["abort_reason"], **inputs}
    ends = {r["mode"]: r["end_s"] for r in summary["modes"]}
    row.update({f"mode_end_{m}_s": ends.get(m) for m in MODES})
    cal = summary["calibration"]
    err = calibration_errors(cal, summary["truth"]) if cal else None
    for a in AXES:
        row[f"drift_error_{a}_deg_h"] = err["drift_deg_h"][a] if err else None
    for a in SF_AXES:
        row[f"scale_factor_error_{a}_ppm"] = err["scale_factor_ppm"][a] if err else None
    for k in CC_KEYS:
        row[f"cross_coupling_error_{k}_arcsec"] = err["cross_coupling_arcsec"][k] if err else None
    row["pointing_error_arcsec"] = summary["target"]["pointing_error_arcsec"]
    row["propellant_kg"] = summary["propellant_kg"]
    row["mission_time_s"] = summary["mission_time_s"]
    return row


def fly_one(cfg, run: int, seed: int) -> dict:
    """Fly run ``run`` (mission seed ``seed``) on scenario ``cfg``; return its row.

    A draw that breaks a scenario rule (or that cannot be drawn) gives status
    ``"invalid"``, an unexpected failure status ``"error"``, each with its
    reason; neither stops the campaign.

    Parameters
    ----------
    cfg : Scenario
        The campaign's scenario, with its ``[dispersions]``.
    run : int
        The run's index in the campaign.
    seed : int
        Its mission seed (the dispersions are drawn for it).

    Returns
    -------
    dict
        The row (:func:`row_from_summary`).
    """
    from allsky.sim.mission import run_mission

    try:
        run_cfg, drawn = dispersions.disperse(cfg, seed)
    except ConfigError as e:
        try:  # the values drawn, for the row's input columns, when they could be drawn
            drawn = dispersions.draw(cfg, seed)
        except ConfigError:
            drawn = {}
        return _failed_row(cfg, run, seed, drawn, "invalid", f"drawn scenario rejected: {e}")
    except Exception as e:  # noqa: BLE001 - one broken draw must not end a long campaign
        return _failed_row(cfg, run, seed, {}, "error", f"{type(e).__name__}: {e}")
    try:
        m = run_mission(run_cfg, telemetry=False)
        return row_from_summary(run, seed, dispersions.flat_inputs(cfg, drawn), m.summary())
    except Exception as e:  # noqa: BLE001 - one broken run must not end a long campaign
        return _failed_row(cfg, run, seed, drawn, "error", f"{type(e).__name__}: {e}")


def _failed_row(cfg, run, seed, drawn, status, reason):
    row = dict.fromkeys(columns(cfg))
    row.update(run=int(run), seed=int(seed), status=status, abort_reason=reason)
    row.update(dispersions.flat_inputs(cfg, drawn))
    return row


_WORKER = {}


def fly_runs(data: dict, jobs) -> list:
    """Worker entry point: rows of ``jobs`` ((run, seed) pairs) on scenario ``data``.

    Parameters
    ----------
    data : dict
        :meth:`Scenario.as_dict` output; the scenario is validated once per
        process and kept while the same data comes back.
    jobs : iterable of (int, int)
        The runs and their mission seeds, flown in this order.

    Returns
    -------
    list of dict
        One row per job (:func:`fly_one`), in the order of ``jobs``.
    """
    return fly_batch(data, jobs)[0]


def fly_batch(data: dict, jobs) -> tuple:
    """Worker entry point of a Dask batch: its rows, and the time its missions took.

    Parameters
    ----------
    data : dict
        :meth:`Scenario.as_dict` output (see :func:`fly_runs`).
    jobs : list of (int, int)
        The batch's runs and their mission seeds, flown in this order.

    Returns
    -------
    (list of dict, float)
        The rows, in the order of ``jobs``, and the seconds spent flying them
        (the scenario's validation and the compiled loop's loading left out),
        from which the campaign sizes its next batches (:func:`batch_size`).
    """
    key = json.dumps(data, sort_keys=True)
    if _WORKER.get("key") != key:
        _WORKER.update(key=key, cfg=scenario_from_dict(data))
        _compile_once_per_machine()
    t0 = time.perf_counter()
    rows = [fly_one(_WORKER["cfg"], run, seed) for run, seed in jobs]
    return rows, time.perf_counter() - t0


def _compile_once_per_machine():
    # Workers starting together on a fresh machine would each compile the frame loop
    # (about 16 s of CPU each); under the machine's compile lock one compiles and the
    # others load its cache (allsky.sim.warm_up).
    from allsky.sim import warm_up

    if warm_up.needs_compiling():
        warm_up.warm_up()


def _init_local_worker(data):
    _WORKER.update(key=json.dumps(data, sort_keys=True), cfg=scenario_from_dict(data))
    _compile_once_per_machine()


def stop_pool(pool, interrupted):
    """End a :class:`~allsky.studies.pool.WorkerPool`; after an interruption, at once.

    The jobs under way were waited for already (:meth:`WorkerPool.finish`);
    what is left is idle workers, or jobs a second Ctrl-C gave up on.

    Parameters
    ----------
    pool : WorkerPool
        The pool to end.
    interrupted : bool
        Whether the campaign was interrupted (or ends with runs not flown):
        the workers are then terminated rather than asked to stop.
    """
    pool.close(at_once=interrupted)


@contextlib.contextmanager
def interrupts_held():
    """Ignore Ctrl-C, SIGTERM and SIGHUP while an interrupted campaign tidies up.

    The tidying (rows that finished, workers ended) is short and bounded; a
    second Ctrl-C in the middle of it would leave workers behind or a row
    unsaved. Outside the main thread, where signals cannot be set, nothing
    changes.
    """
    try:
        ending = [getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP")
                  if hasattr(signal, n)]
        old = {sig: signal.signal(sig, signal.SIG_IGN) for sig in ending}
    except ValueError:
        yield
        return
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


def ordered_rows(fly, jobs, workers, on_progress=None, fly_here=None, total=None,
                 died=None):
    """``fly`` over ``jobs`` in order on ``workers`` processes; Ctrl-C stops cleanly.

    Parameters
    ----------
    fly : callable
        ``fly(job)`` -> row; module-level (it crosses to the worker processes).
    jobs : iterable
        Drawn one at a time as workers come free (a generator holds no list).
    workers : int
        Worker processes (:class:`~allsky.studies.pool.WorkerPool`); 1 flies
        in this process, with ``fly_here`` when given (e.g. a version that
        reports its own progress).
    on_progress : callable, optional
        ``on_progress(done, total)`` after each row, in order.
    total : int, optional
        The number of jobs (default ``len(jobs)``).
    died : callable, optional
        ``died(job, reason)`` -> the row of a job whose worker process died
        twice flying it (:class:`~allsky.studies.pool.Died`); without it such
        a job raises :class:`~allsky.studies.pool.PoolError`.

    Returns
    -------
    (list, bool)
        The rows, in the order of ``jobs``, and whether Ctrl-C stopped them:
        the jobs under way then finish (a second Ctrl-C ends them at once)
        and the rows up to the first missing one are kept. With no row
        finished, the KeyboardInterrupt goes on.
    """
    total = len(jobs) if total is None else int(total)
    workers = max(1, min(int(workers), total))  # no idle processes
    rows, interrupted = [], False

    def progress():
        if on_progress is not None:
            on_progress(len(rows), total)

    if workers == 1:
        try:
            for job in jobs:
                rows.append((fly_here or fly)(job))
                progress()
        except KeyboardInterrupt:
            if not rows:
                raise
            interrupted = True
        return rows, interrupted
    pool = WorkerPool(fly, workers)
    waiting, flying = {}, {}  # index -> row ahead of its turn; index -> job under way

    def feed():
        for i, job in enumerate(jobs):
            flying[i] = job
            yield i, job

    def take(pairs):
        for i, result in pairs:
            job = flying.pop(i)
            if isinstance(result, Died):
                if died is None:
                    raise PoolError(f"job {i}: {result.reason()}")
                result = died(job, result.reason())
            waiting[i] = result
            while len(rows) in waiting:
                rows.append(waiting.pop(len(rows)))
                progress()

    try:
        for pair in pool.results(feed()):
            take([pair])
    except KeyboardInterrupt:
        interrupted = True
        take(pool.finish())
        if not rows:
            raise
    finally:
        with interrupts_held():
            stop_pool(pool, interrupted or len(rows) < total)
    return rows, interrupted


def died_row_maker(cfg):
    """``died(job, reason)`` for :func:`ordered_rows` over runs of ``cfg``.

    Parameters
    ----------
    cfg : Scenario
        The campaign's scenario (the row's drawn inputs are drawn again).

    Returns
    -------
    callable
        ``died((run, seed), reason)`` -> a row of status ``worker_died``.
    """
    def died(job, reason):
        run, seed = job
        try:
            drawn = dispersions.draw(cfg, seed)
        except ConfigError:
            drawn = {}
        return _failed_row(cfg, run, seed, drawn, "worker_died", reason)

    return died


def _fly_local(job):
    run, seed = job
    return fly_one(_WORKER["cfg"], run, seed)


# ---------------------------------------------------------------------------
# Executors: runs in flight, results as they come
# ---------------------------------------------------------------------------

def batch_size(mission_s, threads: int, left: int, overhead_s=DASK_TASK_OVERHEAD_S) -> int:
    """Runs per Dask task: overhead a small share, rows still flowing, workers even.

    * the overhead rule: a task's overhead ``overhead_s`` at most
      :data:`BATCH_OVERHEAD_SHARE` of its batch's time, ``ceil(overhead_s /
      (share * mission_s))`` runs;
    * the progress rule caps it: a batch flies at most :data:`BATCH_MAX_S`, so
      that rows (and progress) come back at least that often from each worker
      thread;
    * the scheduler rule: the client and scheduler handle the tasks one after
      another, ``overhead_s`` each; with ``threads`` worker threads a batch has
      at least ``threads * overhead_s / (SCHEDULER_SHARE * mission_s)`` runs,
      so that they are busy at most :data:`SCHEDULER_SHARE` of the time (on
      more than about 25 threads this rule, not the progress rule, binds: rows
      still arrive often, from many threads);
    * the balance rule caps all: at least :data:`BATCHES_PER_THREAD` batches
      per worker thread out of the ``left`` runs, so that the last batches end
      together.

    Parameters
    ----------
    mission_s : float or None
        [s] Time of one mission on a worker thread; None (not yet measured)
        gives batches of one run, which are measured.
    threads : int
        Worker threads of the cluster.
    left : int
        Runs not yet handed out.
    overhead_s : float
        [s] Overhead of one task (:data:`DASK_TASK_OVERHEAD_S`).

    Returns
    -------
    int
        The number of runs in the next batch (the rows do not depend on it).
    """
    if mission_s is None or not mission_s > 0:
        return 1
    threads = max(int(threads), 1)
    by_overhead = math.ceil(overhead_s / (BATCH_OVERHEAD_SHARE * mission_s))
    by_progress = math.floor(BATCH_MAX_S / mission_s)
    by_scheduler = math.ceil(threads * overhead_s / (SCHEDULER_SHARE * mission_s))
    by_balance = math.ceil(max(left, 1) / (BATCHES_PER_THREAD * threads))
    return max(1, min(max(min(by_overhead, by_progress), by_scheduler), by_balance))


class _Batches:
    """Batches of runs on an executor, a window at a time; each batch's rows as it ends.

    ``submit(jobs)`` starts a batch (a future of :func:`fly_batch`'s result);
    ``wait_first(futures)`` returns the ones that have finished. Each batch's
    size is :func:`batch_size` of the mission time measured so far (the
    median of the last :data:`MISSION_TIMES_KEPT` batches), or ``batch`` when
    given. Rows come out in the order of each batch; the batches in the order
    they finish.

    A batch whose workers died (Dask's ``KilledWorker``: the cluster flew it on
    several workers and each died) is flown again one run a task, so that the
    other runs of the batch are saved; a single run whose workers died becomes
    the row ``died(job, reason)`` (status ``worker_died``), as on local
    workers. Without ``died`` the error is raised. :meth:`salvage` (after an
    interruption) cancels what has not started and returns the rows of the
    batches that finished but were not yet yielded.
    """

    def __init__(self, submit, wait_first, jobs, threads, batch=None, died=None):
        self.submit, self.wait_first, self.died = submit, wait_first, died
        self.jobs, self.left = iter(jobs), len(jobs)
        self.threads, self.batch = max(1, int(threads)), batch
        self.window = IN_FLIGHT_PER_WORKER * self.threads
        self.pending = {}  # future -> its jobs
        self.again = []  # runs of a batch whose workers died, flown one a task
        self.mission_times = []  # [s] per mission, of the last batches
        self.sizes = []  #: the size of each batch handed out, in order

    def mission_s(self):
        """[s] The mission time measured so far (None before the first batch ends)."""
        return statistics.median(self.mission_times) if self.mission_times else None

    def _next_batch(self):
        if self.again:
            return [self.again.pop(0)]
        size = self.batch or batch_size(self.mission_s(), self.threads, self.left)
        chunk = list(itertools.islice(self.jobs, size))
        self.left -= len(chunk)
        return chunk

    def _fill(self):
        while len(self.pending) < self.window:
            chunk = self._next_batch()
            if not chunk:
                return
            self.sizes.append(len(chunk))
            self.pending[self.submit(chunk)] = chunk

    def _rows(self, f, chunk):
        try:
            rows, seconds = f.result()
        except Exception as e:
            if self.died is None or type(e).__name__ != "KilledWorker":
                raise
            if len(chunk) > 1:
                self.again += chunk
                return []
            tries = getattr(e, "allowed_failures", None)
            times = f"{tries + 1} times" if isinstance(tries, int) else "each time"
            return [self.died(chunk[0], f"its Dask workers died {times} flying it "
                                        "(KilledWorker)")]
        if rows:
            self.mission_times = [*self.mission_times, seconds / len(rows)][
                -MISSION_TIMES_KEPT:]
        return rows

    def __iter__(self):
        self._fill()
        while self.pending:
            for f in self.wait_first(set(self.pending)):
                chunk = self.pending.pop(f)
                rows = self._rows(f, chunk)
                self._fill()  # the next batch is on its way before these are recorded
                if rows:
                    yield rows

    def salvage(self) -> list:
        """After a Ctrl-C: cancel the batches not finished; the rows of those that did."""
        for f in self.pending:
            f.cancel()
        rows = []
        for f, chunk in self.pending.items():
            if f.done() and not f.cancelled():
                try:
                    rows += self._rows(f, chunk)
                except Exception:  # noqa: BLE001, S112 - a failed batch has nothing to save
                    continue
        self.pending, self.again = {}, []
        return rows


class _LocalStream:
    """Rows of ``jobs`` on a :class:`~allsky.studies.pool.WorkerPool`, one run a job.

    A run whose worker process dies is flown again on a new worker; a run
    that kills its worker twice becomes a row of status ``worker_died``.
    """

    def __init__(self, data, jobs, workers):
        self.cfg = scenario_from_dict(data)
        self.pool = WorkerPool(_fly_local, workers, initializer=_init_local_worker,
                               initargs=(data,))
        self.jobs, self.died = jobs, died_row_maker(self.cfg)

    def _row(self, job, result):
        return self.died(job, result.reason()) if isinstance(result, Died) else result

    def __iter__(self):
        for job, result in self.pool.results((job, job) for job in self.jobs):
            yield [self._row(job, result)]

    def salvage(self) -> list:
        """After a Ctrl-C: the rows of the runs under way, which the workers finish."""
        return [self._row(job, result) for job, result in self.pool.finish()]


def _local_stream(data, jobs, workers):
    """Rows on ``workers`` local processes (in this process when 1)."""
    if workers == 1:
        cfg = scenario_from_dict(data)

        class _Serial:
            salvage = staticmethod(list)

            def __iter__(self):
                for run, seed in jobs:
                    yield [fly_one(cfg, run, seed)]
        return _Serial(), None
    stream = _LocalStream(data, jobs, workers)
    return stream, lambda interrupted=False: stop_pool(stream.pool, interrupted)


def _dask_stream(data, jobs, address, batch=None):
    """Rows on the Dask distributed cluster whose scheduler is at ``address``.

    Runs go in batches (:class:`_Batches`) of ``batch`` runs, or of the size
    :func:`batch_size` chooses from the mission time measured as they fly.
    """
    try:
        from distributed import Client
        from distributed import wait as dask_wait
    except ImportError:
        raise CampaignError("--scheduler needs Dask distributed: pip install "
                            "'dask[distributed]'") from None
    quiet = _dask_logs_quiet()
    try:
        client = Client(address, timeout=DASK_CONNECT_TIMEOUT_S)
    except (OSError, TimeoutError, ValueError) as e:
        quiet()
        raise CampaignError(f"cannot reach the Dask scheduler at {address}: "
                            f"{' '.join(str(e).split()) or type(e).__name__}") from None
    except BaseException:
        quiet()
        raise
    threads = max(1, sum(client.nthreads().values()))
    # Scatter the scenario as the single element of a list: a dict would be taken
    # as {key: value} and each section would become a cluster-global key
    # ("control", "gyro", ...) that another campaign on the same cluster could
    # overwrite or read. hash=False gives this campaign a key of its own.
    [data_future] = client.scatter([data], broadcast=True, hash=False)

    def submit(chunk):
        return client.submit(fly_batch, data_future, chunk, pure=False)

    def wait_first(fs):
        return dask_wait(list(fs), return_when="FIRST_COMPLETED").done

    stream = _Batches(submit, wait_first, jobs, threads, batch=batch,
                      died=died_row_maker(scenario_from_dict(data)))

    def close(interrupted=False):
        try:
            client.close(timeout=DASK_CONNECT_TIMEOUT_S)
        except Exception:  # noqa: BLE001, S110 - a client of a lost cluster closes as it can
            pass
        finally:
            quiet()

    return stream, close


#: Loggers of Dask and its network layer: while a campaign runs they stay silent (a lost
#: scheduler is one line of ours, ClusterLost, not forty of theirs).
DASK_LOGGERS = ("distributed", "tornado", "asyncio")


def _dask_logs_quiet():
    """Silence :data:`DASK_LOGGERS`; returns the function that restores them."""
    saved = {}
    names = [n for n in list(logging.root.manager.loggerDict)
             if any(n == d or n.startswith(d + ".") for d in DASK_LOGGERS)]
    for name in {*DASK_LOGGERS, *names}:
        log = logging.getLogger(name)
        saved[name] = (log.level, log.propagate, log.disabled)
        log.disabled = True
        if name in DASK_LOGGERS:  # loggers made later inherit it
            log.setLevel(logging.CRITICAL + 1)

    def restore():
        for name, (level, propagate, disabled) in saved.items():
            log = logging.getLogger(name)
            log.setLevel(level)
            log.propagate, log.disabled = propagate, disabled

    return restore


# ---------------------------------------------------------------------------
# The campaign
# ---------------------------------------------------------------------------

def _cluster_lost(e) -> bool:
    """Whether ``e`` says the Dask workers or scheduler went away (not a bug in a run).

    Runs catch their own failures (:func:`fly_one`), so what reaches here from
    the cluster is the cluster: futures cancelled or lost with their workers,
    a worker killed, the connection to the scheduler closed or timed out.
    """
    from concurrent.futures import CancelledError

    names = {"FuturesCancelledError", "KilledWorker", "CommClosedError", "CancelledError",
             "FutureCancelledError", "TimeoutError", "StreamClosedError"}
    return isinstance(e, CancelledError | OSError | TimeoutError) or type(e).__name__ in names


def check_seeds(cfg, runs: int):
    """Refuse more than :data:`RUNS_MAX` runs, or seeds past the largest.

    Parameters
    ----------
    cfg : Scenario
        The scenario; its ``mission.seed`` is the first run's seed.
    runs : int
        The number of runs asked for.

    Raises
    ------
    CampaignError
        Naming the number of runs or the seed range.
    """
    if not 1 <= runs <= RUNS_MAX:
        raise CampaignError(f"--runs {runs}: a campaign has 1..{RUNS_MAX} runs")
    base = int(cfg.mission.seed)
    if base + runs - 1 >= 2**32:
        raise CampaignError(f"seeds {base}..{base + runs - 1} pass the largest mission.seed "
                            f"({2**32 - 1})")


def check_scheduler(address: str):
    """Refuse an empty Dask scheduler address (Dask would start a cluster of its own).

    Parameters
    ----------
    address : str
        The ``--scheduler`` given.

    Raises
    ------
    CampaignError
        An empty or blank address.
    """
    if not str(address).strip():
        raise CampaignError("--scheduler: an empty address; give the scheduler's, "
                            "tcp://HOST:PORT, or leave --scheduler out to fly on this machine")


def check_batch(batch, scheduler):
    """Refuse a batch size below 1 or not whole, or one without a Dask scheduler.

    Parameters
    ----------
    batch : int or None
        Runs per Dask task asked for (None: chosen by :func:`batch_size`).
    scheduler : str or None
        The Dask scheduler's address; local workers fly one run at a time, so
        that the parent knows which run a dead worker took with it.

    Raises
    ------
    CampaignError
        Naming ``--batch``.
    """
    if batch is None:
        return
    if isinstance(batch, bool) or not isinstance(batch, int) or batch < 1:
        raise CampaignError(f"--batch {batch!r}: a batch is a whole number of runs, 1 or more")
    if scheduler is None:
        raise CampaignError("--batch: batches are for a Dask cluster (--scheduler); local "
                            "workers fly one run at a time")


class Jobs:
    """The ``(run, seed)`` pairs a campaign still flies, made as they are drawn.

    ``len()`` is their number; iterating draws them in run order, skipping
    the runs in ``finished``. Nothing is held per run, so a campaign of
    :data:`RUNS_MAX` runs starts as quickly, and in as little memory, as one
    of ten.

    Parameters
    ----------
    runs : int
        The campaign's number of runs (indices ``0 .. runs - 1``).
    base : int
        The first run's mission seed; run i flies seed ``base + i``.
    finished : set of int, optional
        The runs already flown (a campaign resumed), left out.
    """

    def __init__(self, runs: int, base: int, finished=frozenset()):
        self.runs, self.base, self.finished = int(runs), int(base), finished

    def __len__(self):
        return self.runs - sum(1 for i in self.finished if 0 <= i < self.runs)

    def __iter__(self):
        return ((i, self.base + i) for i in range(self.runs) if i not in self.finished)


def run_campaign(cfg, runs: int, workers=None, scheduler=None, done=(), on_row=None,
                 on_progress=None, batch=None) -> dict:
    """Fly a Monte Carlo campaign; return its rows and summary.

    Parameters
    ----------
    cfg : Scenario
        The scenario, with its ``[dispersions]``; run i flies seed
        ``cfg.mission.seed + i``.
    runs : int
        Number of runs.
    workers : int, optional
        Local worker processes (default: every core; 1 flies in this process).
    scheduler : str, optional
        Address of a Dask distributed scheduler (``tcp://HOST:PORT``) to fly on
        instead of local processes.
    done : sequence of dict, optional
        Rows already flown (a campaign resumed): their runs are not flown
        again, and they count in the result.
    on_row : callable, optional
        ``on_row(row)`` with each finished row, in this process, the moment it
        arrives and before the next is awaited (a durable record appends it
        there). What it raises ends the campaign.
    on_progress : callable, optional
        ``on_progress(done, total)``: once before the first run with the runs
        of ``done``, then after each finished run.
    batch : int, optional
        With ``scheduler``: runs per Dask task (default: :func:`batch_size`
        chooses from the measured task overhead and mission time). The rows
        do not depend on it.

    Returns
    -------
    dict
        ``rows`` (sorted by run), ``summary`` (:func:`summarize`), ``runs``,
        ``base_seed``, ``flown`` (runs flown by this call) and ``interrupted``
        (True after a Ctrl-C: the runs that had finished were handed to
        ``on_row``, the others are not flown).

    Raises
    ------
    CampaignError
        Seeds past the largest mission seed, a Dask scheduler that cannot be
        reached, or the cluster lost during the campaign (its workers or
        scheduler gone): the rows already handed to ``on_row`` stand, and a
        resumed campaign flies the others.
    """
    check_seeds(cfg, runs)
    if scheduler is not None:
        check_scheduler(scheduler)
    check_batch(batch, scheduler)
    base = int(cfg.mission.seed)
    rows = list(done)
    finished = {r["run"] for r in rows}
    jobs = Jobs(runs, base, finished)
    data = cfg.as_dict()
    flown, interrupted = [], False
    workers = max(1, min(workers or os.cpu_count() or 1, len(jobs) or 1))
    stream, close = (_dask_stream(data, jobs, scheduler, batch=batch) if scheduler else
                     _local_stream(data, jobs, workers))

    def record(new_rows):
        for row in new_rows:
            if on_row is not None:
                on_row(row)
            flown.append(row)
            if on_progress is not None:
                on_progress(len(finished) + len(flown), runs)

    def arriving():
        # The stream's errors only are the cluster's: one raised by on_row (a results file
        # that cannot be written) goes on as it is.
        chunks = iter(stream)
        while True:
            try:
                chunk_rows = next(chunks)
            except StopIteration:
                return
            except Exception as e:
                if scheduler is None or isinstance(e, CampaignError) or not _cluster_lost(e):
                    raise
                first = (str(e).strip().splitlines() or [""])[0].rstrip(":")
                why = f"{type(e).__name__}{': ' + first[:120] if first else ''}"
                raise ClusterLost(f"lost the Dask cluster at {scheduler} ({why}) after "
                                  f"{len(flown)} runs of this session") from None
            yield chunk_rows

    try:
        if on_progress is not None:
            on_progress(len(finished), runs)
        for chunk_rows in arriving():
            record(chunk_rows)
    except KeyboardInterrupt:
        interrupted = True
        salvaged = stream.salvage()  # the runs under way (a second Ctrl-C: at once)
        with interrupts_held():
            record(salvaged)
    except PoolError as e:
        raise CampaignError(f"the local worker processes cannot fly: {e}") from None
    finally:
        if close is not None:
            with interrupts_held():
                close(interrupted)
    rows = sorted(rows + flown, key=lambda r: r["run"])
    return {"runs": runs, "base_seed": base, "rows": rows, "flown": len(flown),
            "interrupted": interrupted, "summary": summarize(rows, runs, base)}


# ---------------------------------------------------------------------------
# Summary
# ---------------------------------------------------------------------------

def _stats(values) -> dict:
    v = np.asarray(values, dtype=float)
    p = np.percentile(v, PERCENTILES)
    return {"n": int(v.size), "mean": float(v.mean()),
            "std": float(v.std(ddof=1)) if v.size > 1 else 0.0,
            **{f"p{q}": float(x) for q, x in zip(PERCENTILES, p, strict=True)},
            "min": float(v.min()), "max": float(v.max())}


def summarize(rows, runs=None, base_seed=None) -> dict:
    """Campaign statistics: counts by status, abort reasons, statistics of each metric.

    Per metric (:data:`METRICS`, over the complete missions): mean, std,
    percentiles 5/50/95, min and max.

    Parameters
    ----------
    rows : sequence of dict
        The campaign's rows.
    runs : int, optional
        The campaign's number of runs (default: the number of rows).
    base_seed : int, optional
        The first run's mission seed, for the table's heading.

    Returns
    -------
    dict
        ``runs``, ``recorded``, ``base_seed``, the count of each status,
        ``abort_reasons``, ``outcomes`` (:func:`outcome_probabilities`) and
        ``metrics``.
    """
    status = Counter(r["status"] for r in rows)
    complete = [r for r in rows if r["status"] == "complete"]
    reasons = Counter(r["abort_reason"] for r in rows if r["status"] != "complete")
    metrics = {}
    for col in METRICS:
        vals = [r[col] for r in complete if r.get(col) is not None]
        if vals:
            metrics[col] = _stats(vals)
    return {"runs": runs if runs is not None else len(rows), "recorded": len(rows),
            "base_seed": base_seed, "complete": status.get("complete", 0),
            "aborted": status.get("aborted", 0), "invalid": status.get("invalid", 0),
            "error": status.get("error", 0), "worker_died": status.get("worker_died", 0),
            "abort_reasons": dict(reasons.most_common()),
            "outcomes": outcome_probabilities(rows), "metrics": metrics}


def outcome_probabilities(rows) -> dict:
    """Share of the runs ending in each outcome: "complete", or the abort's symptom.

    The symptom is the abort reason without the fault and its onset time
    (:func:`allsky.sim.faults.symptom`), so that runs whose faults started at
    drawn times fall in one outcome.

    Parameters
    ----------
    rows : sequence of dict
        The campaign's rows.

    Returns
    -------
    dict
        ``{outcome: {"runs": n, "probability": p}}``, commonest first.
    """
    n = len(rows) or 1
    counts = Counter("complete" if r["status"] == "complete"
                     else symptom(r["abort_reason"]) if r["status"] == "aborted"
                     else r["status"] for r in rows)
    return {k: {"runs": v, "probability": v / n} for k, v in counts.most_common()}
