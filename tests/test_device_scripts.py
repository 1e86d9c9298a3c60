"""The lent-GPU pipeline script's scheduling logic (benchmarks/device/sweep_pipeline.sh), run here with a fake
``python3`` that records what it was asked to do: no GPU, Warp or training involved."""

from __future__ import annotations

import os
import shutil
import subprocess
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FAKE_PYTHON = r"""#!/bin/bash
# records each call as one line in $FAKE_LOG: "<what> <name> gpu=<CUDA_VISIBLE_DEVICES> <epoch ns>"
case "$1" in
  benchmarks/device/run_campaign.py) mkdir -p "$3"; sleep 0.3; echo "campaign $2 gpu=$CUDA_VISIBLE_DEVICES $(date +%s%N)" >> $FAKE_LOG;;
  -c) F=$(echo "$2" | grep -o "'[^']*\.jsonl\.gz'" | tr -d "'"); echo data > "$F";;
  -m) W=$(echo "$@" | grep -o -- "--widths [0-9]*" | cut -d' ' -f2); D=$(echo "$@" | grep -o -- "--depths [0-9]*" | cut -d' ' -f2)
      C=$(echo "$@" | grep -o -- "--checkpoints [^ ]*" | cut -d' ' -f2); DEV=$(echo "$@" | grep -o -- "--device [a-z]*" | cut -d' ' -f2)
      touch $C/arch_${W}x${D}.npz; echo "train $(basename $(dirname $C))/${W}x${D}/$DEV gpu=$CUDA_VISIBLE_DEVICES $(date +%s%N)" >> $FAKE_LOG;;
  after) echo "after $2 gpu=$CUDA_VISIBLE_DEVICES $(date +%s%N)" >> $FAKE_LOG;;
  *) exit 3;;
esac
"""


@pytest.mark.skipif(shutil.which("bash") is None or shutil.which("setsid") is None, reason="needs bash and setsid")
def test_gpu_lanes_run_campaigns_in_order_then_train_every_architecture_once(tmp_path):
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "python3").write_text(FAKE_PYTHON)
    (bin_dir / "python3").chmod(0o755)
    log, sw, train = tmp_path / "calls.txt", tmp_path / "sw", tmp_path / "train"
    env = {**os.environ, "PATH": f"{bin_dir}:{os.environ['PATH']}", "FAKE_LOG": str(log), "SETUP_SH": "/dev/null",
           "SW_DIR": str(sw), "TRAIN_DIR": str(train), "PROD_OUT": str(tmp_path / "out"), "ST_DIR": str(tmp_path / "st"),
           "POLL_S": "0.2", "CPU_PAR": "3", "GPU_JOBS": "2", "CPU_WIDTHS": "32,64", "LANE_AFTER_0": "python3 after tv"}
    specs = [f"{n}:indentation:{d}:{train}/{n}.jsonl.gz" for n, d in (("a", 3.2), ("b", 5.8), ("c", 3.4))]
    r = subprocess.run(["bash", "benchmarks/device/sweep_pipeline.sh", "a/b,c", *specs], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert "18 CPU and 9 GPU architectures" in r.stdout  # per set 2 widths x 3 depths on CPU, 256 x 3 on a GPU
    deadline = time.time() + 60
    while not (sw / "gpu_done").exists() or not (sw / "cpu_done").exists():
        assert time.time() < deadline, (sw / "pipeline.log").read_text() if (sw / "pipeline.log").exists() else ""
        time.sleep(0.2)
    calls = [line.split() for line in log.read_text().splitlines()]
    when = {(c[0], c[1]): int(c[3]) for c in calls}
    # lane 0 = GPU 0: campaign a, then the LANE_AFTER_0 command; lane 1 = GPU 1: b then c
    assert [(c[1], c[2]) for c in calls if c[0] == "campaign"] in (
        [("a", "gpu=0"), ("b", "gpu=1"), ("c", "gpu=1")], [("b", "gpu=1"), ("a", "gpu=0"), ("c", "gpu=1")])
    assert when["after", "tv"] > when["campaign", "a"] and ["after", "tv", "gpu=0"] == calls[[c[1] for c in calls].index("tv")][:3]
    assert when["campaign", "c"] > when["campaign", "b"]
    trained = [c[1] for c in calls if c[0] == "train"]
    assert len(trained) == len(set(trained)) == 3 * (6 + 3)  # every architecture of every set exactly once
    for c in calls:
        if c[0] == "train" and c[1].endswith("/cuda"):
            lane = int(c[2].removeprefix("gpu="))
            # a GPU trains only after its own campaigns (and lane 0's extra command) are done
            last = max(when["campaign", n] for n in (("a",) if lane == 0 else ("b", "c")))
            assert int(c[3]) > (when["after", "tv"] if lane == 0 else last)
        elif c[0] == "train":
            assert c[2] == "gpu=", c  # CPU jobs see no GPU lane
    for name in ("a", "b", "c"):
        assert len(list((sw / name / "checkpoints").glob("arch_*.npz"))) == 9
