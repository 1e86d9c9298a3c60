"""A campaign on a SLURM cluster: one Dask worker per GPU job, started by dask-jobqueue, reached by ``--scheduler``.

dask-jobqueue is not a dependency of bubblecal (``pip install dask-jobqueue``).  On the login node, in a
long-lived process (the scheduler lives in it)::

    python -m bubblecal.campaigns.slurm --jobs 8 --queue gpu --walltime 04:00:00 --print-script   # inspect
    python -m bubblecal.campaigns.slurm --jobs 8 --queue gpu --walltime 04:00:00                  # submit, wait

then, from any shell of the same environment, the client writes the store and the jobs simulate::

    bubblecal sim campaign definity_compression_1.5-8um --store /scratch/d.store --scheduler tcp://HOST:PORT

Each job asks for one GPU (``--gres=gpu:1``); SLURM sets its ``CUDA_VISIBLE_DEVICES``, so the campaign's device
'cuda' is the job's GPU, and a job that got no GPU stops before its worker starts.  A job that ends (walltime,
pre-emption) loses only its task in flight: the scheduler re-runs it on another worker, and a re-run of the
command continues the store.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass

from bubblecal._extras import require

__all__ = ["SlurmSettings", "slurm_cluster"]

#: The job script's check that SLURM pinned a GPU (else the worker would compete for another job's GPU).
GPU_GUARD = ('[ -n "$CUDA_VISIBLE_DEVICES" ] || { echo "bubblecal: no GPU allocated to this job '
             '(CUDA_VISIBLE_DEVICES unset); check --gres" >&2; exit 1; }')


@dataclass(frozen=True)
class SlurmSettings:
    """One SLURM job per Dask worker, each with one GPU.

    Parameters
    ----------
    queue : str
        Partition (``#SBATCH -p``).
    walltime : str
        Job time limit 'HH:MM:SS'.
    cpus_per_gpu : int
        CPU cores of each job (host work of the worker: mesh building, records); the worker runs one task at a
        time.
    memory : str
        Host memory of each job (e.g. '32GB').
    gres : str
        Generic resources of each job; one GPU per worker.
    account : str, optional
        Account to charge (``#SBATCH -A``).
    prologue : tuple of str
        Shell lines run before the worker (e.g. 'source /path/venv/bin/activate', 'module load cuda').
    python : str, optional
        The Python that runs the worker (default: this one).
    local_directory : str, optional
        Node-local scratch for the worker (e.g. '$TMPDIR').
    """

    queue: str = "gpu"
    walltime: str = "04:00:00"
    cpus_per_gpu: int = 4
    memory: str = "32GB"
    gres: str = "gpu:1"
    account: str | None = None
    prologue: tuple[str, ...] = ()
    python: str | None = None
    local_directory: str | None = None


def slurm_cluster(settings: SlurmSettings | None = None):
    """A dask-jobqueue ``SLURMCluster`` of single-threaded GPU workers (no job submitted until ``scale``).

    Parameters
    ----------
    settings : SlurmSettings, optional
        Job settings (default :class:`SlurmSettings`).

    Returns
    -------
    dask_jobqueue.SLURMCluster
        Its scheduler runs in this process; ``cluster.scale(jobs=N)`` submits N jobs, ``cluster.job_script()``
        shows one, ``cluster.scheduler_address`` is what ``--scheduler`` takes.

    Raises
    ------
    bubblecal.MissingExtraError
        dask-jobqueue (the ``[cluster]`` extra) is not installed.
    """
    SLURMCluster = require("dask_jobqueue", "cluster").SLURMCluster
    s = settings or SlurmSettings()
    kwargs = dict(queue=s.queue, walltime=s.walltime, cores=1, processes=1, job_cpu=s.cpus_per_gpu,
                  memory=s.memory, job_extra_directives=[f"--gres={s.gres}"],
                  job_script_prologue=[*s.prologue, GPU_GUARD], scheduler_options={"dashboard_address": ":0"})
    if s.account:
        kwargs["account"] = s.account
    if s.python:
        kwargs["python"] = s.python
    if s.local_directory:
        kwargs["local_directory"] = s.local_directory
    return SLURMCluster(**kwargs)


def main(argv: Sequence[str] | None = None) -> int:
    """Start a SLURM cluster of GPU workers, print its address and keep it up until interrupted.

    Parameters
    ----------
    argv : Sequence[str], optional
        Command-line arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        0 after ``--print-script`` or an interrupt.
    """
    d = SlurmSettings()
    ap = argparse.ArgumentParser(description="One SLURM job (one GPU, one Dask worker) per worker, for "
                                             "bubblecal sim campaign --scheduler.")
    ap.add_argument("--jobs", type=int, default=1, help="GPU jobs to submit (one worker each)")
    for f in ("queue", "walltime", "memory", "gres", "account", "python", "local_directory"):
        ap.add_argument(f"--{f.replace('_', '-')}", default=getattr(d, f))
    ap.add_argument("--cpus-per-gpu", type=int, default=d.cpus_per_gpu)
    ap.add_argument("--prologue", action="append", default=[], help="shell line before the worker (repeatable)")
    ap.add_argument("--print-script", action="store_true", help="print one job script and submit nothing")
    args = vars(ap.parse_args(argv))
    jobs, print_only = args.pop("jobs"), args.pop("print_script")
    settings = dataclasses.replace(d, **{**args, "prologue": tuple(args["prologue"])})
    cluster = slurm_cluster(settings)
    try:
        if print_only:
            print(cluster.job_script())
            return 0
        cluster.scale(jobs=jobs)
        print(f"scheduler {cluster.scheduler_address} ({jobs} GPU job(s) submitted); run\n  bubblecal sim campaign "
              f"CONFIG --scheduler {cluster.scheduler_address}\nCtrl-C stops the cluster (and cancels its jobs)",
              flush=True)
        while True:
            time.sleep(60)
    except KeyboardInterrupt:
        return 0
    finally:
        cluster.close()


if __name__ == "__main__":
    sys.exit(main())
