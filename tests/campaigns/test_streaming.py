"""Dask campaigns stream each finished curve to the client's store: before the task ends, across a worker that
dies mid-task, and across an interrupted client (one LocalCluster of two worker processes for the module)."""

from __future__ import annotations

import functools
import json
import logging
import os
import sys
import threading
import time
from collections import Counter
from pathlib import Path

import cloudpickle
import pytest

from bubblecal.campaigns import CampaignConfig, run_campaign, sample_ids, synthetic_simulate
from bubblecal.campaigns import runner as runner_module
from bubblecal.data import CampaignStore

cloudpickle.register_pickle_by_value(sys.modules[__name__])  # test-local task functions travel by value

BOX = {"ka": (5580.0, 27900.0), "kb": (100.0, 1000.0), "b1": (0.0, 3.0), "b2": (0.0, 10.0), "a3": (-2.5, 3.0),
       "a4": (0.0, 4.0)}
WAIT_S = 30.0  # how long a test waits for a streamed record before it fails


@pytest.fixture(scope="module")
def client():
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=":0",
                      silence_logs=logging.CRITICAL) as cluster, Client(cluster) as c:
        c.wait_for_workers(2, timeout=120)
        yield c


def cfg(tmp_path, **kw) -> CampaignConfig:
    base = dict(name="t", protocol="compression", diameter_um=2.1, ranges=BOX, n_samples=6, seed=7,
                replicas_per_task=3, store=str(tmp_path / "t.store"))
    base.update(kw)
    return CampaignConfig(**base)


def _lines(c: CampaignConfig) -> list[dict]:
    """The store's complete record lines (read while the campaign may still be appending)."""
    path = c.store_path / "records.jsonl"
    text = path.read_text() if path.exists() else ""
    return [json.loads(line) for line in text.split("\n")[:-1] if line]


def _wait_for(pred, timeout: float = WAIT_S) -> bool:
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        if pred():
            return True
        time.sleep(0.05)
    return False


def _streaming(task, on_curve=None, *, pause: float = 0.05, gate: str | None = None, die_on: str | None = None,
               marker: str | None = None):
    """Synthetic curves handed to ``on_curve`` one by one: replica 1 on waits for the file ``gate``; the first
    task holding ``die_on`` kills its worker process after streaming replica 1 (``marker`` records its pid)."""
    res = synthetic_simulate(task)
    for r in range(task.n_replicas):
        if r == 1 and gate is not None and not _wait_for(lambda: os.path.exists(gate), 2 * WAIT_S):
            raise TimeoutError(f"gate {gate} never opened")
        if on_curve is not None:  # None where the runner does not stream
            on_curve(r, res.y[r], "ok", {"pid": os.getpid()})
        time.sleep(pause)
        if r == 1 and die_on in task.sample_ids and not os.path.exists(marker):
            Path(marker).write_text(str(os.getpid()))
            time.sleep(1.0)  # the streamed curves leave the worker's batched stream
            os._exit(1)
    res.info["pid"] = os.getpid()
    return res


def test_records_reach_the_store_before_their_task_finishes(tmp_path, client):
    c = cfg(tmp_path)
    gate = tmp_path / "gate"
    out = {}
    run = threading.Thread(target=lambda: out.update(s=run_campaign(
        c, client=client, simulate=functools.partial(_streaming, gate=str(gate)), progress=False)))
    run.start()
    try:
        # every task holds at replica 1 until the gate opens, so a stored record was streamed, not returned
        seen = _wait_for(lambda: len(_lines(c)) >= 2)
        early = _lines(c)
    finally:
        gate.write_text("open")
        run.join(120)
    assert seen, "no record reached the store while the tasks were still running"
    assert all(r["provenance"]["streamed"] is True for r in early)
    assert {int(r["sample_id"][2:]) % 3 for r in early} == {0}  # replica 0 of each task: the ones streamed
    assert Counter(r["sample_id"] for r in _lines(c)) == Counter(sample_ids(c))
    assert out["s"].counts["ok"] == 6 and out["s"].n_written == 6 and out["s"].task_errors == []


def test_a_worker_dying_mid_task_keeps_its_streamed_curves_and_writes_nothing_twice(tmp_path, client):
    c = cfg(tmp_path)
    marker = tmp_path / "died"
    summary = run_campaign(c, client=client, progress=False,
                           simulate=functools.partial(_streaming, die_on="t-000004", marker=str(marker)))
    assert marker.exists()
    died = int(marker.read_text())
    lines = _lines(c)
    assert Counter(r["sample_id"] for r in lines) == Counter(sample_ids(c))  # each sample exactly once
    assert summary.counts["ok"] == 6 and summary.task_errors == []
    pid = {r["sample_id"]: r["provenance"]["info"]["pid"] for r in lines}
    # replicas 0 and 1 of the killed task were streamed before the process died and kept; replica 2 came from the
    # re-run, in another process
    assert pid["t-000003"] == pid["t-000004"] == died and pid["t-000005"] != died


def test_an_interrupted_client_keeps_the_streamed_records_and_the_rerun_computes_only_the_rest(tmp_path, client,
                                                                                               monkeypatch):
    c = cfg(tmp_path)
    original = runner_module._RecordWriter.curve_done
    k = 2

    def interrupt_after_k(self, *args, **kw):
        n = original(self, *args, **kw)
        if len(self.written) >= k:
            raise KeyboardInterrupt
        return n

    monkeypatch.setattr(runner_module._RecordWriter, "curve_done", interrupt_after_k)
    slow = functools.partial(_streaming, pause=0.5)
    with pytest.raises(KeyboardInterrupt):
        run_campaign(c, client=client, simulate=slow, progress=False)
    monkeypatch.undo()
    kept = _lines(c)
    assert len(kept) == k and all(r["provenance"]["streamed"] is True for r in kept)
    summary = run_campaign(c, client=client, simulate=slow, progress=False)
    assert summary.n_done_before == k and summary.n_submitted == 6 - k and summary.n_written == 6 - k
    lines = _lines(c)
    assert lines[:k] == kept  # the interrupted run's records stay as they were
    assert Counter(r["sample_id"] for r in lines) == Counter(sample_ids(c))
    assert CampaignStore(c.store_path).counts()["ok"] == 6
