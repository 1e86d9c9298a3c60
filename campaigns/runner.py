"""The campaign loop: run the pending part of a design on Dask (or in-process) and append the records.

The client process is the store's only writer, and it writes each curve as soon as a streaming tier finishes
it (provenance ``streamed``): in process (``scheduler_address='inline'``) through the task's ``on_curve`` hook,
on Dask through events the workers send (:mod:`bubblecal.campaigns.streaming`).  Each finished task then writes
its samples not already written, in one atomic, fsync'ed append.  So a killed worker (Dask re-runs its task) or
an interrupted client (the next run skips what is stored) loses at most the curves in flight and duplicates
nothing.
"""

from __future__ import annotations

import dataclasses
import json
import os
import socket
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from bubblecal._extras import require
from bubblecal.campaigns.cluster import GPU_WORKER_DEVICE, open_client
from bubblecal.campaigns.config import CampaignConfig, _is_int
from bubblecal.campaigns.design import design_points
from bubblecal.campaigns.devices import check_device, check_gpus, cuda_device_count
from bubblecal.campaigns.errors import CampaignConfigError, CampaignError
from bubblecal.campaigns.progress import _Progress
from bubblecal.campaigns.records import task_records
from bubblecal.campaigns.scheduler import CONNECT_TIMEOUT_S, check_scheduler_address
from bubblecal.campaigns.streaming import _run_dask
from bubblecal.campaigns.tasks import (
    CampaignTask,
    TaskResult,
    _execute_task,
    _takes_on_curve,
    make_tasks,
    pending_indices,
    simulate_task,
)
from bubblecal.data import RECORD_STATUSES, RETRY_STATUSES, CampaignStore, code_version

__all__ = ["CampaignSummary", "run_campaign"]

_MAX_CONSECUTIVE_TASK_ERRORS = 10


@dataclass
class CampaignSummary:
    """Outcome of one :func:`run_campaign` call.

    Parameters
    ----------
    name, store : str
        Campaign name and store path.
    n_design : int
        Design points of the campaign.
    n_done_before : int
        Design points final before this call (``n_design - n_pending``).
    n_pending : int
        Design points pending before this call (of the selected diameters).
    n_submitted, n_tasks : int
        Samples and tasks this call ran (``limit`` applied).
    n_written : int
        Samples written by this call.
    counts : dict of str to int
        Statuses written by this call.
    store_counts : dict of str to int
        The store's latest status per sample after it.
    wall_seconds : float
        First submit to last record written [s] (cluster start-up excluded).
    startup_seconds : float
        Cluster start-up [s] (0 in-process).
    compute_seconds : float
        Sum of the per-task compute times measured inside the tasks [s].
    task_seconds : list of float
        Per-task compute times [s].
    n_workers : int
        Dask workers (1 in-process).
    scheduler : str
        Scheduler address, or 'inline'.
    task_errors : list of str
        One line per task that raised.
    retry_statuses : tuple of str
        The config's retry statuses (for :attr:`n_remaining`).
    """

    name: str
    store: str
    n_design: int
    n_done_before: int
    n_pending: int
    n_submitted: int
    n_tasks: int
    n_written: int
    counts: dict[str, int]
    store_counts: dict[str, int]
    wall_seconds: float
    startup_seconds: float
    compute_seconds: float
    task_seconds: list[float]
    n_workers: int
    scheduler: str
    task_errors: list[str] = field(default_factory=list)
    retry_statuses: tuple[str, ...] = RETRY_STATUSES

    @property
    def n_remaining(self) -> int:
        """Design points still pending after this call."""
        return self.n_pending - sum(v for s, v in self.counts.items() if s not in self.retry_statuses)

    @property
    def all_failed(self) -> bool:
        """Whether this call wrote samples and every one of them 'failed' or came back 'invalid'."""
        return self.n_written > 0 and self.counts.get("failed", 0) + self.counts.get("invalid", 0) == self.n_written

    @property
    def efficiency(self) -> float:
        """compute / (wall x workers); NaN when nothing ran."""
        denom = self.wall_seconds * max(self.n_workers, 1)
        return self.compute_seconds / denom if denom > 0 else float("nan")

    @property
    def overhead_fraction(self) -> float:
        """1 - :attr:`efficiency`: the share of worker time not spent inside tasks."""
        return 1.0 - self.efficiency

    def as_dict(self) -> dict:
        """The summary as JSON-able dict (``task_seconds`` left out)."""
        return {"name": self.name, "store": self.store, "n_design": self.n_design, "n_done_before": self.n_done_before,
                "n_pending": self.n_pending, "n_submitted": self.n_submitted, "n_tasks": self.n_tasks,
                "n_written": self.n_written, "n_remaining": self.n_remaining, "counts": dict(self.counts),
                "store_counts": dict(self.store_counts), "wall_seconds": self.wall_seconds,
                "startup_seconds": self.startup_seconds, "compute_seconds": self.compute_seconds,
                "n_workers": self.n_workers, "scheduler": self.scheduler, "efficiency": self.efficiency,
                "overhead_fraction": self.overhead_fraction, "task_errors": list(self.task_errors)}


def _open_store(config: CampaignConfig) -> CampaignStore:
    """Create or open the store; refuse one written by a different design."""
    store = CampaignStore.create(config.store_path, description=f"bubblecal campaign {config.name}",
                                 meta={"campaign": config.to_dict(), "design_hash": config.design_hash()})
    meta = store.header().get("meta", {})
    if meta.get("design_hash") not in (None, config.design_hash()):
        old = meta.get("campaign", {})
        new = config.design_dict()
        diff = [k for k in new if json.dumps(old.get(k), sort_keys=True) != json.dumps(new[k], sort_keys=True)]
        raise CampaignError(f"{config.store_path}: the store holds campaign {old.get('name')!r} of another design "
                            f"(differs in: {', '.join(diff) or '?'}); use a new store path or restore the settings")
    return store


class _RecordWriter:
    """The client-side bookkeeping of one run: turns finished tasks and streamed curves into store appends."""

    def __init__(self, config: CampaignConfig, store: CampaignStore, on_error: str):
        self.config, self.store, self.on_error = config, store, on_error
        self.counts = dict.fromkeys(RECORD_STATUSES, 0)
        self.written: set[str] = set()
        self.task_seconds: list[float] = []
        self.task_errors: list[str] = []
        self.design_hash = config.design_hash()
        self.version = code_version()
        self.consecutive_errors = 0

    def task_done(self, task: CampaignTask, res: TaskResult | None, error: BaseException | None) -> int:
        """Append a finished task's records ('failed' ones when it raised); returns the samples written."""
        config = self.config
        if error is not None:
            self.consecutive_errors += 1
            msg = f"task {task.index} ({task.sample_ids[0]} ...): {type(error).__name__}: {error}"
            self.task_errors.append(msg)
            if self.on_error == "raise" or self.consecutive_errors >= _MAX_CONSECUTIVE_TASK_ERRORS:
                why = "" if self.on_error == "raise" else f" ({self.consecutive_errors} consecutive tasks raised)"
                raise CampaignError(f"campaign {config.name} stopped{why}: {msg}") from error
            recs = task_records(config, task, None, code_version=self.version, design_hash=self.design_hash,
                                error=f"{type(error).__name__}: {error}"[:2000])
        else:
            self.consecutive_errors = 0
            self.task_seconds.append(res.compute_seconds)
            recs = task_records(config, task, res, code_version=self.version, design_hash=self.design_hash)
        recs = [r for r in recs if r["sample_id"] not in self.written]  # never twice in one run
        self.store.append_many(recs)
        for r in recs:
            self.written.add(r["sample_id"])
            self.counts[r["status"]] += 1
        return len(recs)

    def curve_done(self, task: CampaignTask, r: int, y_row, status: str, info: Mapping, *, seconds: float,
                   host: str | None = None, pid: int | None = None) -> int:
        """Append one finished curve of a running task at once (an interrupted task keeps it); returns 0 or 1.

        ``seconds`` [s] is the task's compute time up to this curve; ``host`` and ``pid`` name the process that
        computed it (default: this one).  A sample already written in this run is skipped.
        """
        sid = task.sample_ids[r]
        if sid in self.written:
            return 0
        one = dataclasses.replace(task, indices=(task.indices[r],), sample_ids=(sid,), seeds=(task.seeds[r],),
                                  params={k: np.asarray(v)[r:r + 1] for k, v in task.params.items()},
                                  diameter_um=task.replica_diameter(r), diameters_um=None, grids=None,
                                  grid=task.replica_grid(r))
        res = TaskResult(x=np.asarray(task.replica_grid(r), dtype=np.float64),
                         y=np.asarray(y_row, dtype=np.float64)[None, :],
                         status=[status], info=dict(info), compute_seconds=float(seconds),
                         host=host or socket.gethostname(), pid=os.getpid() if pid is None else int(pid))
        recs = task_records(self.config, one, res, code_version=self.version, design_hash=self.design_hash,
                            provenance={"task": task.index, "replicas_in_task": task.n_replicas, "streamed": True})
        self.store.append_many(recs)
        self.written.add(sid)
        self.counts[recs[0]["status"]] += 1
        return 1


def _run_inline(tasks: list[CampaignTask], simulate: Callable, writer: _RecordWriter, bar: _Progress) -> None:
    """Run the tasks one after another in this process, streaming finished curves where ``simulate`` can."""
    streams = _takes_on_curve(simulate)
    for task in tasks:
        t_task = time.perf_counter()

        def on_curve(r, y_row, status, info, task=task, t_task=t_task):
            """Write replica ``r``'s finished curve at once."""
            bar.update(writer.curve_done(task, r, y_row, status, info, seconds=time.perf_counter() - t_task),
                       writer.counts)

        try:
            res, err = _execute_task(simulate, task, on_curve if streams else None), None
        except Exception as exc:  # recorded or re-raised by task_done()
            res, err = None, exc
        bar.update(writer.task_done(task, res, err), writer.counts)


def run_campaign(config: CampaignConfig, *, client=None, scheduler_address: str | None = None,
                 n_workers: int | None = None, progress: bool = True, limit: int | None = None,
                 simulate: Callable[[CampaignTask], TaskResult] | None = None,
                 on_error: str = "record", diameters: Sequence[float] | None = None,
                 connect_timeout_s: float = CONNECT_TIMEOUT_S, gpus: int | None = None) -> CampaignSummary:
    """Run the pending part of a campaign's design and append one record per sample to its store.

    Parameters
    ----------
    config : CampaignConfig
        The campaign; its store is created, or opened when it holds the same design.
    client : distributed.Client, optional
        A Dask client to use (not closed here).
    scheduler_address : str, optional
        Without ``client``: 'tcp://host:port' of any Dask scheduler (e.g. a dask-jobqueue SLURMCluster);
        'inline' = in-process, no Dask; None, '' or 'local' = a ``LocalCluster(processes=True,
        threads_per_worker=1)`` started and closed here.
    n_workers : int, optional
        LocalCluster workers (default: 1 for a CUDA device, the core count for CPU).
    progress : bool
        Show a progress bar.
    limit : int, optional
        Run at most this many pending samples (a partial run; the next call continues).
    simulate : callable, optional
        Task function ``simulate(task) -> TaskResult`` (default :func:`~bubblecal.campaigns.simulate_task`;
        picklable for Dask).
    on_error : {'record', 'raise'}
        A task that raises writes 'failed' records (re-run by the next call) with 'record', or stops the
        campaign with 'raise' (records already written stay); 10 consecutive raising tasks stop it either way.
    diameters : Sequence[float], optional
        Run only the pending samples of these diameters [um] of a multi-diameter design (e.g. one process
        per diameter: the store takes whole-line appends from several processes).
    connect_timeout_s : float
        Seconds to wait for a remote scheduler [s].
    gpus : int, optional
        Run on this many GPUs of this machine: one single-threaded worker process per GPU, each pinned to its
        GPU by ``CUDA_VISIBLE_DEVICES`` and running the tasks on 'cuda:0' (:func:`~bubblecal.campaigns.
        gpu_cluster`); the GPUs are counted before anything runs.  Not with ``client``, a scheduler address or
        ``n_workers``.  On Dask, a run with fewer tasks than workers splits them (:func:`make_tasks`).

    Returns
    -------
    CampaignSummary
        Counts by status, wall vs compute seconds.

    Raises
    ------
    ValueError
        ``on_error`` or ``limit`` is invalid.
    CampaignConfigError
        A diameter in ``diameters`` is not in the design (field ``diameter_um``), ``scheduler_address`` is
        not one of :data:`~bubblecal.campaigns.SCHEDULER_CHOICES` (field ``scheduler_address``), or ``gpus``
        comes with a client, a scheduler address or ``n_workers`` (field ``gpus``).
    CampaignError
        The store holds another design, ``gpus`` exceeds this machine's GPUs (before the store is opened), the
        scheduler cannot be reached within ``connect_timeout_s``, or the campaign stopped on task errors.
    """
    if on_error not in ("record", "raise"):
        raise ValueError(f"on_error must be 'record' or 'raise', got {on_error!r}")
    if limit is not None and (not _is_int(limit) or limit < 0):
        raise ValueError(f"limit must be an integer >= 0 (samples), got {limit!r}")
    simulate = simulate or simulate_task
    scheduler_address = check_scheduler_address(scheduler_address)
    gpu_ids = None
    if gpus is not None:
        if client is not None or scheduler_address is not None or n_workers is not None:
            given = "a client" if client is not None else (f"scheduler {scheduler_address!r}" if scheduler_address
                                                           else f"{n_workers} workers")
            raise CampaignConfigError("gpus", f"{gpus} GPUs start one worker per GPU on this machine, so they "
                                              f"cannot come with {given}")
        gpu_ids = check_gpus(gpus)  # before the store is touched: too many GPUs runs nothing
    # the [sim] extra, checked before the store is opened: without it every sample would be recorded 'failed'
    if client is None and scheduler_address != "inline":
        require("distributed", "sim")
    if simulate is simulate_task and client is None and scheduler_address in (None, "inline"):
        require("warp", "sim")  # simulated on this machine (remote workers bring their own)
        require("trimesh", "sim")
    store = _open_store(config)
    design = design_points(config)
    pending = pending_indices(config, store)
    if diameters is not None:
        wanted = [float(d) for d in diameters]
        unknown = [d for d in wanted if not any(abs(d - c) < 1e-9 for c in config.diameters)]
        if unknown:
            raise CampaignConfigError("diameter_um", f"{unknown} not in the design's diameters "
                                                     f"{list(config.diameters)}")
        keep = np.isin(np.round(design["diameter_um"], 9), np.round(wanted, 9))
        pending = [i for i in pending if keep[i]]
    n_pending = len(pending)
    todo = pending[:limit] if limit is not None else pending
    run_config = config if gpu_ids is None else dataclasses.replace(config, device=GPU_WORKER_DEVICE)
    tasks = make_tasks(run_config, todo, design)
    writer = _RecordWriter(config, store, on_error)

    bar = _Progress(False, 0, config.name)
    t_start = time.perf_counter()
    startup = 0.0
    own_client = own_cluster = None
    workers = 1
    scheduler = "inline"
    check = tasks and simulate is simulate_task and config.device.startswith("cuda") and gpu_ids is None
    local = client is None and scheduler_address in (None, "inline")  # in process, or a LocalCluster here
    if check and local:
        check_device(config.device)  # before any task: a missing GPU fails every sample otherwise
    try:
        if not tasks:
            pass
        elif client is None and scheduler_address == "inline":
            bar = _Progress(progress, len(todo), config.name)
            _run_inline(tasks, simulate, writer, bar)
        else:
            if client is None:
                nw = n_workers or (1 if config.device.startswith("cuda") else (os.cpu_count() or 1))
                own_client, own_cluster = open_client(scheduler_address, gpu_ids=gpu_ids, n_workers=nw,
                                                      connect_timeout_s=connect_timeout_s)
                client = own_client
            if check and not local:  # remote workers: their devices, not the client's
                for address, n in client.run(cuda_device_count).items():
                    check_device(config.device, n, where=f"Dask worker {address}")
            workers = max(len(client.scheduler_info().get("workers", {})), 1)
            scheduler = str(client.scheduler_info().get("address", "?"))
            if len(tasks) < workers:  # e.g. one pool over every level: one task per worker instead
                tasks = make_tasks(run_config, todo, design, min_tasks=workers)
            startup = time.perf_counter() - t_start
            bar = _Progress(progress, len(todo), config.name)
            t_start = time.perf_counter()  # the wall time counts from the first submit
            _run_dask(client, tasks, simulate, writer, bar, config.name)
    finally:
        bar.close()
        wall = time.perf_counter() - t_start
        if own_client is not None:
            own_client.close()
        if own_cluster is not None:
            own_cluster.close()
    return CampaignSummary(
        name=config.name, store=str(config.store_path), n_design=config.n_design,
        n_done_before=config.n_design - n_pending, n_pending=n_pending, n_submitted=len(todo), n_tasks=len(tasks),
        n_written=len(writer.written), counts=writer.counts, store_counts=store.counts(), wall_seconds=wall,
        startup_seconds=startup, compute_seconds=float(sum(writer.task_seconds)), task_seconds=writer.task_seconds,
        n_workers=workers, scheduler=scheduler, task_errors=writer.task_errors,
        retry_statuses=config.retry_statuses)
