"""Campaigns over several GPUs: counting GPUs, one pinned worker per GPU, a worker that dies mid-task, task splits.

Everything here runs on the CPU: the pinning is an environment variable each worker process sees, and the
"GPUs" are whatever CUDA_VISIBLE_DEVICES or a stand-in nvidia-smi say.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import logging
import os
import sys
from collections import Counter
from pathlib import Path

import cloudpickle
import numpy as np
import pytest
from typer.testing import CliRunner

from bubblecal.campaigns import (
    CampaignConfig,
    CampaignConfigError,
    CampaignError,
    check_gpus,
    gpu_cluster,
    make_tasks,
    run_campaign,
    sample_ids,
    synthetic_simulate,
    visible_gpus,
)
from bubblecal.data import CampaignStore
from bubblecal.workflows.cli import app

cloudpickle.register_pickle_by_value(sys.modules[__name__])  # test-local task functions travel by value

TINY = Path(__file__).parent / "tiny_campaign.toml"
BOX = {"ka": (5580.0, 27900.0), "kb": (100.0, 1000.0), "b1": (0.0, 3.0), "b2": (0.0, 10.0), "a3": (-2.5, 3.0),
       "a4": (0.0, 4.0)}


def cfg(tmp_path, **kw) -> CampaignConfig:
    base = dict(name="t", protocol="compression", diameter_um=2.1, ranges=BOX, n_samples=12, seed=7,
                replicas_per_task=2, store=str(tmp_path / "t.store"))
    base.update(kw)
    return CampaignConfig(**base)


def test_visible_gpus_reads_cuda_visible_devices_then_nvidia_smi(tmp_path):
    assert visible_gpus({"CUDA_VISIBLE_DEVICES": "2,3"}) == ["2", "3"]
    assert visible_gpus({"CUDA_VISIBLE_DEVICES": "GPU-aa, GPU-bb"}) == ["GPU-aa", "GPU-bb"]
    assert visible_gpus({"CUDA_VISIBLE_DEVICES": "1,-1,0"}) == ["1"]  # CUDA stops at the first invalid entry
    assert visible_gpus({"CUDA_VISIBLE_DEVICES": ""}) == []
    smi = tmp_path / "nvidia-smi"
    smi.write_text("#!/bin/sh\necho 'GPU 0: NVIDIA H100 80GB HBM3 (UUID: GPU-1)'\n"
                   "echo 'GPU 1: NVIDIA H100 80GB HBM3 (UUID: GPU-2)'\necho '  MIG 1g.10gb Device 0: x'\n")
    smi.chmod(0o755)
    assert visible_gpus({"PATH": str(tmp_path)}) == ["0", "1"]


def test_more_gpus_than_the_machine_has_is_a_clear_error():
    assert check_gpus(2, {"CUDA_VISIBLE_DEVICES": "4,6,7"}) == ["4", "6"]
    with pytest.raises(CampaignError, match=r"3 GPUs asked for, but this machine has 1 GPU \(0\) \(counted by "
                                            r"CUDA_VISIBLE_DEVICES='0'\); nothing was run and the store is "
                                            r"unchanged \(ask for at most 1\)"):
        check_gpus(3, {"CUDA_VISIBLE_DEVICES": "0"})
    with pytest.raises(CampaignError, match=r"^1 GPU asked for, but this machine has no GPU .*\(run on a GPU "
                                            r"machine\)"):
        check_gpus(1, {"CUDA_VISIBLE_DEVICES": ""})
    with pytest.raises(CampaignError, match="integer >= 1"):
        check_gpus(0, {"CUDA_VISIBLE_DEVICES": "0"})


def test_cli_gpus_3_on_a_machine_with_fewer_runs_nothing(tmp_path, monkeypatch):
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "0")  # a one-GPU machine (this VM has none)
    store = tmp_path / "s"
    res = CliRunner().invoke(app, ["sim", "campaign", str(TINY), "--store", str(store), "--gpus", "3",
                                   "--no-progress"])
    out = " ".join(res.output.split())
    assert res.exit_code == 1, res.output
    assert "3 GPUs asked for, but this machine has 1 GPU (0)" in out and "nothing was run" in out
    assert not store.exists()  # refused before the store is opened
    for extra in (["--scheduler", "tcp://h:8786"], ["--workers", "2"], ["--device", "cuda:1"]):
        res = CliRunner().invoke(app, ["sim", "campaign", str(TINY), "--store", str(store), "--gpus", "2", *extra])
        assert res.exit_code == 2 and extra[0] in " ".join(res.output.split()), res.output
    assert not store.exists()
    with pytest.raises(CampaignConfigError, match="cannot come with scheduler 'tcp://h:8786'"):
        run_campaign(cfg(tmp_path), gpus=1, scheduler_address="tcp://h:8786", progress=False)


def test_gpu_cluster_pins_one_single_threaded_worker_per_gpu():
    from distributed import Client

    with gpu_cluster(["3", "5"], silence_logs=logging.CRITICAL) as cluster, Client(cluster) as client:
        seen = client.run(os.getenv, "CUDA_VISIBLE_DEVICES")  # a bound os.environ.get would travel
        names = {a: w["name"] for a, w in client.scheduler_info()["workers"].items()}
        threads = client.nthreads()
    assert sorted(seen.values()) == ["3", "5"]
    assert {names[a]: v for a, v in seen.items()} == {"gpu-0": "3", "gpu-1": "5"}
    assert set(threads.values()) == {1}
    with pytest.raises(CampaignError, match="distinct GPUs"):
        gpu_cluster(["0", "0"])


def _dies_once(task, marker: str):
    """Kill this worker process the first time a task holds sample t-000004; else a synthetic curve that also
    reports the worker's CUDA_VISIBLE_DEVICES and the task's device."""
    if "t-000004" in task.sample_ids and not os.path.exists(marker):
        Path(marker).write_text(str(os.getpid()))
        os._exit(1)
    res = synthetic_simulate(task, sleep_seconds=0.2)
    res.info.update(cvd=os.environ.get("CUDA_VISIBLE_DEVICES"), device=task.device)
    return res


def test_gpus_campaign_survives_a_worker_that_dies_mid_task(tmp_path, monkeypatch):
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "3,5")  # two "GPUs"; the tasks ignore the device
    c = cfg(tmp_path, device="cuda")
    marker = tmp_path / "died"
    summary = run_campaign(c, gpus=2, simulate=functools.partial(_dies_once, marker=str(marker)), progress=False)
    assert marker.exists()  # a worker process did die mid-task ...
    died = int(marker.read_text())
    lines = Counter(json.loads(line)["sample_id"] for line in (c.store_path / "records.jsonl").read_text().split())
    assert lines == Counter({sid: 1 for sid in sample_ids(c)})  # ... and the store has every sample exactly once
    assert summary.counts["ok"] == 12 and summary.task_errors == [] and summary.n_workers == 2
    recs = {r["sample_id"]: r for r in CampaignStore(c.store_path).read()}
    assert recs["t-000004"]["provenance"]["pid"] != died  # its task ran again, in another process
    assert {r["provenance"]["info"]["cvd"] for r in recs.values()} <= {"3", "5"}
    assert {r["provenance"]["info"]["device"] for r in recs.values()} == {"cuda:0"}


def test_fewer_tasks_than_workers_are_split_into_tasks_of_the_same_mix():
    c = CampaignConfig(name="p", protocol="compression", diameter_um=None, diameter_range_um=(1.5, 8.0),
                       diameter_step_um=0.5, loading_fractions=(0.0, 0.1, 0.2), ranges=BOX, n_samples=41, seed=3,
                       tier="quasistatic", subdivisions=4, replicas_per_task=1000, store="unused")
    assert c.pools_levels
    idx = list(range(41))
    assert [t.n_replicas for t in make_tasks(c, idx)] == [41]
    tasks = make_tasks(c, idx, min_tasks=2)
    assert [t.n_replicas for t in tasks] == [21, 20]
    assert sorted(i for t in tasks for i in t.indices) == idx  # every index once
    d0, d1 = (np.array(t.diameters_um) for t in tasks)
    assert np.all(np.diff(d0) >= 0) and np.all(d0[:20] <= d1) and np.all(d1 <= d0[1:])  # dealt in turn
    small = dataclasses.replace(c, replicas_per_task=10)
    assert [t.n_replicas for t in make_tasks(small, idx, min_tasks=2)] == [10, 10, 10, 10, 1]  # enough already


def test_asking_this_machine_for_one_gpu_more_than_it_has():
    env = {k: v for k, v in os.environ.items() if k != "CUDA_VISIBLE_DEVICES"}  # nvidia-smi, else Warp
    n = len(visible_gpus(env))
    with pytest.raises(CampaignError, match=f"{n + 1} GPUs? asked for, but this machine has "):
        check_gpus(n + 1, env)
