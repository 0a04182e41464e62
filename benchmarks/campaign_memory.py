"""Campaign memory against the number of runs, without flying them all.

Run: ``python benchmarks/campaign_memory.py [--runs 1000 10000000] [--seconds 10]``.

Starts ``allsky montecarlo --runs N --out DIR --quiet`` (2 local workers,
and with ``--scheduler`` on a Dask cluster at that address) for each N,
lets it fly ``--seconds``, reads the peak resident memory of the command's
process (``VmHWM``) and of its worker processes, then stops it with Ctrl-C
(SIGINT: it saves the runs that finished and exits 130). A campaign whose
runs were listed up front would show it here; the rows kept for the
statistics (about 2 kB a finished run) are the same few hundred in each.
"""

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _status_kb(pid, key):
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith(key + ":"):
                return int(line.split()[1])
    except OSError:
        return None
    return None


def _children(pid):
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except OSError:
        return []
    return [int(p) for p in text.split()]


def measure(runs, seconds, scheduler=None):
    """Peak RSS [MB] of the command and its largest worker after ``seconds``, rows saved."""
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "mc"
        where = ["--scheduler", scheduler] if scheduler else ["--workers", "2"]
        proc = subprocess.Popen([sys.executable, "-m", "allsky", "montecarlo", "--runs",
                                 str(runs), *where, "--out", str(out), "--quiet"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        time.sleep(seconds)
        parent = _status_kb(proc.pid, "VmHWM")
        workers = [_status_kb(c, "VmHWM") or 0 for c in _children(proc.pid)]
        rows = max(0, (out / "runs.csv").read_bytes().count(b"\n") - 1)
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=120)
    return {"runs": runs, "parent_mb": parent / 1024, "worker_mb": max(workers, default=0) / 1024,
            "rows": rows, "exit": proc.returncode}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, nargs="+", default=[1000, 10_000_000])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--scheduler", help="a Dask scheduler's address (default: local workers)")
    a = ap.parse_args()
    print(f"{os.cpu_count()} cores; {'Dask ' + a.scheduler if a.scheduler else '2 local workers'}"
          f"; each campaign stopped after {a.seconds:g} s")
    for runs in a.runs:
        r = measure(runs, a.seconds, a.scheduler)
        workers = (f"largest worker {r['worker_mb']:.0f} MB" if r["worker_mb"] else
                   "the Dask workers are not its processes")
        print(f"--runs {runs:>9}: peak RSS command {r['parent_mb']:.0f} MB, {workers}; "
              f"{r['rows']} rows saved, exit {r['exit']}", flush=True)


if __name__ == "__main__":
    main()
