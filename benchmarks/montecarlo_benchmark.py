"""Monte Carlo campaign speed: JIT compile, runner overhead, workers, Dask, memory.

Run: ``python benchmarks/montecarlo_benchmark.py [--runs 1000] [--overhead-runs 60]``.

Each figure comes from a fresh process, so that peak memory is that of
one campaign:

* JIT compile: a mission in a process with an empty numba cache (a
  private ``NUMBA_CACHE_DIR``, so the project's cache is left alone), and
  the first mission of a process that loads the cache;
* runner overhead: the same seeds flown by ``run_mission`` in a loop
  (warmed up) and by a one-worker campaign in the same process; the
  difference per mission is what the runner adds (dispersion draw,
  validation, summary, row, the fsynced write);
* campaigns of ``--runs`` missions on 1 and 2 local worker processes and
  on a local Dask cluster (2 workers, 1 thread each, the workers'
  statistical profiler off unless ``DASK_PROFILE=1``), wall time from the
  call to the last row, worker start-up included, and the same after a
  warm-up campaign for Dask (its workers outlive a campaign);
* peak resident memory of the parent and of the workers at two campaign
  sizes (``ru_maxrss``).
"""

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve()


def _peak_rss_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _rss_mb():
    self_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    children_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    return self_mb, children_mb


def _runner_parts_ms(cfg, out, n=200):
    """Cost of each thing the runner does around a mission [ms]."""
    from allsky.apps import campaign
    from allsky.config import dispersions
    from allsky.sim.mission import run_mission
    from allsky.studies import montecarlo

    m = run_mission(cfg, telemetry=False)
    parts = {}
    t0 = time.perf_counter()
    for s in range(n):
        dispersions.disperse(cfg, s)
    parts["scenario for the seed"] = (time.perf_counter() - t0) / n * 1e3
    t0 = time.perf_counter()
    for _ in range(n):
        row = montecarlo.row_from_summary(0, 1, {}, m.summary())
    parts["summary and row"] = (time.perf_counter() - t0) / n * 1e3
    results = campaign.ResultsFile(Path(f"{out}parts.csv"), montecarlo.columns(cfg))
    t0 = time.perf_counter()
    for _ in range(n):
        results.write(row)
    parts["write and fsync"] = (time.perf_counter() - t0) / n * 1e3
    results.close()
    return parts


def child(mode, runs, out):
    """One measurement, in this (fresh) process; prints a JSON line."""
    from allsky.apps.campaign import run_recorded
    from allsky.config.scenario import load_scenario
    from allsky.sim.mission import run_mission

    cfg = load_scenario()
    res = {"mode": mode, "runs": runs}
    if mode == "compile":
        t0 = time.perf_counter()
        run_mission(cfg, telemetry=False)
        res["first_mission_s"] = time.perf_counter() - t0
    elif mode == "overhead":
        run_mission(cfg, telemetry=False)  # load the compiled code
        seeds = [cfg.mission.seed + i for i in range(runs)]
        single, campaign = [], []
        for k in range(3):  # alternated, best of 3: the machine is shared
            t0 = time.perf_counter()
            for s in seeds:
                run_mission(load_scenario(overrides=[f"mission.seed={s}"]), telemetry=False)
            single.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            run_recorded(cfg, runs=runs, workers=1, out=f"{out}{k}")
            campaign.append(time.perf_counter() - t0)
        res["single_s"], res["campaign_s"] = min(single), min(campaign)
        res["parts_ms"] = _runner_parts_ms(cfg, out)
    elif mode in ("local1", "local2"):
        t0 = time.perf_counter()
        r = run_recorded(cfg, runs=runs, workers=int(mode[-1]), out=out)
        res["campaign_s"] = time.perf_counter() - t0
        res["complete"] = r["summary"]["complete"]
    elif mode == "dask":
        import dask
        from distributed import Client, LocalCluster

        # The workers' statistical profiler (on by default) samples the Python stack every
        # 10 ms; measured 13 % slower missions with it, none without.
        profile = os.environ.get("DASK_PROFILE", "0") == "1"
        res["profiler"] = profile
        t0 = time.perf_counter()
        with dask.config.set({"distributed.worker.profile.enabled": profile}), \
                LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                             host="127.0.0.1", dashboard_address=None) as cluster:
            res["cluster_start_s"] = time.perf_counter() - t0
            t0 = time.perf_counter()
            run_recorded(cfg, runs=4, scheduler=cluster.scheduler_address)  # load the code
            res["warmup_s"] = time.perf_counter() - t0
            t0 = time.perf_counter()
            r = run_recorded(cfg, runs=runs, scheduler=cluster.scheduler_address, out=out)
            res["campaign_s"] = time.perf_counter() - t0
            res["complete"] = r["summary"]["complete"]
            with Client(cluster) as client:
                res["worker_rss_mb"] = list(client.run(_peak_rss_mb).values())
    res["parent_rss_mb"], res["children_rss_mb"] = _rss_mb()
    print(json.dumps(res), flush=True)


def measure(mode, runs, env=None):
    with tempfile.TemporaryDirectory() as d:
        out = subprocess.run([sys.executable, str(HERE), "--child", mode, "--runs", str(runs),
                              "--out", str(Path(d) / "mc")],
                             capture_output=True, text=True, check=True,
                             env={**os.environ, **(env or {})})
    return json.loads(out.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000, help="missions per campaign")
    ap.add_argument("--small-runs", type=int, default=200,
                    help="the smaller campaign, for memory against N")
    ap.add_argument("--overhead-runs", type=int, default=60)
    ap.add_argument("--skip", nargs="*", default=[],
                    choices=["compile", "overhead", "local1", "local2", "dask", "memory"])
    ap.add_argument("--child")
    ap.add_argument("--out")
    a = ap.parse_args()
    if a.child:
        child(a.child, a.runs, a.out)
        return

    print(f"allsky Monte Carlo benchmark, {os.cpu_count()} cores")
    if "compile" not in a.skip:
        with tempfile.TemporaryDirectory() as cache:
            cold = measure("compile", 1, {"NUMBA_CACHE_DIR": cache})
        warm = measure("compile", 1)
        print(f"JIT: first mission with an empty numba cache {cold['first_mission_s']:.1f} s; "
              f"with the cache {warm['first_mission_s']:.2f} s (per new process)")
    if "overhead" not in a.skip:
        r = measure("overhead", a.overhead_runs)
        single = r["single_s"] / a.overhead_runs
        camp = r["campaign_s"] / a.overhead_runs
        print(f"runner overhead ({a.overhead_runs} seeds, one process): run_mission "
              f"{single * 1e3:.1f} ms/mission, campaign {camp * 1e3:.1f} ms/mission, "
              f"difference {(camp - single) * 1e3:+.2f} ms ({(camp / single - 1) * 100:+.1f} %)")
        print("  runner parts: " + ", ".join(f"{k} {v:.2f} ms" for k, v in r["parts_ms"].items()))
    rows = []
    for mode in ("local1", "local2", "dask"):
        if mode in a.skip:
            continue
        r = measure(mode, a.runs)
        workers = (max(r["worker_rss_mb"]) if mode == "dask" else r["children_rss_mb"])
        extra = ""
        if mode == "dask":
            extra = (f" (worker profiler {'on' if r['profiler'] else 'off'}; cluster start {r['cluster_start_s']:.1f} s and warm-up "
                     f"{r['warmup_s']:.1f} s not included)")
        print(f"{mode:>6}: {a.runs} missions in {r['campaign_s']:.1f} s = "
              f"{r['campaign_s'] / a.runs * 1e3:.1f} ms/mission, {r['complete']} complete; "
              f"peak RSS parent {r['parent_rss_mb']:.0f} MB, largest worker "
              f"{workers:.0f} MB{extra}")
        rows.append(r)
    if "memory" not in a.skip:
        for n in (a.small_runs, a.runs):
            r = measure("local2", n)
            print(f"memory at N = {n}: peak RSS parent {r['parent_rss_mb']:.0f} MB, "
                  f"largest worker {r['children_rss_mb']:.0f} MB ({r['campaign_s']:.1f} s)")


if __name__ == "__main__":
    main()
