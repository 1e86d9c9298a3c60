"""Campaign runs: resumable execution (interrupted runs, a killed Dask worker), streaming, real tiny runs."""

from __future__ import annotations

import functools
import importlib.util
import json
import os
import signal
import sys
import threading
import time
from collections import Counter

import cloudpickle
import numpy as np
import pytest

from bubblecal.campaigns import (
    CampaignConfig,
    CampaignConfigError,
    CampaignError,
    TaskResult,
    pending_indices,
    run_campaign,
    sample_ids,
    sample_seed,
    store_status,
    synthetic_simulate,
)
from bubblecal.data import CampaignStore

# test-local simulate functions travel to the Dask workers by value (the test module is not importable there)
cloudpickle.register_pickle_by_value(sys.modules[__name__])

BOX = {"ka": (5580.0, 27900.0), "kb": (100.0, 1000.0), "b1": (0.0, 3.0), "b2": (0.0, 10.0), "a3": (-2.5, 3.0),
       "a4": (0.0, 4.0)}
FAST = functools.partial(synthetic_simulate)


def cfg(tmp_path, **kw) -> CampaignConfig:
    base = dict(name="t", protocol="compression", diameter_um=2.1, ranges=BOX, n_samples=20, seed=7,
                replicas_per_task=3, store=str(tmp_path / "t.store"))
    base.update(kw)
    return CampaignConfig(**base)


def lines_per_sample(store_path) -> Counter:
    """sample_id -> number of lines in records.jsonl (every line must parse)."""
    counts: Counter = Counter()
    for line in (store_path / "records.jsonl").read_text().splitlines():
        counts[json.loads(line)["sample_id"]] += 1
    return counts


# ------------------------------------------------------------------------------------------------
# interruption safety (in-process scheduler: the same client-side bookkeeping as with Dask)
# ------------------------------------------------------------------------------------------------
def test_limit_then_restart_runs_every_sample_once(tmp_path):
    c = cfg(tmp_path)
    s1 = run_campaign(c, scheduler_address="inline", simulate=FAST, limit=7, progress=False)
    assert s1.n_written == 7 and s1.n_tasks == 3 and s1.n_remaining == 13
    assert len(pending_indices(c)) == 13
    s2 = run_campaign(c, scheduler_address="inline", simulate=FAST, progress=False)
    assert s2.n_done_before == 7 and s2.n_written == 13 and s2.n_remaining == 0
    assert lines_per_sample(c.store_path) == Counter({sid: 1 for sid in sample_ids(c)})
    s3 = run_campaign(c, scheduler_address="inline", simulate=FAST, progress=False)
    assert s3.n_tasks == 0 and s3.store_counts["ok"] == 20


def _raise_on_task_2(task):
    if "t-000006" in task.sample_ids:
        raise RuntimeError("simulated crash")
    return synthetic_simulate(task)


def test_exception_interrupts_then_restart_completes(tmp_path):
    c = cfg(tmp_path)
    with pytest.raises(CampaignError, match="simulated crash"):
        run_campaign(c, scheduler_address="inline", simulate=_raise_on_task_2, on_error="raise", progress=False)
    assert set(lines_per_sample(c.store_path)) == set(sample_ids(c)[:6])  # tasks 0, 1 written, nothing else
    # 'record': the failing task's samples are stored as 'failed' and re-run by the next call
    s = run_campaign(c, scheduler_address="inline", simulate=_raise_on_task_2, progress=False)
    assert s.counts["failed"] == 3 and s.counts["ok"] == 11 and len(s.task_errors) == 1
    assert store_status(c.store_path).n_pending == 3
    s = run_campaign(c, scheduler_address="inline", simulate=FAST, progress=False)
    assert s.n_written == 3 and s.store_counts == {**dict.fromkeys(s.store_counts, 0), "ok": 20}
    final = CampaignStore(c.store_path).read()
    assert sorted(r["sample_id"] for r in final) == sample_ids(c)


def _nan_and_ruptured(task):
    res = synthetic_simulate(task)
    res.y[0, -1] = np.nan  # reported ok, non-finite -> 'invalid'
    res.status[-1] = "ruptured"
    return res


def test_invalid_and_ruptured_are_stored_not_rerun_and_filtered(tmp_path):
    from bubblecal.surrogates.training import filter_curves, read_dataset

    c = cfg(tmp_path, n_samples=9, replicas_per_task=3)
    s = run_campaign(c, scheduler_address="inline", simulate=_nan_and_ruptured, progress=False)
    assert s.counts["invalid"] == 3 and s.counts["ruptured"] == 3 and s.counts["ok"] == 3
    assert pending_indices(c) == []  # final statuses: not re-run
    ts = read_dataset(c.store_path)
    kept, report = filter_curves(ts)
    assert kept.n_curves == 3 and report.status_counts == {"invalid": 3, "ruptured": 3}
    rec = CampaignStore(c.store_path).read()[0]
    assert rec["message"].startswith("simulation reported ok") and rec["provenance"]["task"] == 0
    assert rec["tier"] == "quasistatic" and rec["code_version"] and rec["seed"] == sample_seed(7, 0)


def test_store_of_another_design_is_refused(tmp_path):
    run_campaign(cfg(tmp_path, n_samples=3), scheduler_address="inline", simulate=FAST, progress=False)
    with pytest.raises(CampaignError, match="differs in: n_samples"):
        run_campaign(cfg(tmp_path, n_samples=4), scheduler_address="inline", simulate=FAST, progress=False)
    # execution settings are not part of the design
    run_campaign(cfg(tmp_path, n_samples=3, replicas_per_task=1), scheduler_address="inline", simulate=FAST,
                 progress=False)


def _ringdown_fake(task):
    t = np.linspace(0.0, 5.0, 11)
    r = np.sqrt(task.params["ka"])[:, None] * 0 + 9.36 + 0.1 * np.sin(t)[None, :]
    return TaskResult(x=t, y=r, status=["ok"] * task.n_replicas)


def test_ringdown_records_and_missing_module_message(tmp_path):
    fixed = {**{k: (v[0], v[0]) for k, v in BOX.items()}, "ka": (1000.0, 28000.0)}
    c = cfg(tmp_path, protocol="ringdown", design="grid", diameter_um=(4.68, 5.18), ranges=fixed, n_samples=3)
    run_campaign(c, scheduler_address="inline", simulate=_ringdown_fake, progress=False)
    recs = CampaignStore(c.store_path).read()
    assert len(recs) == 6 and recs[0]["setup"] == "ringdown" and len(recs[0]["x"]) == 11
    c2 = cfg(tmp_path, name="r2", protocol="ringdown", design="grid", ranges=fixed, n_samples=2, subdivisions=1,
             tier="implicit", store=str(tmp_path / "r2.store"),
             tier_settings={"equilibration_steps": 200, "record_steps": 400, "record_every": 10})
    if importlib.util.find_spec("bubblecal.sim.protocols.ringdown") is None:
        with pytest.raises(CampaignError, match="ringdown_batch"):
            run_campaign(c2, scheduler_address="inline", on_error="raise", progress=False)
    else:  # the real default task: a tiny implicit-solvent ringdown (~2 s)
        s = run_campaign(c2, scheduler_address="inline", on_error="raise", progress=False)
        recs = CampaignStore(c2.store_path).read()
        assert s.counts["ok"] == 2 and len(recs[0]["x"]) == len(recs[0]["y"]) > 10
        assert abs(recs[0]["y"][0] / recs[0]["radius_dpd"] - 1.0) < 0.05  # R(t) near the bubble radius


# ------------------------------------------------------------------------------------------------
# Dask
# ------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def dask_client():
    import logging

    from distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=":0",
                           silence_logs=logging.ERROR)
    client = Client(cluster)
    yield client
    client.close()
    cluster.close()


def test_dask_exception_interrupt_and_restart(tmp_path, dask_client):
    c = cfg(tmp_path, n_samples=18)
    with pytest.raises(CampaignError, match="simulated crash"):
        run_campaign(c, client=dask_client, simulate=_raise_on_task_2, on_error="raise", progress=False)
    before = lines_per_sample(c.store_path)
    assert "t-000006" not in before and all(v == 1 for v in before.values())
    s = run_campaign(c, client=dask_client, simulate=FAST, progress=False)
    assert s.n_workers == 2 and s.n_written == 18 - len(before) and s.compute_seconds > 0
    assert lines_per_sample(c.store_path) == Counter({sid: 1 for sid in sample_ids(c)})


def test_killed_worker_is_rescheduled_nothing_lost_or_duplicated(tmp_path):
    import logging

    from distributed import Client, LocalCluster

    c = cfg(tmp_path, n_samples=24, replicas_per_task=2)  # 12 tasks of 0.4 s on 2 workers
    slow = functools.partial(synthetic_simulate, sleep_seconds=0.4)
    killed: dict = {}
    with LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=":0",
                      silence_logs=logging.CRITICAL) as cluster, Client(cluster) as client:
        pids = sorted(client.run(os.getpid).values())
        records = c.store_path / "records.jsonl"

        def killer():
            t_end = time.time() + 60
            while time.time() < t_end:
                n = len(records.read_text().splitlines()) if records.exists() else 0
                if n >= 4:  # mid-run: both workers busy with later tasks
                    killed["n_before"] = n
                    os.kill(pids[0], signal.SIGKILL)
                    return
                time.sleep(0.02)

        thread = threading.Thread(target=killer, daemon=True)
        thread.start()
        summary = run_campaign(c, client=client, simulate=slow, progress=False)
        thread.join(5)
        pids_after = sorted(client.run(os.getpid).values())
    assert killed and killed["n_before"] < 24  # the worker died mid-campaign
    assert pids[0] not in pids_after  # ... and its nanny started a new one
    store = CampaignStore(c.store_path)
    assert lines_per_sample(c.store_path) == Counter({sid: 1 for sid in sample_ids(c)})
    assert store.read(warn=False) and not store.problems  # no torn or corrupt line
    assert summary.n_written == 24 and summary.counts["ok"] == 24 and summary.task_errors == []


def test_real_tiny_quasistatic_campaign_on_local_cluster(tmp_path):
    """The default task (quasistatic tier) through the default LocalCluster: 2 samples, subdivision 1."""
    c = cfg(tmp_path, n_samples=2, replicas_per_task=2, subdivisions=1, tier_settings={"max_steps": 4000},
            loading_grid=(0.0, 0.12, 0.24))
    s = run_campaign(c, n_workers=1, progress=False)
    recs = CampaignStore(c.store_path).read()
    assert s.n_written == 2 and s.scheduler.startswith("tcp://")
    assert [r["status"] for r in recs] == ["ok", "ok"]
    y = np.array([r["y"] for r in recs])
    assert y.shape == (2, 3) and np.all(np.diff(y, axis=1) > 0)  # force grows with compression
    assert recs[0]["provenance"]["info"]["mesh_subdivisions"] == 1 and recs[0]["x"] == [0.0, 0.12, 0.24]


def test_diameter_filter_runs_only_that_diameter(tmp_path):
    fixed = {**{k: (v[0], v[0]) for k, v in BOX.items()}, "ka": (1000.0, 28000.0), "kb": (389.23, 389.23)}
    c = cfg(tmp_path, design="grid", diameter_um=(2.1, 3.0), ranges=fixed, n_samples=4, replicas_per_task=3)
    s1 = run_campaign(c, scheduler_address="inline", simulate=FAST, progress=False, diameters=[3.0])
    assert s1.n_written == 4
    ids = sample_ids(c)
    assert set(lines_per_sample(c.store_path)) == set(ids[4:])  # samples 4-7 are the 3.0 um ones
    with pytest.raises(CampaignConfigError, match="not in the design"):
        run_campaign(c, scheduler_address="inline", simulate=FAST, progress=False, diameters=[2.9])
    s2 = run_campaign(c, scheduler_address="inline", simulate=FAST, progress=False)
    assert s2.n_written == 4 and lines_per_sample(c.store_path) == Counter({sid: 1 for sid in ids})


def _unstable_at(budget):
    def sim(task):
        res = synthetic_simulate(task)
        res.status = ["unstable"] * task.n_replicas
        res.info = {"settings": {"fire": {"max_steps": budget}}}
        return res
    return sim


def test_unstable_is_retried_only_with_a_larger_step_budget(tmp_path):
    pytest.importorskip("warp")
    from bubblecal.sim.tiers import QuasistaticTier

    budget = QuasistaticTier().max_steps  # the tier default the config runs with
    c = cfg(tmp_path, n_samples=4, replicas_per_task=2, tier="quasistatic",
            retry_statuses=("failed", "timeout", "unstable"))
    run_campaign(c, scheduler_address="inline", simulate=_unstable_at(budget), limit=2, progress=False)
    assert pending_indices(c) == [2, 3]  # 0-1 ran with today's budget: the same verdict again, not re-run
    run_campaign(c, scheduler_address="inline", simulate=_unstable_at(budget // 5), progress=False)
    assert pending_indices(c) == [2, 3]  # they ran with a smaller budget: re-run
    run_campaign(c, scheduler_address="inline", simulate=FAST, progress=False)
    assert pending_indices(c) == [] and store_status(c.store_path).counts == {**store_status(c.store_path).counts,
                                                                              "ok": 2, "unstable": 2}


class _Killed(BaseException):
    """Stands for a killed process (not an Exception: the campaign loop must not catch it)."""


def _killed_after(n_curves: int):
    """A simulate function that runs the real task and dies once ``n_curves`` curves have been streamed."""
    from bubblecal.campaigns import simulate_task

    def simulate(task, on_curve=None):
        seen = []

        def cb(r, y, status, info):
            on_curve(r, y, status, info)
            seen.append(r)
            if len(seen) == n_curves:
                raise _Killed()

        return simulate_task(task, on_curve=cb)

    return simulate


def test_inline_indentation_streams_finished_curves_and_a_killed_task_keeps_them(tmp_path):
    """Quasi-static indentation with slot refill writes each curve when it is finished: a task killed after
    3 of its 6 curves keeps those 3, the restart runs only the other 3, and every record equals the record of
    an uninterrupted run of the same design (curve, status, seed), streamed or written at the task's end."""
    kw = dict(protocol="indentation", diameter_um=3.2, n_samples=6, replicas_per_task=6, subdivisions=2,
              tier="quasistatic", tier_settings={"max_replicas": 2, "max_steps": 20000},
              loading_grid=(0.0, 20.0, 40.0))
    ref = cfg(tmp_path, store=str(tmp_path / "ref.store"), **kw)
    run_campaign(ref, scheduler_address="inline", progress=False)
    ref_recs = {r["sample_id"]: r for r in CampaignStore(ref.store_path).read()}
    assert len(ref_recs) == 6 and all(r["provenance"].get("streamed") for r in ref_recs.values())
    assert {r["provenance"]["replicas_in_task"] for r in ref_recs.values()} == {6}

    c = cfg(tmp_path, store=str(tmp_path / "k.store"), **kw)
    with pytest.raises(_Killed):
        run_campaign(c, scheduler_address="inline", progress=False, simulate=_killed_after(3))
    kept = CampaignStore(c.store_path).read()
    assert len(kept) == 3 and len(pending_indices(c)) == 3  # the finished curves survive the kill
    s = run_campaign(c, scheduler_address="inline", progress=False)
    assert s.n_submitted == 3 and s.n_written == 3
    assert lines_per_sample(c.store_path) == Counter({sid: 1 for sid in sample_ids(c)})  # none twice
    for r in CampaignStore(c.store_path).read():
        want = ref_recs[r["sample_id"]]
        assert (r["status"], r["seed"], r["params"], r["x"]) == (want["status"], want["seed"], want["params"],
                                                                   want["x"])
        np.testing.assert_array_equal(r["y"], want["y"])  # the same FIRE iterates: identical curves
        assert r["provenance"]["info"]["fire_steps"] == want["provenance"]["info"]["fire_steps"]
        chain = r["provenance"]["info"]["fire_steps_chain"]  # per chain point: sums to the curve's FIRE updates
        assert len(chain) == 3 and sum(chain) == r["provenance"]["info"]["fire_steps"]
        settings = r["provenance"]["info"]["settings"]  # a streamed record keeps the run's settings
        assert settings["fire"]["max_steps"] == 20000 and settings["k_loaded_per_pole"] == 1
        assert settings["pole_patch"] == {"fraction": 0.01} and "fire_evaluations" not in settings
    # without slot refill (one slot per replica) the curves stream too; lock-step has no per-curve end: written
    # at the task's end; both give the same curves
    for name, extra in (("async", {}), ("lockstep", {"schedule": "lockstep"})):
        once = cfg(tmp_path, store=str(tmp_path / f"{name}.store"),
                   **{**kw, "tier_settings": {"max_steps": 20000, **extra}})
        run_campaign(once, scheduler_address="inline", progress=False)
        recs = CampaignStore(once.store_path).read()
        assert [bool(r["provenance"].get("streamed")) for r in recs] == [name == "async"] * 6
        for r in recs:
            np.testing.assert_array_equal(r["y"], ref_recs[r["sample_id"]]["y"])
