"""Dask campaigns fly runs in batches: the batch size rule, and rows that do not depend on it.

No test here depends on timing: the batch size is a function of the mission
time it is given, the batches are checked on an executor that flies each
batch when it is submitted, and on a real local cluster only the rows are
compared (with a fixed batch size, and with the one chosen as the runs fly):
the same rows, bit for bit, as the campaign flown in one process; a campaign
stopped part way and resumed with another batch size; a worker killed in the
middle of a batch.
"""

import math
import os
import signal
from concurrent.futures import Future

import pytest

from allsky.apps import campaign
from allsky.apps.campaign import RESULTS, read_rows, run_recorded
from allsky.apps.cli import main
from allsky.config import load_scenario
from allsky.studies import montecarlo
from allsky.studies.montecarlo import (
    BATCH_MAX_S,
    BATCH_OVERHEAD_SHARE,
    BATCHES_PER_THREAD,
    SCHEDULER_SHARE,
    CampaignError,
    batch_size,
    run_campaign,
)

RUNS = 9
SPEC = ['dispersions.gyro.drift_deg_h={dist="normal",sigma=0.5}',
        'dispersions.jets.thrust_n={dist="uniform",low=0.2,high=0.3}', "mission.seed=300"]


@pytest.fixture(scope="module")
def cfg():
    return load_scenario(overrides=SPEC)


@pytest.fixture(scope="module")
def reference(cfg):
    """The campaign flown in this process, one run at a time."""
    return run_campaign(cfg, runs=RUNS, workers=1)["rows"]


# -- the batch size rule ---------------------------------------------------------------

def test_batch_size_before_any_mission_is_timed_is_one():
    assert batch_size(None, threads=2, left=10**6) == 1
    assert batch_size(0.0, threads=2, left=10**6) == 1


def test_overhead_rule_keeps_the_task_overhead_a_small_share_of_the_batch():
    # 4 ms of overhead on 40 ms missions: 2 % of a batch is 4 ms at 5 missions.
    assert batch_size(0.040, threads=2, left=10**6, overhead_s=0.004) == math.ceil(
        0.004 / (BATCH_OVERHEAD_SHARE * 0.040))
    for mission_s in (0.002, 0.01, 0.03, 0.1, 0.4, 2.0, 30.0):
        for overhead_s in (0.0005, 0.002, 0.004, 0.02):
            n = batch_size(mission_s, threads=2, left=10**7, overhead_s=overhead_s)
            by_progress = max(1, math.floor(BATCH_MAX_S / mission_s))
            assert n >= 1
            # The overhead share is met unless the progress rule (or one run) caps the batch.
            assert overhead_s / (n * mission_s) <= BATCH_OVERHEAD_SHARE or n == by_progress
            # A batch of more than one run never flies longer than BATCH_MAX_S.
            assert n == 1 or n * mission_s <= BATCH_MAX_S


def test_progress_rule_caps_a_batch_and_long_missions_go_one_a_task():
    assert batch_size(0.001, threads=2, left=10**6, overhead_s=0.05) == math.floor(
        BATCH_MAX_S / 0.001)
    assert batch_size(BATCH_MAX_S * 1.5, threads=2, left=10**6) == 1
    assert batch_size(60.0, threads=64, left=10**6) == 1


def test_scheduler_rule_grows_the_batches_on_a_cluster_of_many_threads():
    """The client and scheduler handle one task after another: at most half busy."""
    for threads in (100, 1000):
        n = batch_size(0.04, threads, left=10**9, overhead_s=0.005)
        assert n == math.ceil(threads * 0.005 / (SCHEDULER_SHARE * 0.04))
        assert threads / (n * 0.04) * 0.005 <= SCHEDULER_SHARE  # tasks a second, each 5 ms
    assert batch_size(0.04, 2, left=10**9, overhead_s=0.005) == math.ceil(
        0.005 / (BATCH_OVERHEAD_SHARE * 0.04))  # two threads: the overhead rule


def test_balance_rule_shrinks_the_batches_at_the_end():
    threads = 2
    assert batch_size(0.001, threads, left=20, overhead_s=0.01) == math.ceil(
        20 / (BATCHES_PER_THREAD * threads))
    assert batch_size(0.001, threads, left=3, overhead_s=0.01) == 1
    assert batch_size(0.001, threads, left=0, overhead_s=0.01) == 1
    # A large cluster near the end: batches smaller than the other rules', so that every
    # thread has some.
    assert batch_size(0.001, threads=1000, left=10**5, overhead_s=0.01) == math.ceil(
        10**5 / (BATCHES_PER_THREAD * 1000))


def test_batch_must_be_a_whole_number_and_needs_a_scheduler(cfg, capsys):
    for bad in (0, -1, 2.5, True, "3"):
        with pytest.raises(CampaignError, match="--batch"):
            montecarlo.check_batch(bad, "tcp://127.0.0.1:8786")
    with pytest.raises(CampaignError, match="--scheduler"):
        run_campaign(cfg, runs=1, workers=1, batch=2)
    assert main(["montecarlo", "--runs", "2", "--batch", "2", "--quiet"]) == 2
    assert "--batch: batches are for a Dask cluster" in capsys.readouterr().err
    assert main(["montecarlo", "--runs", "2", "--batch", "0", "--quiet"]) == 2


# -- batches on an executor that flies each batch as it is submitted ---------------------

class KilledWorker(Exception):
    """As Dask's: the task was flown on ``allowed_failures + 1`` workers and each died."""

    allowed_failures = 3


class Executor:
    """Flies each batch when submitted (:func:`montecarlo.fly_batch`); batches holding
    ``poison`` raise :class:`KilledWorker`, as a batch whose workers all died."""

    def __init__(self, data, poison=None, mission_s=None):
        self.data, self.poison, self.mission_s = data, poison, mission_s
        self.batches = []

    def submit(self, jobs):
        self.batches.append([run for run, _ in jobs])
        f = Future()
        if self.poison is not None and any(run == self.poison for run, _ in jobs):
            f.set_exception(KilledWorker())
        else:
            rows, seconds = montecarlo.fly_batch(self.data, jobs)
            f.set_result((rows, seconds if self.mission_s is None
                          else self.mission_s * len(rows)))
        return f

    @staticmethod
    def wait_first(futures):
        return sorted(futures, key=id)  # all done; any order


def _stream(cfg, executor, batch=None, threads=2, runs=RUNS):
    jobs = montecarlo.Jobs(runs, int(cfg.mission.seed))
    return montecarlo._Batches(executor.submit, executor.wait_first, jobs, threads,
                               batch=batch, died=montecarlo.died_row_maker(cfg))


@pytest.mark.parametrize("batch", [1, 2, 4, RUNS, 100, None])
def test_batches_give_the_rows_bit_for_bit_in_run_order_within_each(cfg, reference, batch):
    executor = Executor(cfg.as_dict())
    stream = _stream(cfg, executor, batch)
    chunks = list(stream)
    assert len(chunks) == len(executor.batches)
    for chunk in chunks:  # the batches end in any order, each batch's rows in its order
        assert [r["run"] for r in chunk] in executor.batches
    rows = sorted((r for chunk in chunks for r in chunk), key=lambda r: r["run"])
    assert rows == reference  # the very floats
    handed_out = [run for b in executor.batches for run in b]
    assert handed_out == list(range(RUNS))  # each run once, in run order
    if batch is not None:
        assert all(len(b) == min(batch, RUNS) for b in executor.batches[:-1])


def test_batches_grow_from_one_to_the_rule_as_missions_are_timed(cfg):
    """Before a batch has been timed a batch is one run; then :func:`batch_size` of the time."""
    executor = Executor(cfg.as_dict(), mission_s=0.001)
    stream = _stream(cfg, executor, threads=1, runs=60)
    stream.window = 1  # one batch at a time: each size follows the last batch's time
    list(stream)
    sizes = [len(b) for b in executor.batches]
    assert sizes[0] == 1 and stream.mission_s() == 0.001
    left = 60 - sizes[0]
    assert sizes[1] == batch_size(0.001, 1, left)
    assert sum(sizes) == 60 and sizes == stream.sizes


def test_a_batch_whose_workers_died_is_flown_again_one_run_a_task(cfg, reference):
    """Dask's KilledWorker for a batch: its other runs are saved, the culprit is worker_died."""
    executor = Executor(cfg.as_dict(), poison=5)
    rows = sorted((r for chunk in _stream(cfg, executor, batch=4) for r in chunk),
                  key=lambda r: r["run"])
    assert [r["run"] for r in rows] == list(range(RUNS))
    assert [r for r in rows if r["run"] != 5] == [r for r in reference if r["run"] != 5]
    dead = rows[5]
    assert dead["status"] == "worker_died" and dead["seed"] == reference[5]["seed"]
    assert dead["abort_reason"] == "its Dask workers died 4 times flying it (KilledWorker)"
    assert dead["gyro.drift_deg_h[0]"] == reference[5]["gyro.drift_deg_h[0]"]  # drawn inputs
    assert [4, 5, 6, 7] in executor.batches and [5] in executor.batches


def test_killed_worker_without_a_died_row_maker_is_raised(cfg):
    executor = Executor(cfg.as_dict(), poison=0)
    jobs = montecarlo.Jobs(2, int(cfg.mission.seed))
    stream = montecarlo._Batches(executor.submit, executor.wait_first, jobs, 1, batch=2)
    with pytest.raises(KilledWorker):
        list(stream)


# -- on a real local cluster ---------------------------------------------------------------

@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip("distributed")
    import dask

    with dask.config.set({"distributed.worker.profile.enabled": False}), \
            distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                     host="127.0.0.1", dashboard_address=None) as c:
        yield c


@pytest.mark.parametrize("batch", [1, 4, None])
def test_dask_batches_give_the_local_rows(cfg, reference, cluster, batch):
    seen = []
    result = run_campaign(cfg, runs=RUNS, scheduler=cluster.scheduler_address, batch=batch,
                          on_row=seen.append)
    assert result["rows"] == reference and result["flown"] == RUNS
    assert sorted(r["run"] for r in seen) == list(range(RUNS))


def test_campaign_stopped_part_way_resumed_with_another_batch_equals_the_whole(
        cfg, reference, cluster, tmp_path, monkeypatch):
    """Batches of 4 stopped after 3 rows on disk; resumed in batches of 2: the same rows."""
    out = tmp_path / "mc"
    write = campaign.ResultsFile.write
    written = []

    def write_then_fail(self, row):
        write(self, row)
        written.append(row["run"])
        if len(written) == 3:
            raise OSError("disk full")

    monkeypatch.setattr(campaign.ResultsFile, "write", write_then_fail)
    with pytest.raises(OSError, match="disk full"):
        run_recorded(cfg, runs=RUNS, scheduler=cluster.scheduler_address, batch=4, out=out)
    monkeypatch.setattr(campaign.ResultsFile, "write", write)
    assert len(read_rows(out)) == 3
    result = run_recorded(cfg, scheduler=cluster.scheduler_address, batch=2, out=out,
                          resume=True)
    assert result["flown"] == RUNS - 3
    assert read_rows(out) == reference == result["rows"]
    assert len((out / RESULTS).read_text().splitlines()) == RUNS + 1  # no run twice


def _kill_on(run, mark):
    """In a Dask worker: the mission of ``run`` SIGKILLs its worker, the first time only."""
    original = montecarlo.fly_one

    def fly_one(cfg, r, seed):
        if r == run:
            try:
                os.close(os.open(mark, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            except FileExistsError:
                pass
            else:
                os.kill(os.getpid(), signal.SIGKILL)
        return original(cfg, r, seed)

    montecarlo.fly_one = fly_one


# The module's cluster holds the scheduler's HTTP port (8787, on loopback: Dask serves its
# health routes there even without a dashboard); this cluster's scheduler takes another.
@pytest.mark.filterwarnings("ignore:Port 8787 is already in use")
def test_a_worker_killed_mid_batch_loses_no_row(cfg, reference, tmp_path):
    """Run 5 of the batch 4..7 kills its worker once: the cluster flies the batch again.

    Its own cluster: the killed worker is replaced by its nanny.
    """
    distributed = pytest.importorskip("distributed")
    import dask

    mark = tmp_path / "killed"
    with dask.config.set({"distributed.worker.profile.enabled": False}), \
            distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                     host="127.0.0.1", dashboard_address=None) as c, \
            distributed.Client(c) as client:
        client.run(_kill_on, 5, str(mark))
        seen = []
        result = run_campaign(cfg, runs=RUNS, scheduler=c.scheduler_address, batch=4,
                              on_row=seen.append)
    assert mark.exists()  # a worker died in the middle of the batch
    assert result["rows"] == reference
    assert sorted(r["run"] for r in seen) == list(range(RUNS))  # each row handed on once
