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
import json
import math
import os
import signal
import sys
import time
from collections import Counter
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor
from concurrent.futures import wait as wait_futures

import numpy as np

from allsky.config import ConfigError, dispersions, scenario_from_dict
from allsky.sequencer.master_sequencer import MODES
from allsky.sim import results
from allsky.sim.faults import symptom
from allsky.sim.results import calibration_errors

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
#: Dask chunks: runs per task at most, and tasks in flight per worker thread.
DASK_CHUNK_MAX = 8
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
    """The row's columns for this scenario (its dispersions decide the input columns)."""
    return [*ID_COLUMNS, *dispersions.input_columns(cfg), *RESULT_COLUMNS]


def row_from_summary(run: int, seed: int, inputs: dict, summary: dict) -> dict:
    """A campaign row from a mission summary (:meth:`Mission.summary`).

    ``inputs`` are the drawn values as flat columns
    (:func:`allsky.config.dispersions.flat_inputs`). Values a mission did not reach
    (modes not flown, no calibration, no final pointing) are None.
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

    ``data`` is :meth:`Scenario.as_dict` output; the scenario is validated once
    per process and kept while the same data comes back.
    """
    key = json.dumps(data, sort_keys=True)
    if _WORKER.get("key") != key:
        _WORKER.update(key=key, cfg=scenario_from_dict(data))
        _compile_once_per_machine()
    return [fly_one(_WORKER["cfg"], run, seed) for run, seed in jobs]


def _compile_once_per_machine():
    # Workers starting together on a fresh machine would each compile the frame loop
    # (about 16 s of CPU each); under the machine's compile lock one compiles and the
    # others load its cache (allsky.sim.warm_up).
    from allsky.sim import warm_up

    if warm_up.needs_compiling():
        warm_up.warm_up()


#: [s] How often a worker checks that its parent is still there (where the
#: kernel cannot be asked to signal it, or was asked too late).
PARENT_CHECK_S = 0.5
#: prctl(2) option: the signal the kernel sends this process when its parent dies.
_PR_SET_PDEATHSIG = 1


def worker_process_setup(parent_pid: int):
    """Make a worker process quiet on Ctrl-C and end it when its parent goes.

    Ctrl-C (sent to the whole terminal process group) and SIGTERM are the
    parent's to handle: it stops handing out runs and saves what has
    finished, so the worker ignores SIGINT and takes SIGTERM's default
    action (a forked worker would otherwise inherit the parent's handler).
    If the parent is killed (even by SIGKILL, which it cannot handle), the
    worker must not fly on for minutes: on Linux the kernel sends it
    SIGTERM (``prctl(PR_SET_PDEATHSIG)``); everywhere a daemon thread checks
    every :data:`PARENT_CHECK_S` that the parent is still ``parent_pid``.
    """
    import threading

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
        except (OSError, AttributeError):  # no prctl: the thread below suffices
            pass

    def watch_parent():
        while os.getppid() == parent_pid:
            time.sleep(PARENT_CHECK_S)
        os.kill(os.getpid(), signal.SIGTERM)

    if os.getppid() != parent_pid:  # the parent went before the kernel was asked
        os.kill(os.getpid(), signal.SIGTERM)
    threading.Thread(target=watch_parent, name="allsky-parent-watch", daemon=True).start()


def _init_local_worker(data, parent_pid):
    worker_process_setup(parent_pid)
    _WORKER.update(key=json.dumps(data, sort_keys=True), cfg=scenario_from_dict(data))
    _compile_once_per_machine()


def stop_pool(pool, interrupted):
    """Shut a process pool down; after an interruption, end its workers at once.

    The runs under way when the campaign is interrupted are not waited for
    (they are flown again on ``--resume``): the workers are terminated, so
    that Ctrl-C takes effect now and a second Ctrl-C finds nothing to wait on.
    """
    if interrupted:
        for proc in list((getattr(pool, "_processes", None) or {}).values()):
            proc.terminate()
    pool.shutdown(wait=True, cancel_futures=True)


@contextlib.contextmanager
def interrupts_held():
    """Ignore Ctrl-C and SIGTERM while an interrupted campaign tidies up.

    The tidying (rows that finished, workers ended) is short and bounded; a
    second Ctrl-C in the middle of it would leave workers behind or a row
    unsaved. Outside the main thread, where signals cannot be set, nothing
    changes.
    """
    try:
        old = {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT,
                                                                   signal.SIGTERM)}
    except ValueError:
        yield
        return
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


def ordered_rows(fly, jobs, workers, on_progress=None, fly_here=None):
    """``fly`` over ``jobs`` in order on ``workers`` processes; Ctrl-C stops cleanly.

    One worker flies in this process (with ``fly_here`` when given, e.g. a
    version that reports its own progress). ``on_progress(done, total)``
    follows each row. Returns ``(rows, interrupted)``: a Ctrl-C after the
    first row keeps the rows finished and ends the workers at once; before
    it, the interruption propagates.
    """
    workers = max(1, min(int(workers), len(jobs)))  # no idle processes
    pool = None
    if workers == 1:
        it = map(fly_here or fly, jobs)
    else:
        pool = ProcessPoolExecutor(workers, initializer=worker_process_setup,
                                   initargs=(os.getpid(),))
        it = pool.map(fly, jobs)
    rows, interrupted = [], False
    try:
        for row in it:
            rows.append(row)
            if on_progress is not None:
                on_progress(len(rows), len(jobs))
    except KeyboardInterrupt:
        if not rows:
            raise
        interrupted = True
    finally:
        if pool is not None:
            with interrupts_held():
                stop_pool(pool, interrupted or len(rows) < len(jobs))
    return rows, interrupted


def _fly_local(jobs):
    return [fly_one(_WORKER["cfg"], run, seed) for run, seed in jobs]


# ---------------------------------------------------------------------------
# Executors: runs in flight, results as they come
# ---------------------------------------------------------------------------

class _InFlight:
    """Chunks of runs submitted to an executor, at most ``window`` at a time.

    Iterating yields each finished chunk's rows; :meth:`salvage` (after an
    interruption) cancels what has not started and returns the rows of the
    chunks that finished but were not yet yielded.
    """

    def __init__(self, submit, wait_first, chunks, window):
        self.submit, self.wait_first = submit, wait_first
        self.chunks, self.window = iter(chunks), window
        self.pending = set()

    def _fill(self):
        while len(self.pending) < self.window:
            chunk = next(self.chunks, None)
            if chunk is None:
                return
            self.pending.add(self.submit(chunk))

    def __iter__(self):
        self._fill()
        while self.pending:
            done = self.wait_first(self.pending)
            for f in done:
                rows = f.result()
                self.pending.discard(f)
                yield rows
            self._fill()

    def salvage(self) -> list:
        for f in self.pending:
            f.cancel()
        rows = []
        for f in self.pending:
            if f.done() and not f.cancelled():
                try:
                    rows += f.result()
                except Exception:  # noqa: BLE001, S112 - a failed chunk has nothing to save
                    continue
        self.pending = set()
        return rows


def _chunks(jobs, size):
    for i in range(0, len(jobs), size):
        yield jobs[i:i + size]


def _local_stream(data, jobs, workers):
    """Rows on ``workers`` local processes (in this process when 1)."""
    if workers == 1 or not jobs:
        cfg = scenario_from_dict(data)

        class _Serial:
            salvage = staticmethod(list)

            def __iter__(self):
                for run, seed in jobs:
                    yield [fly_one(cfg, run, seed)]
        return _Serial(), None
    pool = ProcessPoolExecutor(workers, initializer=_init_local_worker,
                               initargs=(data, os.getpid()))

    def wait_first(fs):
        return wait_futures(fs, return_when=FIRST_COMPLETED).done

    # One run per task: a finished run is handed back at once (the task costs ~0.1 ms).
    stream = _InFlight(lambda c: pool.submit(_fly_local, c), wait_first, _chunks(jobs, 1),
                       IN_FLIGHT_PER_WORKER * workers)
    return stream, lambda interrupted=False: stop_pool(pool, interrupted)


def _dask_stream(data, jobs, address):
    """Rows on the Dask distributed cluster whose scheduler is at ``address``."""
    try:
        from distributed import Client
        from distributed import wait as dask_wait
    except ImportError:
        raise CampaignError("--scheduler needs Dask distributed: pip install "
                            "'dask[distributed]'") from None
    try:
        client = Client(address, timeout=DASK_CONNECT_TIMEOUT_S)
    except (OSError, TimeoutError, ValueError) as e:
        raise CampaignError(f"cannot reach the Dask scheduler at {address}: {e}") from None
    threads = max(1, sum(client.nthreads().values()))
    size = max(1, min(DASK_CHUNK_MAX, math.ceil(len(jobs) / (16 * threads))))
    # Scatter the scenario as the single element of a list: a dict would be taken
    # as {key: value} and each section would become a cluster-global key
    # ("control", "gyro", ...) that another campaign on the same cluster could
    # overwrite or read. hash=False gives this campaign a key of its own.
    [data_future] = client.scatter([data], broadcast=True, hash=False)

    def submit(chunk):
        return client.submit(fly_runs, data_future, chunk, pure=False)

    def wait_first(fs):
        return dask_wait(list(fs), return_when="FIRST_COMPLETED").done

    stream = _InFlight(submit, wait_first, _chunks(jobs, size), IN_FLIGHT_PER_WORKER * threads)
    return stream, lambda interrupted=False: client.close()


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
    """Refuse a campaign whose seeds ``cfg.mission.seed + i`` pass the largest seed.

    Raises
    ------
    CampaignError
        Naming the seed range.
    """
    base = int(cfg.mission.seed)
    if base + runs - 1 >= 2**32:
        raise CampaignError(f"seeds {base}..{base + runs - 1} pass the largest mission.seed "
                            f"({2**32 - 1})")


def run_campaign(cfg, runs: int, workers=None, scheduler=None, done=(), on_row=None,
                 on_progress=None) -> dict:
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
    base = int(cfg.mission.seed)
    rows = list(done)
    finished = {r["run"] for r in rows}
    jobs = [(i, base + i) for i in range(runs) if i not in finished]
    data = cfg.as_dict()
    flown, interrupted = [], False
    workers = max(1, min(workers or os.cpu_count() or 1, len(jobs) or 1))
    stream, close = (_dask_stream(data, jobs, scheduler) if scheduler else
                     _local_stream(data, jobs, workers))

    def record(new_rows):
        for row in new_rows:
            if on_row is not None:
                on_row(row)
            flown.append(row)
            if on_progress is not None:
                on_progress(len(finished) + len(flown), runs)

    try:
        if on_progress is not None:
            on_progress(len(finished), runs)
        for chunk_rows in stream:
            record(chunk_rows)
    except KeyboardInterrupt:
        interrupted = True
        with interrupts_held():
            record(stream.salvage())
    except Exception as e:
        if scheduler is None or isinstance(e, CampaignError) or not _cluster_lost(e):
            raise
        raise ClusterLost(f"lost the Dask cluster at {scheduler} ({type(e).__name__}"
                            f"{': ' + str(e) if str(e) else ''}) after {len(flown)} runs of "
                            "this session") from None
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
    """Campaign statistics: counts by status, abort reasons, and per metric
    (:data:`METRICS`, over the complete missions) mean, std, percentiles 5/50/95."""
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
            "error": status.get("error", 0),
            "abort_reasons": dict(reasons.most_common()),
            "outcomes": outcome_probabilities(rows), "metrics": metrics}


def outcome_probabilities(rows) -> dict:
    """Share of the runs ending in each outcome: "complete", or the abort's symptom.

    The symptom is the abort reason without the fault and its onset time
    (:func:`allsky.sim.faults.symptom`), so that runs whose faults started at
    drawn times fall in one outcome.
    """
    n = len(rows) or 1
    counts = Counter("complete" if r["status"] == "complete"
                     else symptom(r["abort_reason"]) if r["status"] == "aborted"
                     else r["status"] for r in rows)
    return {k: {"runs": v, "probability": v / n} for k, v in counts.most_common()}
