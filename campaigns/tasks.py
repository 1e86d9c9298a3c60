"""Campaign tasks: chunks of design points simulated together, what is still pending, and the task functions.

A task is R replicas of one diameter, simulated in one :class:`~bubblecal.sim.tiers.CurveRequest` (one batched
GPU launch).  :func:`simulate_task` is the default task function; :func:`synthetic_simulate` is a closed-form
stand-in for tests and the overhead benchmark.  Task functions run on the Dask workers, so they and their
arguments must be picklable.
"""

from __future__ import annotations

import inspect
import math
import os
import socket
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from bubblecal.campaigns.config import CampaignConfig
from bubblecal.campaigns.design import design_points, sample_ids
from bubblecal.campaigns.errors import CampaignError
from bubblecal.data import RECORD_STATUSES, SHELL_PARAMETERS, CampaignStore

__all__ = ["CampaignTask", "TaskResult", "make_tasks", "pending_indices", "simulate_task", "synthetic_simulate"]


@dataclass(frozen=True)
class CampaignTask:
    """R replicas, simulated together (one CurveRequest / one GPU launch): of one diameter, or of several
    diameter levels on one mesh level (``diameters_um``, :attr:`CampaignConfig.pools_levels`).

    Parameters
    ----------
    index : int
        Task number within one :func:`~bubblecal.campaigns.run_campaign` call.
    campaign : str
        Campaign name.
    protocol : str
        'compression', 'indentation' or 'ringdown'.
    diameter_um : float
        Bubble diameter [um].
    tier : str
        Tier name (:data:`bubblecal.sim.tiers.TIER_NAMES`).
    tier_settings : Mapping[str, object]
        Keyword arguments of the tier (ringdown: of ``ringdown_batch``).
    grid : tuple of float or None
        Loading grid: compression total displacements [DPD length], indentation forces [DPD force];
        None for ringdown.
    device : str
        'cpu', 'cuda' or 'cuda:N'.
    subdivisions : int or None
        Icosphere level (None = the mesh default).
    indices : tuple of int
        Design indices of the replicas.
    sample_ids : tuple of str
        Their sample ids.
    params : Mapping[str, numpy.ndarray]
        ``{ka..a4: array[R]}`` in DPD units.
    seeds : tuple of int
        Per-replica seeds.
    diameters_um : tuple of float, optional
        Per-replica diameters [um] of a task over several levels (``diameter_um`` is then the first); None:
        every replica at ``diameter_um``.
    grids : tuple of tuple of float, optional
        Per-replica loading grids of such a task when the grid scales with the diameter (``grid`` is then the
        first replica's); None: ``grid`` for every replica.
    """

    index: int
    campaign: str
    protocol: str
    diameter_um: float
    tier: str
    tier_settings: Mapping[str, object]
    grid: tuple[float, ...] | None
    device: str
    subdivisions: int | None
    indices: tuple[int, ...]
    sample_ids: tuple[str, ...]
    params: Mapping[str, np.ndarray]
    seeds: tuple[int, ...]
    diameters_um: tuple[float, ...] | None = None
    grids: tuple[tuple[float, ...], ...] | None = None

    @property
    def n_replicas(self) -> int:
        """Number of replicas R."""
        return len(self.sample_ids)

    def replica_diameter(self, r: int) -> float:
        """Diameter [um] of replica ``r``."""
        return self.diameter_um if self.diameters_um is None else self.diameters_um[r]

    def replica_grid(self, r: int) -> tuple[float, ...] | None:
        """Loading grid of replica ``r`` (DPD length or DPD force; None for ringdown)."""
        return self.grid if self.grids is None else self.grids[r]


@dataclass
class TaskResult:
    """What a task function returns for a task of R replicas.

    Parameters
    ----------
    x : numpy.ndarray
        [P] or [R, P] loading coordinate: compression DPD length, indentation DPD force, ringdown DPD time.
    y : numpy.ndarray
        [R, P] response: DPD force (compression), DPD length (indentation depth), radius in DPD length (ringdown).
    status : list of str
        R values from :data:`bubblecal.data.names.RECORD_STATUSES`.
    info : dict
        JSON-able extras; a list of length R is split per replica.
    messages : list of str or None, optional
        Per-replica reasons.
    compute_seconds : float
        Task compute time [s], filled in by the executor inside the task.
    host : str
        Host name, filled in by the executor.
    pid : int
        Worker process id, filled in by the executor.
    """

    x: np.ndarray
    y: np.ndarray
    status: list[str]
    info: dict = field(default_factory=dict)
    messages: list[str | None] | None = None
    compute_seconds: float = 0.0
    host: str = ""
    pid: int = 0


def pending_indices(config: CampaignConfig, store: CampaignStore | None = None) -> list[int]:
    """Design indices still to run: no record yet, or the latest record's status is a retry status.

    An 'unstable' record (minimiser step budget reached) counts as pending only when ``retry_statuses``
    holds 'unstable' and it ran with a smaller step budget than the config's.

    Parameters
    ----------
    config : CampaignConfig
        The campaign.
    store : CampaignStore, optional
        Its store (default: ``CampaignStore(config.store_path)``); a store that does not exist yet has
        every index pending.

    Returns
    -------
    list of int
        Pending design indices, increasing.
    """
    store = store if store is not None else CampaignStore(config.store_path)
    done: set[str] = set()
    if (store.header_path is None and store.records_path.exists()) or (
            store.header_path is not None and store.header_path.exists()):
        final = [s for s in RECORD_STATUSES if s not in config.retry_statuses]
        done = store.finished_ids(statuses=final)
        if "unstable" in config.retry_statuses:
            budget = _fire_budget(config)
            done |= {r["sample_id"] for r in store.read(statuses=["unstable"], warn=False)
                     if not _unstable_retry_due(r, budget)}
    return [i for i, sid in enumerate(sample_ids(config)) if sid not in done]


def _fire_budget(config: CampaignConfig) -> int | None:
    """The minimiser's step budget per load point the config would run with (None: the tier has none)."""
    if "max_steps" in config.tier_settings:
        return int(config.tier_settings["max_steps"])
    try:
        from bubblecal.sim.tiers import get_tier

        return getattr(get_tier(config.tier, **config.tier_settings), "max_steps", None)
    except Exception:  # tier not importable here (no Warp): retry as configured
        return None


def _unstable_retry_due(record: Mapping, budget: int | None) -> bool:
    """Whether an 'unstable' record ran with a smaller step budget than ``budget`` (or either is unknown)."""
    # the quasi-static tier is deterministic: the same budget gives the same verdict at the same cost
    fire = record.get("provenance", {}).get("info", {}).get("settings", {}).get("fire", {})
    ran = fire.get("max_steps") if isinstance(fire, Mapping) else None
    return budget is None or ran is None or int(ran) < int(budget)


def make_tasks(config: CampaignConfig, indices: Sequence[int], design: Mapping[str, np.ndarray] | None = None,
               min_tasks: int = 1) -> list[CampaignTask]:
    """Chunk design indices into tasks of at most ``replicas_per_task`` replicas of one diameter.

    When the chunks are fewer than ``min_tasks`` (e.g. one task over every level and two GPUs), each group is
    dealt round-robin into near-equal tasks instead, so every task gets the same mix of diameters (the same cost)
    and no worker idles.

    Parameters
    ----------
    config : CampaignConfig
        The campaign.
    indices : Sequence[int]
        Design indices to run (e.g. :func:`pending_indices`).
    design : Mapping[str, numpy.ndarray], optional
        :func:`~bubblecal.campaigns.design_points` of ``config`` (computed when not given).
    min_tasks : int
        Tasks to make at least (as many as there are workers), where the indices allow.

    Returns
    -------
    list of CampaignTask
        Tasks numbered from 0, grouped by diameter in order of first appearance; when
        :attr:`CampaignConfig.pools_levels`, chunks of the indices sorted by diameter, over the levels.
    """
    design = design if design is not None else design_points(config)
    ids = sample_ids(config)
    groups: dict[float | None, list[int]] = {}
    for i in indices:
        groups.setdefault(None if config.pools_levels else float(design["diameter_um"][i]), []).append(int(i))
    if None in groups:  # chunks of neighbouring levels: a compression chunk then mostly has one chain length
        groups[None].sort(key=lambda i: (float(design["diameter_um"][i]), i))
    tasks = []
    settings = dict(config.tier_settings)
    rpt = config.replicas_per_task
    n_regular = sum(math.ceil(len(idx) / rpt) for idx in groups.values())
    for key, idx in groups.items():
        if n_regular >= min_tasks:
            chunks = [idx[start:start + rpt] for start in range(0, len(idx), rpt)]
        else:  # deal each group over its share of the tasks
            k = min(len(idx), max(math.ceil(len(idx) / rpt), math.ceil(min_tasks * len(idx) / len(indices))))
            chunks = [idx[j::k] for j in range(k)]
        for chunk in chunks:
            sizes = tuple(float(design["diameter_um"][i]) for i in chunk)
            dia = sizes[0] if key is None else key
            tasks.append(CampaignTask(
                index=len(tasks), campaign=config.name, protocol=config.protocol, diameter_um=dia, tier=config.tier,
                tier_settings=settings, grid=config.grid_for(dia), device=config.device,
                subdivisions=config.subdivisions, indices=tuple(chunk), sample_ids=tuple(ids[i] for i in chunk),
                params={k: np.asarray(design[k][chunk], dtype=np.float64) for k in SHELL_PARAMETERS},
                seeds=tuple(int(design["seed"][i]) for i in chunk), diameters_um=sizes if key is None else None,
                grids=tuple(config.grid_for(d) for d in sizes) if key is None and config.loading_fractions else None))
    return tasks


def simulate_task(task: CampaignTask,
                  on_curve: Callable[[int, np.ndarray, str, dict], None] | None = None) -> TaskResult:
    """The default task function: simulate every replica of a task with its tier.

    Compression and indentation run ``get_tier(task.tier, **task.tier_settings).run(CurveRequest, device)``;
    ringdown runs ``bubblecal.sim.protocols.ringdown.ringdown_batch``.

    Parameters
    ----------
    task : CampaignTask
        The task.
    on_curve : callable, optional
        ``on_curve(r, y [P], status, info)``: replica ``r``'s curve as soon as it is finished, where the tier
        reports finished curves (quasi-static indentation, async schedule).

    Returns
    -------
    TaskResult
        Every replica's curve (whether or not it was also passed to ``on_curve``).

    Raises
    ------
    CampaignError
        Ringdown without the ringdown protocol module.
    """
    if task.protocol == "ringdown":
        try:
            from bubblecal.sim.protocols.ringdown import ringdown_batch
        except ModuleNotFoundError as exc:
            if exc.name != "bubblecal.sim.protocols.ringdown":
                raise
            raise CampaignError("protocol 'ringdown' needs bubblecal.sim.protocols.ringdown.ringdown_batch, "
                                "which is not in this installation (ringdown protocol)") from None
        settings = dict(task.tier_settings)
        if task.subdivisions is not None:
            settings.setdefault("subdivisions", task.subdivisions)
        res = ringdown_batch(task.diameter_um, {k: np.asarray(v) for k, v in task.params.items()}, list(task.seeds),
                             tier=task.tier, device=task.device, **settings)
        status = [str(s) for s in res.status]
        return TaskResult(x=np.asarray(res.t, dtype=np.float64), y=np.asarray(res.radius, dtype=np.float64),
                          status=status, info=dict(getattr(res, "info", {}) or {}))
    from bubblecal.sim.tiers import CurveRequest, get_tier

    tier = get_tier(task.tier, **dict(task.tier_settings))
    request = CurveRequest(protocol=task.protocol, diameter_um=task.diameter_um, grid=task.grid,
                           params=task.params, seeds=task.seeds, subdivisions=task.subdivisions,
                           diameters_um=task.diameters_um, grids=None if task.grids is None else np.array(task.grids))
    if on_curve is not None and _takes_on_curve(tier.run):
        batch = tier.run(request, task.device, on_curve=on_curve)
    else:
        batch = tier.run(request, task.device)
    return TaskResult(x=request.grid_array(), y=batch.observable, status=list(batch.status), info=dict(batch.info))


def synthetic_simulate(task: CampaignTask, work_seconds: float = 0.0, sleep_seconds: float = 0.0) -> TaskResult:
    """A stand-in task function with closed-form curves (tests, overhead benchmark).

    y = ka-scaled power law of the grid (16 points over [0, 10] when the task has no grid), after busy CPU
    work and sleep.  Use ``functools.partial(synthetic_simulate, work_seconds=...)`` as ``simulate``.

    Parameters
    ----------
    task : CampaignTask
        The task.
    work_seconds : float
        Busy CPU work (a compute loop) per task [s].
    sleep_seconds : float
        Sleep per task [s].

    Returns
    -------
    TaskResult
        Status 'ok' for every replica; ``info = {"synthetic": True, "acc": True}``.
    """
    t_end = time.perf_counter() + float(work_seconds)
    acc = 0.0
    while time.perf_counter() < t_end:
        acc += float(np.sum(np.sqrt(np.arange(2000.0))))
    if sleep_seconds > 0:
        time.sleep(float(sleep_seconds))
    grid = np.asarray(task.grid if task.grid is not None else np.linspace(0.0, 10.0, 16), dtype=np.float64)
    p = task.params
    y = (p["ka"][:, None] * 1e-2 * grid[None, :] ** 1.5 * (1.0 + 0.1 * p["b1"][:, None])
         + p["kb"][:, None] * 1e-3 * grid[None, :])
    return TaskResult(x=grid, y=y, status=["ok"] * task.n_replicas, info={"synthetic": True, "acc": acc > 0})


def _takes_on_curve(simulate: Callable) -> bool:
    """Whether a task function accepts ``on_curve`` (streams finished curves; :func:`simulate_task` does).

    Parameters
    ----------
    simulate : callable
        A task function (or a tier's ``run``).

    Returns
    -------
    bool
        True when its signature has an ``on_curve`` parameter.
    """
    try:
        return "on_curve" in inspect.signature(simulate).parameters
    except (TypeError, ValueError):
        return False


def _execute_task(simulate: Callable[[CampaignTask], TaskResult], task: CampaignTask,
                  on_curve: Callable | None = None) -> TaskResult:
    """Run a task function on a task and time it inside the worker.

    Parameters
    ----------
    simulate : callable
        The task function, ``simulate(task) -> TaskResult`` (any object with x, y, status, [info, messages]).
    task : CampaignTask
        The task.
    on_curve : callable, optional
        Passed on to ``simulate`` when given (in process it writes the curve; on a Dask worker it sends the curve
        to the client, :mod:`bubblecal.campaigns.streaming`).

    Returns
    -------
    TaskResult
        The result, with ``compute_seconds`` [s], ``host`` and ``pid`` filled in.
    """
    t0 = time.perf_counter()
    res = simulate(task) if on_curve is None else simulate(task, on_curve=on_curve)
    if not isinstance(res, TaskResult):
        res = TaskResult(x=np.asarray(res.x), y=np.asarray(res.y), status=list(res.status),
                         info=dict(getattr(res, "info", {}) or {}), messages=getattr(res, "messages", None))
    res.compute_seconds = time.perf_counter() - t0
    res.host = socket.gethostname()
    res.pid = os.getpid()
    return res
