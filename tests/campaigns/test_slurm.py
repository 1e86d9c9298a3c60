"""The SLURM example: the job script dask-jobqueue would submit, checked without a cluster."""

from __future__ import annotations

import pytest

from bubblecal.campaigns.slurm import GPU_GUARD, SlurmSettings, main, slurm_cluster

pytest.importorskip("dask_jobqueue")


def test_slurm_job_script_asks_one_gpu_one_worker_thread_and_pins_it():
    settings = SlurmSettings(queue="gpu-long", walltime="08:30:00", cpus_per_gpu=6, memory="48GB", account="proj7",
                             prologue=("source /opt/bc/venv/bin/activate",), python="/opt/bc/venv/bin/python")
    with slurm_cluster(settings) as cluster:
        script = cluster.job_script()
        address = cluster.scheduler_address
    lines = script.splitlines()
    for directive in ("#SBATCH -p gpu-long", "#SBATCH -A proj7", "#SBATCH -t 08:30:00", "#SBATCH --gres=gpu:1",
                      "#SBATCH --cpus-per-task=6", "#SBATCH -n 1"):
        assert directive in lines, script
    assert any(line.startswith("#SBATCH --mem=") for line in lines)
    worker = lines[-1]
    assert worker.startswith("/opt/bc/venv/bin/python -m distributed.cli.dask_worker " + address)
    assert "--nthreads 1" in worker and "--nanny" in worker and worker.count("--nthreads") == 1
    # the environment first, then the GPU check, then the worker
    assert lines.index("source /opt/bc/venv/bin/activate") < lines.index(GPU_GUARD) < len(lines) - 1
    assert address.startswith("tcp://")


def test_slurm_print_script_submits_nothing(capsys):
    assert main(["--print-script", "--queue", "a100", "--walltime", "01:00:00", "--gres", "gpu:a100:1"]) == 0
    out = capsys.readouterr().out
    assert "#SBATCH -p a100" in out and "#SBATCH --gres=gpu:a100:1" in out and "#SBATCH -t 01:00:00" in out


def test_a_job_without_a_gpu_stops_before_its_worker():
    import os
    import subprocess

    env = {k: v for k, v in os.environ.items() if k != "CUDA_VISIBLE_DEVICES"}
    none = subprocess.run(["bash", "-c", GPU_GUARD + "\necho worker"], env=env, capture_output=True, text=True)
    assert none.returncode == 1 and "no GPU allocated" in none.stderr and "worker" not in none.stdout
    one = subprocess.run(["bash", "-c", GPU_GUARD + "\necho worker"], env={**env, "CUDA_VISIBLE_DEVICES": "2"},
                         capture_output=True, text=True)
    assert one.returncode == 0 and one.stdout.strip() == "worker"
