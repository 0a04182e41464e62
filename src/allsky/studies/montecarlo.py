"""``allsky montecarlo``: campaigns of missions over seeds and dispersions.

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

With an output directory, the campaign is durable: ``campaign.json``
(the manifest: scenario with its dispersions, runs, base seed, version)
and ``runs.csv``, to which each finished row is appended by one write and
fsynced; a crash can tear at most the line being written, which the next
reader drops. ``resume=True`` flies only the runs not yet in the file and
refuses a directory holding a different campaign.
"""

import csv
import io
import json
import math
import os
import signal
import sys
from collections import Counter
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor
from concurrent.futures import wait as wait_futures
from pathlib import Path

import numpy as np

from allsky import __version__
from allsky.config import dispersions
from allsky.config.scenario import ConfigError, scenario_from_dict
from allsky.sequencer.master_sequencer import MODES

MANIFEST = "campaign.json"
RESULTS = "runs.csv"
SUMMARY_TEXT = "summary.txt"
SUMMARY_JSON = "summary.json"
HISTOGRAMS = "histograms.png"
MANIFEST_FORMAT = 1
AXES = ("roll", "pitch", "yaw")
SF_AXES = ("roll", "yaw")
CC_KEYS = ("roll_into_pitch", "roll_into_yaw", "yaw_into_pitch", "yaw_into_roll")
RAD2ARCSEC = 206264.80624709636
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
    """A campaign that cannot start or go on (directory, resume mismatch, cluster)."""


# ---------------------------------------------------------------------------
# One run
# ---------------------------------------------------------------------------

def columns(cfg) -> list:
    """The row's columns for this scenario (its dispersions decide the input columns)."""
    return [*ID_COLUMNS, *dispersions.input_columns(cfg), *RESULT_COLUMNS]


def row_from_summary(run: int, seed: int, inputs: dict, summary: dict) -> dict:
    """A campaign row from a mission summary (:meth:`allsky.sim.mission.Mission.summary`).

    ``inputs`` are the drawn values as flat columns
    (:func:`allsky.config.dispersions.flat_inputs`). Values a mission did not reach
    (modes not flown, no calibration, no final pointing) are None.
    """
    row = {"run": int(run), "seed": int(seed), "status": summary["status"],
           "abort_reason": summary["abort_reason"], **inputs}
    ends = {r["mode"]: r["end_s"] for r in summary["modes"]}
    row.update({f"mode_end_{m}_s": ends.get(m) for m in MODES})
    cal, truth = summary["calibration"], summary["truth"]
    for a in AXES:
        row[f"drift_error_{a}_deg_h"] = (cal["drift_deg_h"][a] - truth["drift_deg_h"][a]
                                         if cal else None)
    for a in SF_AXES:
        row[f"scale_factor_error_{a}_ppm"] = (
            1e6 * (cal["scale_factor"][a] - truth["scale_factor"][a]) if cal else None)
    for k in CC_KEYS:
        row[f"cross_coupling_error_{k}_arcsec"] = (
            RAD2ARCSEC * (cal["cross_coupling"][k] - truth["cross_coupling"][k]) if cal else None)
    row["pointing_error_arcsec"] = summary["target"]["pointing_error_arcsec"]
    row["propellant_kg"] = summary["propellant_kg"]
    row["mission_time_s"] = summary["mission_time_s"]
    return row


def fly_one(cfg, run: int, seed: int) -> dict:
    """Fly run ``run`` (mission seed ``seed``) of a campaign on scenario ``cfg``; its row.

    A draw that breaks a scenario rule gives status ``"invalid"``, an
    unexpected failure status ``"error"``, each with its reason; neither stops
    the campaign.
    """
    from allsky.sim.mission import run_mission

    try:
        run_cfg, drawn = dispersions.disperse(cfg, seed)
    except ConfigError as e:
        drawn = dispersions.draw(cfg, seed)
        return _failed_row(cfg, run, seed, drawn, "invalid", f"drawn scenario rejected: {e}")
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
    """Worker entry point: rows of ``jobs`` (``(run, seed)`` pairs) on scenario ``data``.

    ``data`` is :meth:`Scenario.as_dict` output; the scenario is validated once
    per process and kept while the same data comes back.
    """
    key = json.dumps(data, sort_keys=True)
    if _WORKER.get("key") != key:
        _WORKER.update(key=key, cfg=scenario_from_dict(data))
    return [fly_one(_WORKER["cfg"], run, seed) for run, seed in jobs]


def _init_local_worker(data):
    # Ctrl-C is the parent's to handle: it stops handing out runs and saves
    # what has finished; workers finish their current run quietly.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _WORKER.update(key=json.dumps(data, sort_keys=True), cfg=scenario_from_dict(data))


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
    pool = ProcessPoolExecutor(workers, initializer=_init_local_worker, initargs=(data,))

    def wait_first(fs):
        return wait_futures(fs, return_when=FIRST_COMPLETED).done

    # One run per task: a finished run is handed back at once (the task costs ~0.1 ms).
    stream = _InFlight(lambda c: pool.submit(_fly_local, c), wait_first, _chunks(jobs, 1),
                       IN_FLIGHT_PER_WORKER * workers)
    return stream, lambda: pool.shutdown(wait=True, cancel_futures=True)


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
    return stream, client.close


# ---------------------------------------------------------------------------
# The durable record: manifest and results file
# ---------------------------------------------------------------------------

def _write_atomic(path: Path, text: str):
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w", encoding="utf-8") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def _encode(row, cols) -> bytes:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(
        ["" if row.get(c) is None else repr(row[c]) if isinstance(row[c], float) else row[c]
         for c in cols])
    return buf.getvalue().encode("utf-8")


def _decode(record, cols) -> dict:
    row = {}
    for c, text in zip(cols, record, strict=True):
        if text == "":
            row[c] = None
        elif c in ("run", "seed"):
            row[c] = int(text)
        elif c in TEXT_COLUMNS:
            row[c] = text
        else:
            row[c] = float(text)
    return row


def read_rows(out) -> list:
    """The rows recorded in campaign directory ``out``, sorted by run index.

    A torn last line (a crash in the middle of a write) is left out; a run
    recorded twice counts once.
    """
    path = Path(out) / RESULTS
    data = path.read_bytes()
    complete = data[: data.rfind(b"\n") + 1]
    records = list(csv.reader(io.StringIO(complete.decode("utf-8"))))
    if not records:
        return []
    cols, rows = records[0], {}
    for rec in records[1:]:
        if len(rec) != len(cols):
            raise CampaignError(f"{path}: a line has {len(rec)} fields, the header {len(cols)}")
        row = _decode(rec, cols)
        rows.setdefault(row["run"], row)
    return [rows[k] for k in sorted(rows)]


class _Results:
    """``runs.csv`` opened for appending: one write and one fsync per row."""

    def __init__(self, path: Path, cols):
        self.cols = cols
        if not path.exists():
            _write_atomic(path, ",".join(cols) + "\n")
        else:
            with path.open("rb+") as f:  # drop a line torn by a crash
                data = f.read()
                if not data.endswith(b"\n"):
                    f.truncate(data.rfind(b"\n") + 1)
        self.fd = os.open(path, os.O_WRONLY | os.O_APPEND)

    def write(self, row):
        os.write(self.fd, _encode(row, self.cols))
        os.fsync(self.fd)

    def close(self):
        os.close(self.fd)


def manifest(cfg, runs: int) -> dict:
    """The ``campaign.json`` content of a campaign of ``runs`` runs on scenario ``cfg``."""
    return {"format": MANIFEST_FORMAT, "allsky_version": __version__, "runs": int(runs),
            "base_seed": int(cfg.mission.seed), "dispersions": dispersions.spec(cfg),
            "columns": columns(cfg), "scenario": json.loads(json.dumps(cfg.as_dict()))}


def _first_difference(a, b, path=""):
    if isinstance(a, dict) and isinstance(b, dict):
        for k in list(a) + [k for k in b if k not in a]:
            d = _first_difference(a.get(k), b.get(k), f"{path}.{k}" if path else k)
            if d:
                return d
        return None
    return None if a == b else (path, a, b)


def _open_campaign(cfg, runs, out: Path, resume: bool):
    """Create or reopen the campaign directory; return (runs, rows already recorded)."""
    mpath = out / MANIFEST
    mine = manifest(cfg, runs or 0)
    if not resume:
        if mpath.exists():
            raise CampaignError(f"{out} already holds a campaign ({MANIFEST}); add --resume to "
                                "continue it, or choose another --out")
        if (out / RESULTS).exists():
            raise CampaignError(f"{out} holds {RESULTS} but no {MANIFEST}; choose another --out")
        if runs is None:
            raise CampaignError("--runs N is needed to start a campaign")
        out.mkdir(parents=True, exist_ok=True)
        _write_atomic(mpath, json.dumps(mine, indent=2) + "\n")
        return runs, []
    try:
        theirs = json.loads(mpath.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CampaignError(f"no campaign to resume in {out} (no {MANIFEST})") from None
    except (OSError, ValueError) as e:
        raise CampaignError(f"{mpath}: cannot read the manifest: {e}") from None
    if theirs.get("format") != MANIFEST_FORMAT:
        raise CampaignError(f"{mpath}: not an allsky campaign manifest "
                            f"(format {MANIFEST_FORMAT})")
    if theirs.get("allsky_version") != __version__:
        raise CampaignError(f"{out}: the campaign was made by allsky "
                            f"{theirs.get('allsky_version')}, this is {__version__}; its "
                            "rows would not be comparable: choose another --out")
    diff = _first_difference(mine["scenario"], theirs.get("scenario"))
    if diff:
        key, here, there = diff
        raise CampaignError(f"{out}: the campaign there has a different scenario: {key} = "
                            f"{json.dumps(there)} there, {json.dumps(here)} here; resume with "
                            "the same scenario, --disperse and --set, or choose another --out")
    if runs is not None and runs < theirs["runs"]:
        raise CampaignError(f"{out}: the campaign there has {theirs['runs']} runs; --runs "
                            f"{runs} would shorten it (leave --runs out to finish it)")
    if runs is not None and runs > theirs["runs"]:
        _write_atomic(mpath, json.dumps({**theirs, "runs": runs}, indent=2) + "\n")
    runs = theirs["runs"] if runs is None else runs
    rows = read_rows(out) if (out / RESULTS).exists() else []
    return runs, [r for r in rows if r["run"] < runs]


# ---------------------------------------------------------------------------
# The campaign
# ---------------------------------------------------------------------------

def run_campaign(cfg, runs=None, workers=None, scheduler=None, out=None, resume=False,
                 progress=False) -> dict:
    """Fly a Monte Carlo campaign; return its rows and summary.

    Parameters
    ----------
    cfg : Scenario
        The scenario, with its ``[dispersions]``; run i flies seed
        ``cfg.mission.seed + i``.
    runs : int, optional
        Number of runs (needed unless resuming; when resuming, a larger number
        extends the campaign).
    workers : int, optional
        Local worker processes (default: every core; 1 flies in this process).
    scheduler : str, optional
        Address of a Dask distributed scheduler (``tcp://HOST:PORT``) to fly on
        instead of local processes.
    out : path-like, optional
        Campaign directory (manifest, results, summary, histograms); without it
        nothing is written.
    resume : bool
        Continue the campaign in ``out``, flying only the runs it lacks.
    progress : bool
        Show a progress bar (runs done, rate, time left) on stderr.

    Returns
    -------
    dict
        ``rows`` (sorted by run), ``summary`` (:func:`summarize`), ``runs``,
        ``flown`` (runs flown by this call) and ``interrupted`` (True after a
        Ctrl-C: what finished is recorded, the rest is left for ``resume``).

    Raises
    ------
    CampaignError
        A directory that holds another campaign, a Dask scheduler that cannot
        be reached.
    """
    out = None if out is None else Path(out)
    base = int(cfg.mission.seed)
    if runs is not None and base + runs - 1 >= 2**32:
        raise CampaignError(f"seeds {base}..{base + runs - 1} pass the largest mission.seed "
                            f"({2**32 - 1})")
    if resume and out is None:
        raise CampaignError("--resume needs --out DIR (the campaign to continue)")
    if out is not None:
        runs, rows = _open_campaign(cfg, runs, out, resume)
    elif runs is None:
        raise CampaignError("--runs N is needed to start a campaign")
    else:
        rows = []
    done = {r["run"] for r in rows}
    jobs = [(i, base + i) for i in range(runs) if i not in done]
    data = cfg.as_dict()
    results = _Results(out / RESULTS, columns(cfg)) if out is not None else None
    flown, interrupted = [], False
    stream, close = (_dask_stream(data, jobs, scheduler) if scheduler else
                     _local_stream(data, jobs, workers or os.cpu_count() or 1))
    bar = _progress(runs, len(done), progress and bool(jobs))

    def record(new_rows):
        for row in new_rows:
            if results is not None:
                results.write(row)
            flown.append(row)
            if bar is not None:
                bar.update(1)

    try:
        for chunk_rows in stream:
            record(chunk_rows)
    except KeyboardInterrupt:
        interrupted = True
        record(stream.salvage())
    finally:
        if close is not None:
            close()
        if bar is not None:
            bar.close()
        if results is not None:
            results.close()
    rows = sorted(rows + flown, key=lambda r: r["run"])
    return {"runs": runs, "base_seed": base, "rows": rows, "flown": len(flown),
            "interrupted": interrupted, "summary": summarize(rows, runs, base)}


def _progress(total, initial, show):
    if not show:
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="run", desc="missions", file=sys.stderr,
                dynamic_ncols=True)


# ---------------------------------------------------------------------------
# Summary, table, histograms
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
            "abort_reasons": dict(reasons.most_common()), "metrics": metrics}


def format_summary(s: dict) -> str:
    """The summary as a text table."""
    seeds = ("" if s["base_seed"] is None else
             f", seeds {s['base_seed']}..{s['base_seed'] + s['runs'] - 1}")
    head = f"Monte Carlo campaign: {s['recorded']} of {s['runs']} runs recorded{seeds}"
    counts = ", ".join(f"{s[k]} {k}" for k in ("complete", "aborted", "invalid", "error")
                       if s[k] or k == "complete")
    lines = [head, f"  {counts}"]
    if s["metrics"]:
        lines += ["", f"Over the {s['complete']} complete missions",
                  f"  {'quantity':<36}{'mean':>11}{'std':>11}{'p5':>11}{'p50':>11}{'p95':>11}"]
        for col, st in s["metrics"].items():
            cells = "".join(f"{st[k]:>11.4g}" for k in ("mean", "std", "p5", "p50", "p95"))
            lines.append(f"  {METRICS[col]:<36}{cells}")
    if s["abort_reasons"]:
        lines += ["", "Missions not complete (count, reason)"]
        lines += [f"  {n:>5}  {reason}" for reason, n in s["abort_reasons"].items()]
    return "\n".join(lines)


def plot_histograms(rows, path) -> Path:
    """PNG of histograms: pointing error, calibration errors, propellant (complete runs)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in rows if r["status"] == "complete"]
    panels = [
        ("final pointing error [arcsec]", {"": "pointing_error_arcsec"}),
        ("propellant used [kg]", {"": "propellant_kg"}),
        ("drift error [deg/h]", {a: f"drift_error_{a}_deg_h" for a in AXES}),
        ("scale-factor error [ppm]", {a: f"scale_factor_error_{a}_ppm" for a in SF_AXES}),
        ("cross-coupling error [arcsec]", {k.replace("_into_", "→"):
                                           f"cross_coupling_error_{k}_arcsec" for k in CC_KEYS}),
        ("mission time [s]", {"": "mission_time_s"}),
    ]
    fig, axes = plt.subplots(2, 3, figsize=(12, 6.5))
    n_bins = max(10, min(50, int(math.sqrt(max(len(ok), 1))) * 2))
    for ax, (title, series) in zip(axes.flat, panels, strict=True):
        values = {label: [r[col] for r in ok if r.get(col) is not None]
                  for label, col in series.items()}
        everything = [x for v in values.values() for x in v]
        if not everything:
            continue
        # Bins shared by the overlays, over the central 99 % so that a rare outlier does not
        # squash the rest; the runs beyond are counted on the panel.
        lo, hi = np.percentile(everything, [0.5, 99.5]) if len(everything) >= 200 else (
            min(everything), max(everything))
        bins = np.histogram_bin_edges(everything, bins=n_bins, range=(lo, hi) if hi > lo
                                      else None)
        for label, v in values.items():
            ax.hist(v, bins=bins, alpha=0.55 if len(series) > 1 else 0.9,
                    label=label or None, histtype="stepfilled")
        beyond = sum(x < bins[0] or x > bins[-1] for x in everything)
        if beyond:
            ax.text(0.98, 0.02 if len(series) > 1 else 0.95, f"{beyond} beyond the axis",
                    transform=ax.transAxes, ha="right", va="bottom" if len(series) > 1
                    else "top", fontsize=8)
        ax.set_xlabel(title)
        ax.set_ylabel("missions")
        ax.grid(True, alpha=0.3)
        if len(series) > 1:
            ax.legend(fontsize=8)
    fig.suptitle(f"Monte Carlo campaign: {len(ok)} complete missions of {len(rows)}")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


# ---------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------

def run_from_cli(cfg, args) -> int:
    """``allsky montecarlo``: fly the campaign, print and save the summary."""
    try:
        result = run_campaign(cfg, runs=args.runs, workers=args.workers,
                              scheduler=args.scheduler, out=args.out, resume=args.resume,
                              progress=not args.quiet)
    except CampaignError as e:
        print(f"allsky: error: {e}", file=sys.stderr)
        return 2
    s = result["summary"]
    text = format_summary(s)
    to_stdout_json = args.json == "-"
    if not to_stdout_json:
        print(text)
    if args.json:
        body = json.dumps(s, indent=2) + "\n"
        if to_stdout_json:
            sys.stdout.write(body)
        else:
            Path(args.json).write_text(body)
    if args.out:
        out = Path(args.out)
        _write_atomic(out / SUMMARY_TEXT, text + "\n")
        _write_atomic(out / SUMMARY_JSON, json.dumps(s, indent=2) + "\n")
        if result["rows"]:
            plot_histograms(result["rows"], out / HISTOGRAMS)
        if not to_stdout_json:
            print(f"\nresults: {out / RESULTS}; summary: {out / SUMMARY_TEXT}; "
                  f"histograms: {out / HISTOGRAMS}")
    if result["interrupted"]:
        where = (f"; continue with --resume --out {args.out}" if args.out else "")
        print(f"allsky: interrupted after {s['recorded']} of {s['runs']} runs{where}",
              file=sys.stderr)
        return 130
    return 0
