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
results as they complete), in wall time per task with both workers busy
and in CPU time per task of all the processes;
and after them the result bytes per run (a row pickled, as it comes back
from a worker; and as a line of ``runs.csv``).

Prints for each campaign its missions per second, as a whole (from the
call to the last row) and *steady* (after the first tenth of the rows: the
local pool's start-up left out), and the CPU seconds of every process
taking part (this one with the client and scheduler, the workers, the
nannies) per mission; then the medians, and Dask's as a share of the
local pool's, with the ratio of each pair (a Dask campaign against the
local one flown just before it: on a shared machine the pairs are what
can be compared). ``--batch N [N ...]`` adds Dask
campaigns in fixed batches of N missions (where the campaign API takes a
batch size) to the round, beside the one whose batches the campaign
chooses; from their times it fits the per-task overhead as the campaign
sees it (time per mission = t_mission + t_task / N, least squares).
"""

import argparse
import inspect
import os
import pickle
import resource
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


def cpu_s():
    """CPU seconds so far of this process, its finished children and its live descendants."""
    import psutil

    me = psutil.Process()
    own = resource.getrusage(resource.RUSAGE_SELF)
    ended = resource.getrusage(resource.RUSAGE_CHILDREN)
    total = own.ru_utime + own.ru_stime + ended.ru_utime + ended.ru_stime
    for child in me.children(recursive=True):
        try:
            t = child.cpu_times()
        except psutil.Error:
            continue
        total += t.user + t.system
    return total


class Clock:
    """``on_progress`` that notes when the campaign's ``steady``-th row arrived."""

    def __init__(self, steady):
        self.steady, self.at = steady, None

    def __call__(self, done, total):
        if self.at is None and done >= self.steady:
            self.at = time.perf_counter()


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
        overhead, overhead_cpu = [], []
        with Client(cluster) as client:
            for _ in range(3):
                c0 = cpu_s()
                overhead.append(task_overhead_s(client, tasks=2000))
                overhead_cpu.append((cpu_s() - c0) / 2000)
        print(f"per-task overhead (trivial tasks, 8 in flight, 2 workers): wall "
              f"{', '.join(f'{t * 1e3:.2f}' for t in overhead)} ms, median "
              f"{statistics.median(overhead) * 1e3:.2f} ms; CPU (all processes) "
              f"{', '.join(f'{t * 1e3:.2f}' for t in overhead_cpu)} ms, median "
              f"{statistics.median(overhead_cpu) * 1e3:.2f} ms")
        montecarlo.run_campaign(cfg, runs=8, scheduler=address)  # load the loop in each worker
        rates = {kind: [] for kind in kinds}  # steady: after the first tenth of the rows
        whole = {kind: [] for kind in kinds}  # the campaign from its call to its last row
        per_core_s = {kind: [] for kind in kinds}  # missions per CPU second, all processes
        for _ in range(a.repeats):
            for kind, where in kinds.items():
                if kind != "local":
                    where = {"scheduler": address, **where}
                steady = a.runs // 10
                clock = Clock(steady)
                c0, t0 = cpu_s(), time.perf_counter()
                r = montecarlo.run_campaign(cfg, runs=a.runs, on_progress=clock, **where)
                t1 = time.perf_counter()
                cpu = cpu_s() - c0
                assert r["flown"] == a.runs
                rates[kind].append((a.runs - steady) / (t1 - clock.at))
                whole[kind].append(a.runs / (t1 - t0))
                per_core_s[kind].append(a.runs / cpu)
                print(f"  {kind:>7}: {a.runs} missions in {t1 - t0:6.2f} s = "
                      f"{a.runs / (t1 - t0):6.2f} missions/s; after the first {steady} "
                      f"{rates[kind][-1]:6.2f} missions/s; {cpu / a.runs * 1e3:5.1f} ms of CPU "
                      "a mission (all processes)", flush=True)
    for name, table in (("steady", rates), ("whole campaign", whole)):
        local = statistics.median(table["local"])
        print(f"{name} missions/s, median (best) and share of local's median:")
        for kind, got in table.items():
            ratios = [d / loc for loc, d in zip(table["local"], got, strict=True)]
            print(f"  {kind:>7}: {statistics.median(got):6.2f} ({max(got):6.2f}) = "
                  f"{statistics.median(got) / local:6.1%} (pairwise "
                  f"{', '.join(f'{x:.1%}' for x in ratios)})")
    print("missions per CPU second (all processes), median:")
    for kind, got in per_core_s.items():
        print(f"  {kind:>7}: {statistics.median(got):6.2f} = "
              f"{statistics.median(got) / statistics.median(per_core_s['local']):6.1%} of local")
    if len(a.batch) >= 2:
        # Wall time per mission on 2 workers = (t_mission + t_task / n) / 2: fit both.
        xs = [1 / n for n in a.batch]
        ys = [2 / max(rates[f"dask/{n}"]) for n in a.batch]  # the best: least disturbed
        mx, my = statistics.fmean(xs), statistics.fmean(ys)
        slope = (sum((x - mx) * (y - my) for x, y in zip(xs, ys, strict=True))
                 / sum((x - mx) ** 2 for x in xs))
        print(f"fit over batches {a.batch}: t_task {slope * 1e3:.2f} ms per task, "
              f"t_mission {(my - slope * mx) * 1e3:.1f} ms per mission per worker")
    pickled, line = result_bytes(cfg)
    print(f"result bytes per run: {pickled} pickled (worker to client), {line} in runs.csv")


if __name__ == "__main__":
    main()
