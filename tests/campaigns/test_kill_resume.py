"""SIGKILL of a running compression campaign (the client process, mid-batch), then resume: every sample stored
exactly once, with the same curve as an uninterrupted run (CPU, quasi-static tier, a tiny design)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import pytest

CAMPAIGN = """
[campaign]
name = "killme"
protocol = "compression"
diameter_um = 2.1
tier = "quasistatic"
n_samples = 6
seed = 11
replicas_per_task = 2
device = "cpu"
subdivisions = 1
loading_grid = [0.0, 0.06, 0.12, 0.18, 0.24]

[ranges]
priors = "definity_full"
kb = 500.0

[tier]
max_steps = 4000

[dask]
scheduler_address = "inline"
"""


def _campaign(toml: Path, store: Path) -> list[str]:
    return [sys.executable, "-m", "bubblecal.workflows.cli", "sim", "campaign", str(toml), "--store", str(store),
            "--no-progress"]


def _records(store: Path) -> list[dict]:
    path = store / "records.jsonl"
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


@pytest.mark.slow
def test_sigkill_mid_campaign_then_resume_loses_and_duplicates_nothing(tmp_path):
    toml = tmp_path / "killme.toml"
    toml.write_text(CAMPAIGN)
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    reference = tmp_path / "reference.store"
    subprocess.run(_campaign(toml, reference), check=True, env=env, capture_output=True, timeout=600)

    store = tmp_path / "killed.store"
    proc = subprocess.Popen(_campaign(toml, store), env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t_end = time.time() + 600
    while time.time() < t_end and len(_records(store)) < 1 and proc.poll() is None:
        time.sleep(0.05)
    assert proc.poll() is None, "the campaign finished before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    n_killed = len(_records(store))
    assert 1 <= n_killed < 6

    done = subprocess.run(_campaign(toml, store), env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    records = _records(store)
    assert Counter(r["sample_id"] for r in records) == Counter({f"killme-{i:06d}": 1 for i in range(6)})
    want = {r["sample_id"]: r["y"] for r in _records(reference)}
    assert {r["sample_id"]: r["y"] for r in records} == want  # identical curves, bit for bit
