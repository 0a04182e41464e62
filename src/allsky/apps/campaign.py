"""``allsky montecarlo``: a campaign's durable record, its table and histograms.

The missions are flown by :func:`allsky.studies.montecarlo.run_campaign`;
this module keeps the record. With an output directory the campaign is
durable: ``campaign.json`` (the manifest: scenario with its dispersions,
runs, base seed, version) and ``runs.csv``, to which each finished row is
appended by one write and fsynced the moment it arrives; a crash can tear
at most the line being written, which the next reader drops.
``resume=True`` flies only the runs not yet in the file and refuses a
directory holding a different campaign, or a manifest or results file that
no campaign wrote (:func:`read_manifest`, :func:`read_results`), in one
line naming the file and the line. At the end, ``summary.txt``,
``summary.json`` and ``histograms.png`` join them.
"""

import csv
import io
import json
import math
import os
import sys
from collections import Counter
from pathlib import Path

import numpy as np

from allsky import __version__
from allsky.apps.output import write_atomic
from allsky.config import ConfigError, dispersions
from allsky.config.rules import SEED_MAX
from allsky.config.toml_io import os_reason, read_bounded
from allsky.studies import montecarlo
from allsky.studies.montecarlo import (
    AXES,
    CC_KEYS,
    METRICS,
    SF_AXES,
    TEXT_COLUMNS,
    CampaignError,
    columns,
)

MANIFEST = "campaign.json"
RESULTS = "runs.csv"
SUMMARY_TEXT = "summary.txt"
SUMMARY_JSON = "summary.json"
HISTOGRAMS = "histograms.png"
#: Every file a campaign directory holds.
FILES = (MANIFEST, RESULTS, SUMMARY_TEXT, SUMMARY_JSON, HISTOGRAMS)
MANIFEST_FORMAT = 1
#: [bytes] Largest manifest read (the resolved scenario and dispersions: some kB).
MANIFEST_MAX_BYTES = 16 * 2**20
#: [bytes] Most a results line may take (inputs drawn, results, an abort reason), and so
#: the largest results file of a campaign of N runs, (N + 1) lines of it.
ROW_MAX_BYTES = 64 * 2**10
#: [bytes] Largest results file read without its manifest's number of runs.
RESULTS_MAX_BYTES = 4 * 2**30


# ---------------------------------------------------------------------------
# The durable record: manifest and results file
# ---------------------------------------------------------------------------

def _encode(row, cols) -> bytes:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(
        ["" if row.get(c) is None else repr(row[c]) if isinstance(row[c], float) else row[c]
         for c in cols])
    return buf.getvalue().encode("utf-8")


#: Statuses a campaign row can have (:func:`allsky.studies.montecarlo.fly_one`).
STATUSES = ("complete", "aborted", "invalid", "error", "worker_died")


def _decode(record, cols) -> dict:
    """A row from its CSV cells; ValueError naming the column of a cell that is not one."""
    row = {}
    for c, text in zip(cols, record, strict=True):
        try:
            if text == "":
                row[c] = None
            elif c in ("run", "seed"):
                row[c] = int(text)
            elif c in TEXT_COLUMNS:
                row[c] = text
            else:
                row[c] = float(text)
        except ValueError:
            kind = "an integer" if c in ("run", "seed") else "a number"
            shown = text if len(text) <= 40 else text[:40] + "..."
            raise ValueError(f"column {c!r}: {shown!r} is not {kind}") from None
    return row


def read_rows(out) -> list:
    """The rows recorded in campaign directory ``out``, sorted by run index.

    A torn last line (a crash in the middle of a write) is left out; a run
    recorded twice, line for line, counts once.

    Raises
    ------
    CampaignError
        A file that is not a results table of its own header (see
        :func:`read_results`).
    """
    return read_results(Path(out) / RESULTS)[0]


def read_results(path, cols=None, runs=None, base_seed=None):
    """The rows of results file ``path``, checked, and the exact duplicates dropped.

    Parameters
    ----------
    path : path-like
        ``runs.csv`` of a campaign directory.
    cols : list of str, optional
        The columns the header must name, in order (default: the file's own header).
    runs, base_seed : int, optional
        With them, each row's run must be in ``0..runs - 1`` and its seed ``base_seed + run``.

    Returns
    -------
    (list of dict, int)
        The rows sorted by run, and the number of lines that repeated another line.

    Raises
    ------
    CampaignError
        One line naming the file and, where it applies, the line and column: a
        file that cannot be read, that is empty or not UTF-8, a header other than
        ``cols``, a line of the wrong number of fields, a cell that is not a
        number, an unknown status, a run outside the campaign or of another
        seed, two different lines for one run.
    """
    path = Path(path)
    limit = RESULTS_MAX_BYTES if runs is None else (runs + 1) * ROW_MAX_BYTES
    try:
        data = read_bounded(path, limit, "results file")
    except OSError as e:
        raise CampaignError(f"{path}: cannot read it: {os_reason(e)}") from None
    except ConfigError as e:
        raise CampaignError(str(e)) from None
    complete = data[: data.rfind(b"\n") + 1]  # a torn last line is left out
    if not complete.strip():
        raise CampaignError(f"{path}: empty, no header line; move it away to fly every run "
                            "again")
    try:
        text = complete.decode("utf-8")
    except UnicodeDecodeError as e:
        line = complete.count(b"\n", 0, e.start) + 1
        raise CampaignError(f"{path}: line {line}: not UTF-8 text (byte "
                            f"0x{complete[e.start]:02x})") from None
    reader = csv.reader(io.StringIO(text, newline=""))
    try:
        records = [(reader.line_num, rec) for rec in reader]
    except csv.Error as e:
        raise CampaignError(f"{path}: line {reader.line_num}: not CSV ({e})") from None
    head = records[0][1]
    if cols is not None and head != list(cols):
        diff = next((i for i, (a, b) in enumerate(zip(head, cols, strict=False)) if a != b),
                    min(len(head), len(cols)))
        found = repr(head[diff]) if diff < len(head) else "nothing"
        wanted = repr(cols[diff]) if diff < len(cols) else "nothing"
        raise CampaignError(f"{path}: line 1, the header: column {diff + 1} is {found}, this "
                            f"campaign's is {wanted}")
    by_run, duplicates = {}, 0
    for line, rec in records[1:]:
        where = f"{path}: line {line}"
        if len(rec) != len(head):
            raise CampaignError(f"{where} has {len(rec)} fields, the header {len(head)}")
        try:
            row = _decode(rec, head)
        except ValueError as e:
            raise CampaignError(f"{where}, {e}") from None
        run, seed = row.get("run"), row.get("seed")
        if run is None or seed is None:
            raise CampaignError(f"{where}: no run index or seed")
        if row.get("status") not in STATUSES:
            raise CampaignError(f"{where}: status {row.get('status')!r} is not one of "
                                f"{', '.join(STATUSES)}")
        if runs is not None and not 0 <= run < runs:
            raise CampaignError(f"{where}: run {run} of a campaign of {runs} runs "
                                f"(0..{runs - 1})")
        if base_seed is not None and seed != base_seed + run:
            raise CampaignError(f"{where}: run {run} with seed {seed}; the campaign flies "
                                f"seed {base_seed + run}")
        if run in by_run:
            first_line, first = by_run[run]
            if first != rec:
                raise CampaignError(f"{path}: lines {first_line} and {line} record run {run} "
                                    "differently; keep the right one")
            duplicates += 1
            continue
        by_run[run] = (line, rec)
    return [_decode(by_run[k][1], head) for k in sorted(by_run)], duplicates


def _drop_torn_line(path: Path):
    """Cut a last line that a crash left without its newline (read from the end only)."""
    with path.open("rb+") as f:
        end = f.seek(0, os.SEEK_END)
        pos = end
        while pos > 0:
            start = max(0, pos - 65536)
            f.seek(start)
            block = f.read(pos - start)
            if pos == end and block.endswith(b"\n"):
                return
            cut = block.rfind(b"\n")
            if cut >= 0:
                f.truncate(start + cut + 1)
                return
            pos = start
        f.truncate(0)


class ResultsFile:
    """``runs.csv`` opened for appending: one write and one fsync per row.

    A new file gets the header; an existing one loses a last line torn by a
    crash, so that the next row starts on a line of its own.

    Parameters
    ----------
    path : Path
        The results file.
    cols : list of str
        The campaign's columns (:func:`allsky.studies.montecarlo.columns`),
        the header of a new file and the order of each line's cells.
    """

    def __init__(self, path: Path, cols):
        self.cols = cols
        if not path.exists():
            write_atomic(path, ",".join(cols) + "\n")
        else:
            _drop_torn_line(path)
        self.fd = os.open(path, os.O_WRONLY | os.O_APPEND)

    def write(self, row):
        """Append ``row`` as one line and fsync it."""
        os.write(self.fd, _encode(row, self.cols))
        os.fsync(self.fd)

    def close(self):
        """Close the results file (every row is already on disk)."""
        os.close(self.fd)


def manifest(cfg, runs: int) -> dict:
    """The ``campaign.json`` content of a campaign of ``runs`` runs on ``cfg``."""
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


def open_campaign(cfg, runs, out: Path, resume: bool, on_note=None):
    """Create or reopen the campaign directory; return (runs, rows already recorded).

    Resuming checks the manifest (:func:`read_manifest`) and the results
    (:func:`read_results`).

    Parameters
    ----------
    cfg : Scenario
        The campaign's scenario, with its dispersions.
    runs : int or None
        The number of runs (None when resuming: the manifest's; a larger
        number extends the campaign).
    out : Path
        The campaign directory.
    resume : bool
        Continue the campaign there (else start one: the directory must not
        hold one).
    on_note : callable, optional
        ``on_note(text)`` hears of exact duplicate lines left out.

    Returns
    -------
    (int, list of dict)
        The campaign's number of runs and the rows already recorded.

    Raises
    ------
    CampaignError
        A directory that holds another campaign, or a damaged record of one.
    """
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
        write_atomic(mpath, json.dumps(mine, indent=2) + "\n")
        return runs, []
    try:
        theirs = read_manifest(out)
    except CampaignError as e:
        raise CampaignError(f"--resume: {e}") from None
    diff = _first_difference(mine["scenario"], theirs.get("scenario"))
    if diff:
        key, here, there = diff
        raise CampaignError(f"{out}: the campaign there has a different scenario: {key} = "
                            f"{json.dumps(there)} there, {json.dumps(here)} here; resume with "
                            "the same scenario, --disperse and --set, or choose another --out")
    if theirs.get("columns") != mine["columns"]:
        raise CampaignError(f"{mpath}: columns differ from this campaign's; choose another --out")
    recorded = theirs["runs"]
    if runs is not None and runs < recorded:
        raise CampaignError(f"{out}: the campaign there has {recorded} runs; --runs "
                            f"{runs} would shorten it (leave --runs out to finish it)")
    rpath = out / RESULTS
    try:
        rows, duplicates = (read_results(rpath, mine["columns"], recorded, mine["base_seed"])
                            if rpath.exists() else ([], 0))
    except CampaignError as e:
        raise CampaignError(f"--resume: {e}") from None
    if duplicates and on_note is not None:
        on_note(f"{rpath}: {duplicates} line{'s' if duplicates > 1 else ''} repeating another "
                "line for the same run left out")
    if runs is not None and runs > recorded:
        write_atomic(mpath, json.dumps({**theirs, "runs": runs}, indent=2) + "\n")
    return (recorded if runs is None else runs), rows


def read_manifest(out) -> dict:
    """The manifest of campaign directory ``out``, checked.

    Raises
    ------
    CampaignError
        One line naming the file: missing, unreadable, not UTF-8 or not JSON,
        not an object of format :data:`MANIFEST_FORMAT`, made by another
        version, or ``runs`` that is not a whole number of runs >= 1 whose
        seeds fit below the largest mission seed.
    """
    out = Path(out)
    mpath = out / MANIFEST
    try:
        data = read_bounded(mpath, MANIFEST_MAX_BYTES, "campaign manifest")
    except ConfigError as e:
        raise CampaignError(str(e)) from None
    except FileNotFoundError:
        raise CampaignError(f"no campaign to resume in {out} (no {MANIFEST})") from None
    except OSError as e:
        raise CampaignError(f"{mpath}: cannot read the manifest: {os_reason(e)}") from None
    try:
        theirs = json.loads(data.decode("utf-8"))
    except UnicodeDecodeError as e:
        raise CampaignError(f"{mpath}: not UTF-8 text (byte 0x{data[e.start]:02x} at offset "
                            f"{e.start})") from None
    except (ValueError, RecursionError) as e:
        raise CampaignError(f"{mpath}: not JSON ({' '.join(str(e).split())[:120]})") from None
    if not isinstance(theirs, dict) or theirs.get("format") != MANIFEST_FORMAT:
        raise CampaignError(f"{mpath}: not an allsky campaign manifest "
                            f"(format {MANIFEST_FORMAT})")
    if theirs.get("allsky_version") != __version__:
        raise CampaignError(f"{out}: the campaign was made by allsky "
                            f"{theirs.get('allsky_version')}, this is {__version__}; its "
                            "rows would not be comparable: choose another --out")
    runs, base = theirs.get("runs"), theirs.get("base_seed")
    if type(base) is not int or not 0 <= base <= SEED_MAX:
        raise CampaignError(f"{mpath}: base_seed = {_shown(base)} is not a mission seed "
                            f"(0..{SEED_MAX})")
    if type(runs) is not int or not 1 <= runs <= SEED_MAX + 1 - base:
        raise CampaignError(f"{mpath}: runs = {_shown(runs)} is not a number of runs "
                            f"(1..{SEED_MAX + 1 - base} from base_seed {base})")
    return theirs


def _shown(v, limit=60) -> str:
    text = json.dumps(v)
    return text if len(text) <= limit else text[:limit - 3] + "..."


# ---------------------------------------------------------------------------
# The campaign, recorded as it flies
# ---------------------------------------------------------------------------

class _ProgressBar:
    """An ``on_progress(done, total)`` that draws a bar (tqdm, stderr) once there is work."""

    def __init__(self, show):
        self.show, self.bar = show, None

    def __call__(self, done, total):
        if self.bar is None:
            if not self.show or done >= total:  # nothing left to fly: no bar
                return
            from tqdm import tqdm

            self.bar = tqdm(total=total, initial=done, unit="run", desc="missions",
                            file=sys.stderr, dynamic_ncols=True)
        else:
            self.bar.update(done - self.bar.n)

    def close(self):
        if self.bar is not None:
            self.bar.close()


def run_recorded(cfg, runs=None, workers=None, scheduler=None, out=None, resume=False,
                 progress=False, on_note=None, on_progress=None, batch=None) -> dict:
    """Fly a Monte Carlo campaign, recording each run in ``out`` as it finishes.

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
        Campaign directory (manifest and results); without it nothing is
        written.
    resume : bool
        Continue the campaign in ``out``, flying only the runs it lacks.
    progress : bool
        Show a progress bar (runs done, rate, time left) on stderr.
    on_note : callable, optional
        ``on_note(text)`` with a line worth telling that is not an error (exact
        duplicate lines left out of the results when resuming).
    on_progress : callable, optional
        ``on_progress(done, total)`` in place of the ``progress`` bar (a
        notebook's, :func:`allsky.montecarlo`), as
        :func:`~allsky.studies.montecarlo.run_campaign` calls it.
    batch : int, optional
        With ``scheduler``: runs per Dask task (default: chosen by
        :func:`allsky.studies.montecarlo.batch_size`). The rows, and so a
        resumed campaign, do not depend on it.

    Returns
    -------
    dict
        As :func:`allsky.studies.montecarlo.run_campaign`, with the rows
        recorded before a resume among ``rows``.

    Raises
    ------
    CampaignError
        A directory that holds another campaign or a damaged record of one,
        seeds past the largest mission seed, a Dask scheduler that cannot be
        reached.
    """
    out = None if out is None else Path(out)
    # Checked before the directory is made, so that a refused campaign leaves nothing.
    if runs is not None:
        montecarlo.check_seeds(cfg, runs)
    if resume and out is None:
        raise CampaignError("--resume needs --out DIR (the campaign to continue)")
    if scheduler is not None:
        montecarlo.check_scheduler(scheduler)
    montecarlo.check_batch(batch, scheduler)
    if out is None and runs is None:
        raise CampaignError("--runs N is needed to start a campaign")
    made = _Made(out)  # before the lock makes the directory
    lock = _DirectoryLock(out) if out is not None else None
    results, rows, failed = None, [0], True
    bar = _ProgressBar(progress) if on_progress is None else None
    try:
        if out is not None:
            runs, done = open_campaign(cfg, runs, out, resume, on_note)
            results = ResultsFile(out / RESULTS, columns(cfg))
        else:
            done = []

        def on_row(row):
            results.write(row)
            rows[0] += 1

        result = montecarlo.run_campaign(cfg, runs, workers=workers, scheduler=scheduler,
                                         done=done, on_row=None if results is None else on_row,
                                         on_progress=on_progress if bar is None else bar,
                                         batch=batch)
        failed = False
        return result
    except KeyboardInterrupt:
        failed = False  # an interrupted start is a campaign to --resume
        raise
    except montecarlo.ClusterLost as e:
        saved = (f"the runs finished are saved in {out / RESULTS}; --resume --out {out} "
                 "continues the campaign" if out is not None and (rows[0] or done) else
                 "no run was saved; start again when the cluster is back" if out is not None
                 else "nothing was saved (no --out DIR)")
        raise montecarlo.ClusterLost(f"{e}; {saved}") from None
    finally:
        if bar is not None:
            bar.close()
        if results is not None:
            results.close()
        if failed and out is not None and not resume and rows[0] == 0:
            made.undo()  # a start that failed (no cluster, no worker) leaves nothing behind
        if lock is not None:
            lock.release()


class _Made:
    """The files and directory a new campaign made, to take back if it never flew a run."""

    def __init__(self, out):
        self.out = None if out is None else Path(out)
        self.dir_existed = self.out is None or self.out.exists()
        self.existed = set() if self.out is None else {
            n for n in (MANIFEST, RESULTS) if (self.out / n).exists()}

    def undo(self):
        for name in (MANIFEST, RESULTS):
            if name not in self.existed:
                (self.out / name).unlink(missing_ok=True)
        if not self.dir_existed:
            try:
                self.out.rmdir()
            except OSError:  # something else was put there meanwhile: leave it
                pass


class _DirectoryLock:
    """An exclusive ``flock`` on a campaign directory while a campaign flies in it.

    A second ``allsky montecarlo`` on the same directory (two ``--resume`` at
    once would both fly the missing runs and record them twice) is refused
    in one line. The lock goes with the process, even one that is killed.
    Where the platform has no ``fcntl``, nothing is locked.
    """

    def __init__(self, out):
        out = Path(out)
        self.fd = None
        try:
            import fcntl
        except ImportError:
            return
        try:
            out.mkdir(parents=True, exist_ok=True)
            self.fd = os.open(out, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
        except OSError as e:
            raise CampaignError(f"--out {out}: cannot use the directory: {os_reason(e)}"
                                ) from None
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self.fd)
            self.fd = None
            raise CampaignError(f"{out}: another allsky montecarlo is flying a campaign "
                                "there now (the directory is locked); wait for it to end, "
                                "or choose another --out") from None

    def release(self):
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None


# ---------------------------------------------------------------------------
# Table, histograms, command line
# ---------------------------------------------------------------------------

def format_summary(s: dict, outcomes=False) -> str:
    """The summary (:func:`allsky.studies.montecarlo.summarize`) as a text table.

    Parameters
    ----------
    s : dict
        The campaign's summary.
    outcomes : bool
        List the probability of each outcome (complete, or an abort's symptom
        without the fault's onset time) in place of the abort reasons one by
        one: a campaign whose scenario has faults, drawn or not, has a reason
        per onset time.
    """
    seeds = ("" if s["base_seed"] is None else
             f", seeds {s['base_seed']}..{s['base_seed'] + s['runs'] - 1}")
    head = f"Monte Carlo campaign: {s['recorded']} of {s['runs']} runs recorded{seeds}"
    counts = ", ".join(f"{s.get(k, 0)} {k}" for k in ("complete", "aborted", "invalid",
                                                       "error", "worker_died")
                       if s.get(k) or k == "complete")
    lines = [head, f"  {counts}"]
    if s["metrics"]:
        lines += ["", f"Over the {s['complete']} complete missions",
                  f"  {'quantity':<36}{'mean':>11}{'std':>11}{'p5':>11}{'p50':>11}{'p95':>11}"]
        for col, st in s["metrics"].items():
            cells = "".join(f"{st[k]:>11.4g}" for k in ("mean", "std", "p5", "p50", "p95"))
            lines.append(f"  {METRICS[col]:<36}{cells}")
    if outcomes and s["outcomes"]:
        lines += ["", "Outcomes (runs, probability, outcome)"]
        lines += [f"  {o['runs']:>5}  {o['probability']:>6.1%}  {name}"
                  for name, o in s["outcomes"].items()]
    elif s["abort_reasons"]:
        lines += ["", "Missions not complete (count, reason)"]
        lines += [f"  {n:>5}  {reason}" for reason, n in s["abort_reasons"].items()]
    return "\n".join(lines)


#: The histogram panels: (x label, {legend label: row column}).
HISTOGRAM_PANELS = (
    ("final pointing error [arcsec]", {"": "pointing_error_arcsec"}),
    ("propellant used [kg]", {"": "propellant_kg"}),
    ("drift error [deg/h]", {a: f"drift_error_{a}_deg_h" for a in AXES}),
    ("scale-factor error [ppm]", {a: f"scale_factor_error_{a}_ppm" for a in SF_AXES}),
    ("cross-coupling error [arcsec]", {k.replace("_into_", "→"):
                                       f"cross_coupling_error_{k}_arcsec" for k in CC_KEYS}),
    ("mission time [s]", {"": "mission_time_s"}),
)


def histogram_figure(rows):
    """Histograms of the complete runs, or a "no complete missions" notice.

    With complete runs: pointing error, propellant, calibration errors and
    mission time, one panel each (:data:`HISTOGRAM_PANELS`). With rows but
    none complete, a single panel says so and lists the runs by status and
    the commonest reasons, rather than six empty axes. With no rows at all
    (a campaign interrupted before its first run) there is nothing to draw:
    None.

    Parameters
    ----------
    rows : sequence of dict
        The campaign's rows.

    Returns
    -------
    matplotlib.figure.Figure or None
    """
    from matplotlib.figure import Figure  # imported here: the table alone needs no figures

    if not rows:
        return None
    ok = [r for r in rows if r["status"] == "complete"]
    if not ok:
        return _no_complete_figure(Figure(figsize=(12, 6.5)), rows)
    fig = Figure(figsize=(12, 6.5))
    axes = fig.subplots(2, 3)
    n_bins = max(10, min(50, int(math.sqrt(max(len(ok), 1))) * 2))
    for ax, (title, series) in zip(axes.flat, HISTOGRAM_PANELS, strict=True):
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
    return fig


#: Reasons listed on the "no complete missions" figure, commonest first.
MAX_REASONS_SHOWN = 8


def _no_complete_figure(fig, rows):
    """One blank panel: no complete mission, the runs by status and the commonest reasons."""
    status = Counter(r["status"] for r in rows)
    reasons = Counter(r.get("abort_reason") or r["status"] for r in rows)
    ax = fig.subplots()
    ax.set_axis_off()
    counts = ", ".join(f"{n} {k}" for k, n in status.most_common())
    lines = [f"No complete missions: nothing to histogram ({len(rows)} runs: {counts})", ""]
    lines += [f"{n:>5}  {reason}" for reason, n in reasons.most_common(MAX_REASONS_SHOWN)]
    if len(reasons) > MAX_REASONS_SHOWN:
        lines.append(f"  ... and {len(reasons) - MAX_REASONS_SHOWN} other reasons "
                     "(summary.txt lists them all)")
    ax.text(0.5, 0.5, "\n".join(lines), transform=ax.transAxes, ha="center", va="center",
            multialignment="left", fontsize=11, family="monospace")
    fig.suptitle(f"Monte Carlo campaign: 0 complete missions of {len(rows)}")
    return fig


def plot_histograms(rows, path):
    """Write :func:`histogram_figure` as PNG at ``path``; returns the path.

    Without rows nothing is written and None is returned.

    Parameters
    ----------
    rows : sequence of dict
        The campaign's rows.
    path : path-like
        The PNG file, written atomically.
    """
    fig = histogram_figure(rows)
    if fig is None:
        return None
    return write_atomic(path, writer=lambda tmp: fig.savefig(tmp, dpi=100))


def run_from_cli(cfg, args) -> int:
    """``allsky montecarlo``: fly the campaign, print and save the summary.

    Ctrl-C or SIGTERM: the rows finished are already in ``runs.csv``; the
    summary of those is written and the campaign ends with exit 130 (a second
    Ctrl-C while it tidies up is ignored). A lost Dask cluster: one line,
    exit 2, ``--resume`` continues.

    Parameters
    ----------
    cfg : Scenario
        The scenario, with its dispersions (``--disperse`` and ``--set`` applied).
    args : argparse.Namespace
        The command's options (``allsky montecarlo --help``).

    Returns
    -------
    int
        The exit code.
    """
    from allsky.apps.output import Interrupted, cap_workers, check_output

    check_output("--json", args.json)
    check_output("--out", args.out, directory=True)
    workers = args.workers
    if args.scheduler is None and args.runs is not None:
        workers, note = cap_workers(args.workers, args.runs)
        if note:
            print(f"allsky: {note}", file=sys.stderr)
    try:
        result = run_recorded(cfg, runs=args.runs, workers=workers,
                              scheduler=args.scheduler, batch=args.batch, out=args.out,
                              resume=args.resume,
                              progress=not args.quiet and sys.stderr.isatty(),
                              on_note=lambda text: print(f"allsky: {text}", file=sys.stderr))
    except CampaignError as e:
        print(f"allsky: error: {e}", file=sys.stderr)
        return 2
    s = result["summary"]
    text = format_summary(s, outcomes=bool(cfg.faults))
    to_stdout_json = args.json == "-"
    if not to_stdout_json:
        print(text)
    written = []
    if args.json:
        body = json.dumps(s, indent=2) + "\n"
        if to_stdout_json:
            sys.stdout.write(body)
        else:
            write_atomic(args.json, body, option="--json")
            written.append(args.json)
    if args.out:
        out = Path(args.out)
        write_atomic(out / SUMMARY_TEXT, text + "\n", option="--out")
        write_atomic(out / SUMMARY_JSON, json.dumps(s, indent=2) + "\n", option="--out")
        histograms = plot_histograms(result["rows"], out / HISTOGRAMS)
        if not to_stdout_json:
            drawn = f"; histograms: {histograms}" if histograms is not None else ""
            print(f"\nresults: {out / RESULTS}; summary: {out / SUMMARY_TEXT}{drawn}")
    if result["interrupted"]:
        where = (f"; continue with --resume --out {args.out}" if args.out else "")
        raise Interrupted(f"after {s['recorded']} of {s['runs']} runs (their summary "
                          f"written){where}")
    return no_run_flown(s)


def no_run_flown(s) -> int:
    """The exit code of a finished campaign: 0 if any run was flown to its end.

    A campaign whose every run was rejected (its drawn scenario invalid), raised
    or lost its worker flew nothing: one line says so, exit 2 (3 when runs raised,
    a defect). ``s`` is the campaign's summary (:func:`allsky.studies.montecarlo.summarize`).
    """
    if not s["recorded"] or s["complete"] + s["aborted"]:
        return 0
    counts = ", ".join(f"{s[k]} {k}" for k in ("invalid", "error", "worker_died") if s[k])
    first = next(iter(s["abort_reasons"]), "")
    print(f"allsky: error: no run of the campaign was flown ({counts}); the first: "
          f"{first}", file=sys.stderr)
    return 3 if s["error"] else 2
