"""The Dask cluster a campaign runs on: one worker process per GPU, a LocalCluster, or a scheduler elsewhere.

:func:`gpu_cluster` does what ``dask_cuda.LocalCUDACluster`` does for a campaign (one single-threaded worker
process per GPU, each started with ``CUDA_VISIBLE_DEVICES`` set to its own GPU, so device 'cuda:0' inside the
worker is that GPU) with distributed's own ``SpecCluster`` and ``Nanny``: dask-cuda pins an older dask than
bubblecal does (docs/decisions.md, "GPU campaigns without dask-cuda").  A worker that dies is restarted by its
nanny with the same pinning, and the scheduler re-runs its task elsewhere (``distributed.scheduler.
allowed-failures`` times); the client is the store's only writer, so nothing is lost or written twice.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

from bubblecal._extras import require
from bubblecal.campaigns.errors import CampaignError
from bubblecal.campaigns.scheduler import CONNECT_TIMEOUT_S, connect_scheduler

__all__ = ["GPU_WORKER_DEVICE", "gpu_cluster", "open_client"]

#: The device a campaign's tasks use inside a pinned worker: the one GPU its CUDA_VISIBLE_DEVICES leaves.
GPU_WORKER_DEVICE = "cuda:0"
#: Seconds the workers of a cluster started here may take to join.
WORKER_START_TIMEOUT_S = 120.0


def gpu_cluster(gpu_ids: Sequence[str], *, silence_logs: int = logging.ERROR):
    """A local Dask cluster of one single-threaded worker process per GPU, each pinned to its GPU.

    Parameters
    ----------
    gpu_ids : Sequence[str]
        ``CUDA_VISIBLE_DEVICES`` value of each worker ('0', '1', ... or GPU UUIDs; e.g.
        :func:`~bubblecal.campaigns.check_gpus`), one worker each, named ``gpu-<position>``.
    silence_logs : int
        Logging level of the scheduler and workers.

    Returns
    -------
    distributed.SpecCluster
        Started, every worker joined; its host memory split evenly between the workers (as a LocalCluster's).

    Raises
    ------
    CampaignError
        ``gpu_ids`` is empty or repeats a GPU (two workers on one GPU time-slice it).
    """
    distributed = require("distributed", "sim")
    Nanny, Scheduler, SpecCluster = distributed.Nanny, distributed.Scheduler, distributed.SpecCluster
    parse_memory_limit = require("distributed.worker_memory", "sim").parse_memory_limit

    ids = [str(g) for g in gpu_ids]
    if not ids or len(set(ids)) != len(ids):
        raise CampaignError(f"a GPU cluster needs distinct GPUs, one worker each; got {ids}")
    memory = parse_memory_limit("auto", 1, len(ids), logger=logging.getLogger(__name__))
    workers = {f"gpu-{i}": {"cls": Nanny, "options": {
        "nthreads": 1, "env": {"CUDA_VISIBLE_DEVICES": gid}, "memory_limit": memory, "host": "127.0.0.1",
        "silence_logs": silence_logs}} for i, gid in enumerate(ids)}
    scheduler = {"cls": Scheduler, "options": {"host": "127.0.0.1", "dashboard_address": ":0"}}
    return SpecCluster(workers=workers, scheduler=scheduler, silence_logs=silence_logs, name="bubblecal-gpus")


def open_client(scheduler_address: str | None, *, gpu_ids: Sequence[str] | None = None, n_workers: int = 1,
                connect_timeout_s: float = CONNECT_TIMEOUT_S):
    """A Dask client for a campaign, and the cluster started for it here (None for a remote scheduler).

    Parameters
    ----------
    scheduler_address : str or None
        A remote 'tcp://HOST:PORT' (checked by :func:`~bubblecal.campaigns.check_scheduler_address`), or None
        for a cluster on this machine.
    gpu_ids : Sequence[str], optional
        Without a remote address: one pinned worker per GPU (:func:`gpu_cluster`); None: a
        ``LocalCluster(processes=True, threads_per_worker=1)`` of ``n_workers``.
    n_workers : int
        LocalCluster worker processes.
    connect_timeout_s : float
        Seconds to wait for a remote scheduler [s].

    Returns
    -------
    tuple
        ``(distributed.Client, cluster or None)``; the caller closes both.

    Raises
    ------
    CampaignError
        The remote scheduler does not answer within ``connect_timeout_s``, or the workers started here did not
        all join within :data:`WORKER_START_TIMEOUT_S`.
    """
    distributed = require("distributed", "sim")
    Client, LocalCluster = distributed.Client, distributed.LocalCluster

    if scheduler_address:
        return connect_scheduler(scheduler_address, connect_timeout_s), None
    if gpu_ids:
        cluster, n = gpu_cluster(gpu_ids), len(gpu_ids)
    else:
        n = n_workers
        cluster = LocalCluster(n_workers=n, processes=True, threads_per_worker=1, dashboard_address=":0",
                               silence_logs=logging.ERROR)
    client = None
    try:
        client = Client(cluster)
        client.wait_for_workers(n, timeout=WORKER_START_TIMEOUT_S)
    except (OSError, TimeoutError) as exc:
        if client is not None:
            client.close()
        cluster.close()
        raise CampaignError(f"{n} Dask worker(s) did not start on this machine within {WORKER_START_TIMEOUT_S:g} s "
                            f"({exc}); nothing was run") from None
    return client, cluster

