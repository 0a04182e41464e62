"""Campaign throughput: the local worker pool against a local Dask cluster, same two cores.

Run: ``python benchmarks/dask_throughput.py [--runs 1000] [--repeats 3] [--batch N]``.

Both fly the same campaign (the default scenario, ``--runs`` missions,
nothing written), alternately, ``--repeats`` times each, in one sitting:

* **local**: :func:`allsky.studies.montecarlo.run_campaign` on 2 local
  worker processes, started for each campaign (their start-up included, as
  in ``allsky montecarlo``);
* **dask**: the same on a ``LocalCluster`` of 2 single-threaded worker
  processes (the workers' statistical profiler off, as ``docs/montecarlo.md``
  starts them; ``--profile`` leaves it on). The cluster outlives a campaign,
  so it is started and warmed up once (a small campaign loads the compiled
  loop in each worker), outside the timing.

Before them it measures the cluster's per-task overhead: trivial tasks
through the path a campaign's batches take (submitted a window at a time,
results as they complete), in wall time per task with both workers busy;
and after them the result bytes per run (a row pickled, as it comes back
from a worker; and as a line of ``runs.csv``).

Prints missions per second for each campaign, the medians, and Dask's
median as a share of the local pool's. ``--batch N [N ...]`` adds Dask
campaigns in fixed batches of N missions (where the campaign API takes a
batch size) to the round, beside the one whose batches the campaign
chooses; from their times it fits the per-task overhead as the campaign
sees it (time per mission = t_mission + t_task / N, least squares).
"""

import argparse
import inspect
import os
import pickle
import statistics
import sys
import time


def _noop(x):
    return x


def task_overhead_s(client, tasks=2000, window=8):
    """Wall time per trivial task, ``window`` in flight, results taken as they complete."""
    from distributed import as_completed

    items = iter(range(tasks))
    t0 = time.perf_counter()
    ac = as_completed([client.submit(_noop, next(items), pure=False) for _ in range(window)])
    for f in ac:
        f.result()
        x = next(items, None)
        if x is not None:
            ac.add(client.submit(_noop, x, pure=False))
    return (time.perf_counter() - t0) / tasks


def result_bytes(cfg):
    """Bytes per run coming back from a worker (pickled row) and written (CSV line)."""
    from allsky.apps import campaign
    from allsky.studies import montecarlo

    row = montecarlo.run_campaign(cfg, runs=1, workers=1)["rows"][0]
    cols = montecarlo.columns(cfg)
    return len(pickle.dumps(row, protocol=5)), len(campaign._encode(row, cols))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000, help="missions per campaign")
    ap.add_argument("--repeats", type=int, default=3, help="campaigns of each kind")
    ap.add_argument("--batch", type=int, nargs="*", default=[],
                    help="also fly Dask campaigns in batches of these sizes")
    ap.add_argument("--profile", action="store_true",
                    help="leave the Dask workers' statistical profiler on")
    a = ap.parse_args()

    import dask
    from distributed import Client, LocalCluster

    import allsky
    from allsky.config.scenario import load_scenario
    from allsky.studies import montecarlo

    cfg = load_scenario()
    takes_batch = "batch" in inspect.signature(montecarlo.run_campaign).parameters
    if a.batch and not takes_batch:
        sys.exit("--batch: this allsky's run_campaign takes no batch size")
    kinds = {"local": {"workers": 2}, "dask": {}}
    kinds.update({f"dask/{n}": {"batch": n} for n in a.batch})
    print(f"allsky {allsky.__file__}; {os.cpu_count()} cores; {a.runs} missions per campaign, "
          f"{a.repeats} of each, alternated; Dask profiler {'on' if a.profile else 'off'}")
    with dask.config.set({"distributed.worker.profile.enabled": a.profile}), \
            LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                         host="127.0.0.1", dashboard_address=None) as cluster:
        address = cluster.scheduler_address
        with Client(cluster) as client:
            overhead = [task_overhead_s(client) for _ in range(3)]
        print(f"per-task overhead (trivial tasks, 8 in flight, 2 workers): "
              f"{', '.join(f'{t * 1e3:.2f}' for t in overhead)} ms; "
              f"median {statistics.median(overhead) * 1e3:.2f} ms")
        montecarlo.run_campaign(cfg, runs=8, scheduler=address)  # load the loop in each worker
        rates = {kind: [] for kind in kinds}
        for _ in range(a.repeats):
            for kind, where in kinds.items():
                if kind != "local":
                    where = {"scheduler": address, **where}
                t0 = time.perf_counter()
                r = montecarlo.run_campaign(cfg, runs=a.runs, **where)
                dt = time.perf_counter() - t0
                assert r["flown"] == a.runs
                rates[kind].append(a.runs / dt)
                print(f"  {kind:>7}: {a.runs} missions in {dt:6.2f} s = "
                      f"{a.runs / dt:6.2f} missions/s", flush=True)
    local = statistics.median(rates["local"])
    for kind, got in rates.items():
        ratios = [d / loc for loc, d in zip(rates["local"], got, strict=True)]
        print(f"median {kind:>7}: {statistics.median(got):6.2f} missions/s = "
              f"{statistics.median(got) / local:6.1%} of local (pairwise "
              f"{', '.join(f'{x:.1%}' for x in ratios)})")
    if len(a.batch) >= 2:
        # Wall time per mission on 2 workers = (t_mission + t_task / n) / 2: fit both.
        xs = [1 / n for n in a.batch]
        ys = [2 / statistics.median(rates[f"dask/{n}"]) for n in a.batch]
        mx, my = statistics.fmean(xs), statistics.fmean(ys)
        slope = (sum((x - mx) * (y - my) for x, y in zip(xs, ys, strict=True))
                 / sum((x - mx) ** 2 for x in xs))
        print(f"fit over batches {a.batch}: t_task {slope * 1e3:.2f} ms per task, "
              f"t_mission {(my - slope * mx) * 1e3:.1f} ms per mission per worker")
    pickled, line = result_bytes(cfg)
    print(f"result bytes per run: {pickled} pickled (worker to client), {line} in runs.csv")


if __name__ == "__main__":
    main()
