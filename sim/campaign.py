"""Training-data campaigns: a seeded design over a parameter box, executed on Dask, into a resumable store.

A campaign turns a :class:`CampaignConfig` (usually read from a TOML file by
:func:`bubblecal.workflows.campaign.load_campaign_config`) into one record per design point in an
append-only :class:`bubblecal.data.store.CampaignStore`::

    cfg = CampaignConfig(name="def21", protocol="compression", diameter_um=2.1, ranges={...},
                         n_samples=6000, seed=1, tier="quasistatic", replicas_per_task=64,
                         device="cuda", store="def21.store")
    summary = run_campaign(cfg)                 # LocalCluster(processes=True, threads_per_worker=1)
    summary = run_campaign(cfg, scheduler_address="tcp://10.0.0.5:8786")   # any Dask scheduler

Design
------
* ``design='lhs'``: :func:`lhs_design` draws ``n_samples`` points with
  ``scipy.stats.qmc.LatinHypercube(d, seed=config.seed)`` over the free parameters (``lo < hi``) and
  scales them to the ranges; a parameter with ``lo == hi`` is held fixed.  The design is a pure function
  of the config, so a restarted campaign regenerates exactly the same points.
* ``design='grid'`` (ringdown sweeps): ``ka`` takes ``ka_values`` (or ``n_samples`` values evenly spaced
  over ``ranges['ka']``), every other parameter is fixed (``lo == hi``), mu = ka/3 (the shell model's
  rule); several diameters may be listed and the design is diameters x ka values.

Sample ``i`` has the id ``f"{name}-{i:06d}"`` and the seed :func:`sample_seed` ``(config.seed, i)``.

Execution
---------
``pending`` = design minus the samples whose latest store record is final (every status except
``config.retry_statuses``, default 'failed' and 'timeout': a sample that ruptured, went unstable or
produced a non-finite curve ('invalid') is not re-run).  Pending samples are chunked into tasks of
``replicas_per_task`` replicas of one diameter -- one :class:`~bubblecal.sim.tiers.CurveRequest` (one
batched GPU launch) per task -- and submitted to Dask.  Results are collected with ``as_completed`` and
appended by the CLIENT process only (single writer; every task's records go out in one atomic,
fsync'ed append), so a killed worker (Dask reschedules its task) or an interrupted client (the next run
skips what is stored) loses and duplicates nothing.  The per-task compute time is measured inside the
task, so Dask's overhead is ``1 - sum(task compute) / (wall x workers)`` (:class:`CampaignSummary`).

``scheduler_address='inline'`` runs the same loop in-process without Dask (debugging, or a machine
without dask installed), and there the quasi-static indentation tier (async schedule) streams: each curve's
record is appended as soon as the curve is finished (provenance ``streamed``), so a large task (one long
refill pool per campaign, whose slowest curves are paid once) loses only its unfinished curves when killed.
One process per GPU: processes sharing a GPU without MPS time-slice it, and a pool's latency-bound slowest
curves then crawl (benchmarks/RESULTS.md, session 10).  Several GPUs on one host: a ``dask_cuda.LocalCUDACluster`` (one worker per GPU,
CUDA_VISIBLE_DEVICES set per worker) and its address; a plain LocalCluster puts every 'cuda' worker on GPU 0.

Clusters (SLURM via dask-jobqueue, not a dependency of bubblecal)::

    from dask_jobqueue import SLURMCluster
    cluster = SLURMCluster(queue="gpu", cores=4, memory="16GB", processes=1,
                           job_extra_directives=["--gres=gpu:1"], walltime="04:00:00")
    cluster.scale(jobs=8)                # 8 GPU jobs = 8 workers
    print(cluster.scheduler_address)     # tcp://...:PORT  ->  bubblecal sim campaign CFG --scheduler tcp://...

Units: parameter ranges in DPD units (ka DPD 2-D modulus, kb DPD energy, b1..a4 dimensionless);
diameters in um; loading grids in DPD length (compression) or DPD force (indentation); ringdown
time in DPD time and radius in DPD length (:mod:`bubblecal.data.units`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import inspect
import json
import math
import os
import re
import socket
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bubblecal.data import (
    PROTOCOLS,
    RECORD_STATUSES,
    RETRY_STATUSES,
    SHELL_PARAMETERS,
    CampaignStore,
    code_version,
    jsonable,
    make_record,
    radius_dpd_from_diameter_um,
)
from bubblecal.sim.tiers import TIER_NAMES

__all__ = [
    "DESIGNS",
    "CampaignError",
    "CampaignConfigError",
    "CampaignConfig",
    "CampaignTask",
    "TaskResult",
    "CampaignSummary",
    "StoreStatus",
    "lhs_design",
    "grid_design",
    "design_points",
    "sample_ids",
    "sample_seed",
    "make_tasks",
    "pending_indices",
    "simulate_task",
    "synthetic_simulate",
    "run_campaign",
    "store_status",
]

DESIGNS = ("lhs", "grid")
_DIAMETER_RANGE_UM = (0.5, 20.0)
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")
#: Fields that define the design (and the meaning of the records): a store refuses a config that changes them.
_DESIGN_FIELDS = ("name", "protocol", "diameter_um", "ranges", "n_samples", "seed", "tier", "tier_settings",
                  "design", "ka_values", "loading_grid", "subdivisions")
_MAX_CONSECUTIVE_TASK_ERRORS = 10


class CampaignError(RuntimeError):
    """A campaign cannot run (store of another design, missing ringdown module, repeated task errors)."""


class CampaignConfigError(ValueError):
    """A campaign setting is invalid; ``field`` names the CampaignConfig field, the message the allowed values."""

    def __init__(self, field_name: str, message: str):
        self.field = field_name
        self.detail = message
        super().__init__(f"{field_name}: {message}")


def _is_number(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def _is_int(v) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool)


# ------------------------------------------------------------------------------------------------
# configuration
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CampaignConfig:
    """One training-data campaign (validated on construction; errors name the field).

    ``name``: id prefix and default store name (letters, digits, '.', '_', '-').
    ``protocol``: 'compression' | 'indentation' | 'ringdown'.
    ``diameter_um``: bubble diameter [um] in [0.5, 20]; a tuple of diameters only for ``design='grid'``.
    ``ranges``: {ka, kb, b1, b2, a3, a4: (lo, hi)} in DPD units (ka DPD 2-D modulus > 0, kb DPD energy
    >= 0, b1..a4 dimensionless); ``lo == hi`` fixes a parameter.
    ``n_samples``: LHS points; for 'grid' the number of ka values per diameter (= len(ka_values) if given).
    ``seed``: design and per-sample seeds.  ``tier``: one of :data:`bubblecal.sim.tiers.TIER_NAMES`;
    ``tier_settings``: keyword arguments of the tier (or of ``ringdown_batch``).
    ``design``: 'lhs' | 'grid'.  ``ka_values``: explicit ka grid (DPD 2-D modulus) for 'grid'.
    ``loading_grid``: compression total displacements [DPD length] or indentation forces [DPD force];
    None = the published grid (:mod:`bubblecal.sim.protocols.loading`); must be None for ringdown.
    ``replicas_per_task``: replicas batched in one task (one GPU launch).  ``device``: 'cpu' | 'cuda[:N]'.
    ``subdivisions``: icosphere level (None = the mesh default for the diameter).
    ``store``: campaign store directory.  ``retry_statuses``: statuses a restart re-runs.
    """

    name: str
    protocol: str
    diameter_um: float | tuple[float, ...]
    ranges: Mapping[str, tuple[float, float]]
    n_samples: int
    seed: int = 0
    tier: str = "quasistatic"
    tier_settings: Mapping[str, object] = field(default_factory=dict)
    design: str = "lhs"
    ka_values: tuple[float, ...] | None = None
    loading_grid: tuple[float, ...] | None = None
    replicas_per_task: int = 16
    device: str = "cpu"
    subdivisions: int | None = None
    store: str | Path = "campaign.store"
    retry_statuses: tuple[str, ...] = RETRY_STATUSES

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        if not isinstance(self.name, str) or not _NAME_RE.match(self.name):
            raise CampaignConfigError("name", f"must be a non-empty string of letters, digits, '.', '_', '-' "
                                              f"(starting with a letter or digit), got {self.name!r}")
        if self.protocol not in PROTOCOLS:
            raise CampaignConfigError("protocol", f"must be one of {', '.join(PROTOCOLS)}, got {self.protocol!r}")
        if self.design not in DESIGNS:
            raise CampaignConfigError("design", f"must be one of {', '.join(DESIGNS)}, got {self.design!r}")
        # diameters
        d = self.diameter_um
        many = isinstance(d, (list, tuple))
        values = list(d) if many else [d]
        if not values:
            raise CampaignConfigError("diameter_um", "must name at least one diameter [um]")
        lo_d, hi_d = _DIAMETER_RANGE_UM
        for v in values:
            if not _is_number(v) or not (math.isfinite(v) and lo_d <= v <= hi_d):
                raise CampaignConfigError("diameter_um", f"must be a number in [{lo_d:g}, {hi_d:g}] um, got {v!r}")
        if many and len(set(values)) != len(values):
            raise CampaignConfigError("diameter_um", f"lists a diameter twice: {values}")
        if many and len(values) > 1 and self.design != "grid":
            raise CampaignConfigError("diameter_um", "several diameters are allowed only with design = 'grid' "
                                                     "(ringdown sweeps); use one campaign per diameter for 'lhs'")
        set_(self, "diameter_um", tuple(float(v) for v in values) if many and len(values) > 1 else float(values[0]))
        # ranges
        if not isinstance(self.ranges, Mapping):
            raise CampaignConfigError("ranges", f"must map {', '.join(SHELL_PARAMETERS)} to (lo, hi)")
        unknown = [k for k in self.ranges if k not in SHELL_PARAMETERS]
        if unknown:
            raise CampaignConfigError(f"ranges.{unknown[0]}", f"unknown parameter (allowed: "
                                                              f"{', '.join(SHELL_PARAMETERS)})")
        ranges = {}
        for k in SHELL_PARAMETERS:
            if k not in self.ranges:
                raise CampaignConfigError(f"ranges.{k}", "missing; give (lo, hi) in DPD units (lo == hi fixes it)")
            b = self.ranges[k]
            if not isinstance(b, (list, tuple)) or len(b) != 2 or not all(_is_number(x) for x in b):
                raise CampaignConfigError(f"ranges.{k}", f"must be [lo, hi] of two numbers, got {b!r}")
            lo, hi = float(b[0]), float(b[1])
            if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
                raise CampaignConfigError(f"ranges.{k}", f"must be finite with lo <= hi, got [{lo:g}, {hi:g}]")
            if k == "ka" and lo <= 0:
                raise CampaignConfigError("ranges.ka", f"lower bound must be > 0 (DPD 2-D modulus), got {lo:g}")
            if k == "kb" and lo < 0:
                raise CampaignConfigError("ranges.kb", f"lower bound must be >= 0 (DPD energy), got {lo:g}")
            ranges[k] = (lo, hi)
        set_(self, "ranges", ranges)
        # sizes
        if self.ka_values is not None:
            if self.design != "grid":
                raise CampaignConfigError("ka_values", "only used with design = 'grid'")
            kv = list(self.ka_values)
            if len(kv) < 1 or not all(_is_number(v) and math.isfinite(v) and v > 0 for v in kv):
                raise CampaignConfigError("ka_values", f"must be a non-empty list of finite ka > 0 (DPD 2-D modulus), "
                                                       f"got {self.ka_values!r}")
            if len(set(kv)) != len(kv):
                raise CampaignConfigError("ka_values", "lists a value twice")
            set_(self, "ka_values", tuple(float(v) for v in kv))
            if self.n_samples is None:
                set_(self, "n_samples", len(kv))
        if not _is_int(self.n_samples) or self.n_samples < 1:
            raise CampaignConfigError("n_samples", f"must be an integer >= 1, got {self.n_samples!r}")
        set_(self, "n_samples", int(self.n_samples))
        if self.ka_values is not None and len(self.ka_values) != self.n_samples:
            raise CampaignConfigError("n_samples", f"is {self.n_samples} but ka_values lists {len(self.ka_values)} "
                                                   "values (leave n_samples out or make them agree)")
        if not _is_int(self.seed) or not (0 <= self.seed < 2**63):
            raise CampaignConfigError("seed", f"must be an integer in [0, 2^63), got {self.seed!r}")
        free = [k for k, (lo, hi) in ranges.items() if hi > lo]
        if self.design == "lhs" and not free:
            raise CampaignConfigError("ranges", "design 'lhs' needs at least one free parameter (lo < hi)")
        if self.design == "grid":
            if [k for k in free if k != "ka"]:
                raise CampaignConfigError(f"ranges.{[k for k in free if k != 'ka'][0]}",
                                          "design 'grid' varies ka only; fix every other parameter (lo == hi)")
            if self.ka_values is None and self.n_samples > 1 and "ka" not in free:
                raise CampaignConfigError("ranges.ka", "design 'grid' with n_samples > 1 needs lo < hi for ka "
                                                       "(or explicit ka_values)")
        # execution
        if self.tier not in TIER_NAMES:
            raise CampaignConfigError("tier", f"must be one of {', '.join(TIER_NAMES)}, got {self.tier!r}")
        if not isinstance(self.tier_settings, Mapping) or not all(isinstance(k, str) for k in self.tier_settings):
            raise CampaignConfigError("tier_settings", f"must be a table of name = value, got {self.tier_settings!r}")
        set_(self, "tier_settings", dict(self.tier_settings))
        if not _is_int(self.replicas_per_task) or self.replicas_per_task < 1:
            raise CampaignConfigError("replicas_per_task", f"must be an integer >= 1, got {self.replicas_per_task!r}")
        if not isinstance(self.device, str) or not re.match(r"^(cpu|cuda(:\d+)?)$", self.device):
            raise CampaignConfigError("device", f"must be 'cpu', 'cuda' or 'cuda:N', got {self.device!r}")
        if self.subdivisions is not None and (not _is_int(self.subdivisions) or not 0 <= self.subdivisions <= 7):
            raise CampaignConfigError("subdivisions", f"must be an integer in [0, 7] or absent, got {self.subdivisions!r}")
        # loading grid
        if self.protocol == "ringdown":
            if self.loading_grid is not None:
                raise CampaignConfigError("loading_grid", "ringdown records R(t); it takes no loading grid")
        elif self.loading_grid is not None:
            g = self.loading_grid
            ok = isinstance(g, (list, tuple)) and len(g) >= 2 and all(_is_number(v) and math.isfinite(v) for v in g)
            a = np.asarray(g, dtype=float) if ok else None
            if not ok or np.any(a < 0) or np.any(np.diff(a) <= 0):
                unit = "DPD length" if self.protocol == "compression" else "DPD force"
                raise CampaignConfigError("loading_grid", f">= 2 finite, non-negative, strictly increasing values "
                                                          f"[{unit}] needed, got {g!r}")
            set_(self, "loading_grid", tuple(float(v) for v in a))
        else:
            for dia in self.diameters:
                try:
                    _published_grid(self.protocol, dia)
                except ValueError as exc:
                    raise CampaignConfigError("loading_grid", f"no published grid for {self.protocol} at {dia:g} um "
                                                              f"({exc}); give loading_grid explicitly") from None
        rs = tuple(self.retry_statuses)
        bad = [s for s in rs if s not in RECORD_STATUSES or s == "ok"]
        if bad:
            raise CampaignConfigError("retry_statuses", f"{bad} not allowed; choose from "
                                                        f"{[s for s in RECORD_STATUSES if s != 'ok']}")
        set_(self, "retry_statuses", rs)
        if not isinstance(self.store, (str, Path)) or not str(self.store):
            raise CampaignConfigError("store", f"must be a directory path, got {self.store!r}")

    # -- derived ----------------------------------------------------------------------------------
    @property
    def diameters(self) -> tuple[float, ...]:
        """The campaign's diameters [um] (one unless a grid over several)."""
        d = self.diameter_um
        return tuple(d) if isinstance(d, tuple) else (float(d),)

    @property
    def free_names(self) -> tuple[str, ...]:
        """Parameters that vary (lo < hi), in :data:`SHELL_PARAMETERS` order."""
        return tuple(k for k in SHELL_PARAMETERS if self.ranges[k][1] > self.ranges[k][0])

    @property
    def fixed(self) -> dict[str, float]:
        """Parameters held constant (lo == hi) -> value (DPD units)."""
        return {k: lo for k, (lo, hi) in self.ranges.items() if hi == lo}

    @property
    def n_design(self) -> int:
        """Number of design points (grid: ka values x diameters)."""
        return self.n_samples * len(self.diameters) if self.design == "grid" else self.n_samples

    @property
    def n_tasks(self) -> int:
        """Tasks of a full run (chunks of ``replicas_per_task`` per diameter)."""
        per = math.ceil(self.n_design / len(self.diameters) / self.replicas_per_task)
        return per * len(self.diameters)

    @property
    def store_path(self) -> Path:
        return Path(self.store)

    def grid_for(self, diameter_um: float) -> tuple[float, ...] | None:
        """The loading grid at ``diameter_um`` (None for ringdown): DPD length or DPD force."""
        if self.protocol == "ringdown":
            return None
        if self.loading_grid is not None:
            return self.loading_grid
        return _published_grid(self.protocol, diameter_um)

    def design_dict(self) -> dict:
        """The fields that define the design and the records' meaning (JSON-able)."""
        out = {}
        for k in _DESIGN_FIELDS:
            v = getattr(self, k)
            if k == "ranges":
                v = {p: list(b) for p, b in v.items()}
            elif isinstance(v, tuple):
                v = list(v)
            out[k] = v
        # scheduling-only settings give the same curves (tested bit-identical), so they do not change the design
        out["tier_settings"] = jsonable({k: v for k, v in out["tier_settings"].items()
                                         if k not in EXECUTION_ONLY_TIER_SETTINGS})
        return out

    def design_hash(self) -> str:
        """sha256 (16 hex) of :meth:`design_dict`: a store belongs to one design."""
        text = json.dumps(self.design_dict(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def to_dict(self) -> dict:
        """Every field, JSON-able (the store header keeps it)."""
        out = self.design_dict()
        out["tier_settings"] = jsonable(self.tier_settings)
        out.update(replicas_per_task=self.replicas_per_task, device=self.device, store=str(self.store),
                   retry_statuses=list(self.retry_statuses))
        return out


EXECUTION_ONLY_TIER_SETTINGS = ("schedule", "max_replicas")
"""[tier] keys that change how curves are scheduled on the device, not the curves: left out of the design hash."""


def _published_grid(protocol: str, diameter_um: float) -> tuple[float, ...]:
    from bubblecal.sim.protocols.loading import (
        published_compression_protocol,
        published_indentation_protocol,
    )

    if protocol == "compression":
        return published_compression_protocol().displacements_dpd
    return published_indentation_protocol(diameter_um).forces_dpd


# ------------------------------------------------------------------------------------------------
# design
# ------------------------------------------------------------------------------------------------
def sample_ids(config: CampaignConfig) -> list[str]:
    """Design point ids ``f"{name}-{i:06d}"`` (i = 0 .. n_design - 1)."""
    return [f"{config.name}-{i:06d}" for i in range(config.n_design)]


def sample_seed(seed: int, index: int) -> int:
    """Seed of design point ``index`` (31-bit int), derived from (campaign seed, index) via SeedSequence."""
    return int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1, dtype=np.uint32)[0] >> 1)


def lhs_design(config: CampaignConfig) -> dict[str, np.ndarray]:
    """Latin hypercube over the free parameters: {param: array[n_samples]} in DPD units.

    ``scipy.stats.qmc.LatinHypercube(d, seed=config.seed)`` with d = number of free parameters, scaled to
    ``config.ranges``; fixed parameters (lo == hi) are constant.  Deterministic in the config.
    """
    from scipy.stats import qmc

    free = config.free_names
    n = config.n_samples
    out = {k: np.full(n, config.ranges[k][0]) for k in SHELL_PARAMETERS}
    if free:
        unit = qmc.LatinHypercube(len(free), seed=config.seed).random(n)
        lo = np.array([config.ranges[k][0] for k in free])
        hi = np.array([config.ranges[k][1] for k in free])
        scaled = qmc.scale(unit, lo, hi)
        for j, k in enumerate(free):
            out[k] = scaled[:, j].astype(np.float64)
    return out


def grid_design(config: CampaignConfig) -> dict[str, np.ndarray]:
    """ka grid (``ka_values`` or ``n_samples`` evenly spaced over ranges['ka']) x diameters; every other
    parameter fixed.  Returns {param: array[n_design], 'diameter_um': array[n_design]} (diameter-major)."""
    if config.ka_values is not None:
        ka = np.asarray(config.ka_values, dtype=np.float64)
    else:
        lo, hi = config.ranges["ka"]
        ka = np.linspace(lo, hi, config.n_samples) if config.n_samples > 1 else np.array([lo])
    nd = len(config.diameters)
    out = {k: np.full(ka.size * nd, config.ranges[k][0]) for k in SHELL_PARAMETERS}
    out["ka"] = np.tile(ka, nd)
    out["diameter_um"] = np.repeat(np.asarray(config.diameters, dtype=np.float64), ka.size)
    return out


def design_points(config: CampaignConfig) -> dict[str, np.ndarray]:
    """The full design: {ka..a4 (DPD units), 'diameter_um' [um], 'seed'}: arrays [n_design]."""
    if config.design == "grid":
        out = grid_design(config)
    else:
        out = lhs_design(config)
        out["diameter_um"] = np.full(config.n_samples, config.diameters[0])
    out["seed"] = np.array([sample_seed(config.seed, i) for i in range(config.n_design)], dtype=np.int64)
    return out


# ------------------------------------------------------------------------------------------------
# tasks
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CampaignTask:
    """R replicas of one diameter, simulated together (one CurveRequest / one GPU launch).

    ``params``: {ka..a4: array[R]} (DPD units); ``grid``: loading grid (DPD length or force; None for
    ringdown); ``indices``: design indices of the replicas.
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

    @property
    def n_replicas(self) -> int:
        return len(self.sample_ids)


@dataclass
class TaskResult:
    """What a simulate function returns for a task of R replicas.

    ``x``: [P] or [R, P] loading coordinate (compression DPD length, indentation DPD force, ringdown
    DPD time); ``y``: [R, P] response (DPD force / DPD length / radius in DPD length); ``status``: R values
    from :data:`bubblecal.data.names.RECORD_STATUSES`; ``info``: JSON-able extras (a list of length R is split
    per replica); ``messages``: optional per-replica reasons.  ``compute_seconds``, ``host``, ``pid`` are
    filled in by the executor (inside the task).
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
    """Design indices still to run: no record yet, or the latest record's status is a retry status."""
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
    """An 'unstable' record (minimiser step budget reached) is worth re-running only with a larger budget:
    the quasi-static tier is deterministic, so the same budget gives the same verdict at the same cost."""
    fire = record.get("provenance", {}).get("info", {}).get("settings", {}).get("fire", {})
    ran = fire.get("max_steps") if isinstance(fire, Mapping) else None
    return budget is None or ran is None or int(ran) < int(budget)


def make_tasks(config: CampaignConfig, indices: Sequence[int], design: Mapping[str, np.ndarray] | None = None
               ) -> list[CampaignTask]:
    """Chunk design ``indices`` into tasks of at most ``replicas_per_task`` replicas of one diameter."""
    design = design if design is not None else design_points(config)
    ids = sample_ids(config)
    by_diameter: dict[float, list[int]] = {}
    for i in indices:
        by_diameter.setdefault(float(design["diameter_um"][i]), []).append(int(i))
    tasks = []
    settings = dict(config.tier_settings)
    for dia, idx in by_diameter.items():
        for start in range(0, len(idx), config.replicas_per_task):
            chunk = idx[start:start + config.replicas_per_task]
            tasks.append(CampaignTask(
                index=len(tasks), campaign=config.name, protocol=config.protocol, diameter_um=dia, tier=config.tier,
                tier_settings=settings, grid=config.grid_for(dia), device=config.device,
                subdivisions=config.subdivisions, indices=tuple(chunk), sample_ids=tuple(ids[i] for i in chunk),
                params={k: np.asarray(design[k][chunk], dtype=np.float64) for k in SHELL_PARAMETERS},
                seeds=tuple(int(design["seed"][i]) for i in chunk)))
    return tasks


# ------------------------------------------------------------------------------------------------
# simulate functions (run on the workers)
# ------------------------------------------------------------------------------------------------
def simulate_task(task: CampaignTask,
                  on_curve: Callable[[int, np.ndarray, str, dict], None] | None = None) -> TaskResult:
    """The default task: ``get_tier(task.tier, **settings).run(CurveRequest, device)`` for compression /
    indentation, ``bubblecal.sim.protocols.ringdown.ringdown_batch`` for ringdown.  ``on_curve(r, y [P],
    status, info)``: replica ``r``'s curve as soon as it is finished, where the tier reports them (quasi-static
    indentation, async schedule); the returned result holds every curve either way."""
    if task.protocol == "ringdown":
        try:
            from bubblecal.sim.protocols.ringdown import ringdown_batch
        except ModuleNotFoundError as exc:
            if exc.name != "bubblecal.sim.protocols.ringdown":
                raise
            raise CampaignError("protocol 'ringdown' needs bubblecal.sim.protocols.ringdown.ringdown_batch, "
                                "which is not in this installation yet (issue 6, ringdown protocol)") from None
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
                           params=task.params, seeds=task.seeds, subdivisions=task.subdivisions)
    if on_curve is not None and _takes_on_curve(tier.run):
        batch = tier.run(request, task.device, on_curve=on_curve)
    else:
        batch = tier.run(request, task.device)
    return TaskResult(x=request.grid_array(), y=batch.observable, status=list(batch.status), info=dict(batch.info))


def synthetic_simulate(task: CampaignTask, work_seconds: float = 0.0, sleep_seconds: float = 0.0) -> TaskResult:
    """A stand-in simulation (tests, overhead benchmark): closed-form curves y = ka-scaled power law of the
    grid, after ``work_seconds`` of busy CPU work (a compute loop) and ``sleep_seconds`` of sleep per task.
    Use ``functools.partial(synthetic_simulate, work_seconds=...)`` as ``simulate``."""
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
    """Whether ``simulate`` accepts ``on_curve`` (streams finished curves; :func:`simulate_task` does)."""
    try:
        return "on_curve" in inspect.signature(simulate).parameters
    except (TypeError, ValueError):
        return False


def _execute_task(simulate: Callable[[CampaignTask], TaskResult], task: CampaignTask,
                  on_curve: Callable | None = None) -> TaskResult:
    """Run ``simulate(task)`` and time it (inside the worker: the per-task compute seconds); ``on_curve`` is
    passed on when given (in-process runs only: a Dask worker cannot write the client's store)."""
    t0 = time.perf_counter()
    res = simulate(task) if on_curve is None else simulate(task, on_curve=on_curve)
    if not isinstance(res, TaskResult):
        res = TaskResult(x=np.asarray(res.x), y=np.asarray(res.y), status=list(res.status),
                         info=dict(getattr(res, "info", {}) or {}), messages=getattr(res, "messages", None))
    res.compute_seconds = time.perf_counter() - t0
    res.host = socket.gethostname()
    res.pid = os.getpid()
    return res


# ------------------------------------------------------------------------------------------------
# records
# ------------------------------------------------------------------------------------------------
def _replica_info(info: Mapping, r: int, n: int) -> dict:
    out = {}
    for k, v in info.items():
        if isinstance(v, (list, tuple, np.ndarray)) and len(v) == n and n > 1:
            out[k] = jsonable(v[r])
        else:
            out[k] = jsonable(v)
    return out


def _records_for(config: CampaignConfig, task: CampaignTask, res: TaskResult | None, *, code_version: str,
                 design_hash: str, error: str | None = None, provenance: Mapping | None = None) -> list[dict]:
    """One store record per replica of ``task`` ('failed' records with ``error`` when res is None);
    ``provenance`` overrides provenance keys (a streamed curve: its task's index and size)."""
    R = task.n_replicas
    radius = radius_dpd_from_diameter_um(task.diameter_um)
    recs = []
    if res is not None:
        x = np.asarray(res.x, dtype=np.float64)
        y = np.asarray(res.y, dtype=np.float64)
        x2 = np.broadcast_to(x, y.shape) if x.ndim == 1 and y.ndim == 2 and x.shape[0] == y.shape[-1] else x
        shapes_ok = y.ndim == 2 and y.shape[0] == R and x2.shape == y.shape and len(res.status) == R
    for r in range(R):
        prov = {"campaign": config.name, "design_hash": design_hash, "task": task.index, "replicas_in_task": R,
                "device": task.device, "diameter_um": task.diameter_um}
        message = None
        if res is None:
            status, xs, ys, message = "failed", [], [], error
        else:
            prov.update(host=res.host, pid=res.pid, task_compute_s=round(res.compute_seconds, 6),
                        info=_replica_info(res.info, r, R))
            if not shapes_ok:
                status, xs, ys = "invalid", [], []
                message = f"task returned x {x.shape}, y {y.shape}, {len(res.status)} statuses for {R} replicas"
            else:
                xs, ys = x2[r].tolist(), y[r].tolist()
                status = str(res.status[r])
                if res.messages is not None and res.messages[r]:
                    message = str(res.messages[r])
                if status not in RECORD_STATUSES:
                    message, status = f"unknown status {status!r} from the simulation", "failed"
                elif status == "ok" and not (np.all(np.isfinite(x2[r])) and np.all(np.isfinite(y[r]))):
                    status, message = "invalid", "simulation reported ok but the curve holds non-finite values"
        if provenance:
            prov.update(provenance)
        recs.append(make_record(
            sample_id=task.sample_ids[r], setup=config.protocol,
            params={k: float(task.params[k][r]) for k in SHELL_PARAMETERS}, radius_dpd=radius, x=xs, y=ys,
            status=status, seed=task.seeds[r], tier=task.tier, curve_id=f"{config.name}/{task.sample_ids[r]}",
            provenance=prov, message=message, code_version=code_version))
    return recs


# ------------------------------------------------------------------------------------------------
# the campaign loop
# ------------------------------------------------------------------------------------------------
@dataclass
class CampaignSummary:
    """Outcome of one :func:`run_campaign` call.

    ``counts``: statuses written by this call; ``store_counts``: the store's latest status per sample
    after it.  ``wall_seconds``: first submit to last record written (cluster start-up excluded,
    ``startup_seconds``); ``compute_seconds``: sum of the per-task compute times measured inside the
    tasks; ``efficiency`` = compute / (wall x workers); ``overhead_fraction`` = 1 - efficiency.
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
    def efficiency(self) -> float:
        denom = self.wall_seconds * max(self.n_workers, 1)
        return self.compute_seconds / denom if denom > 0 else float("nan")

    @property
    def overhead_fraction(self) -> float:
        return 1.0 - self.efficiency

    def as_dict(self) -> dict:
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


class _Progress:
    """rich progress bar (samples, ETA, status counts) or nothing."""

    def __init__(self, enabled: bool, total: int, name: str):
        self.enabled = enabled and total > 0
        self._bar = None
        if self.enabled:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self._bar = Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                                 TextColumn("samples"), TimeElapsedColumn(), TextColumn("ETA"),
                                 TimeRemainingColumn(), TextColumn("{task.fields[counts]}"))
            self._bar.start()
            self._task = self._bar.add_task(name, total=total, counts="")

    def update(self, n: int, counts: Mapping[str, int]) -> None:
        if self._bar is not None:
            text = " ".join(f"{k}={v}" for k, v in counts.items() if v)
            self._bar.update(self._task, advance=n, counts=text)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.stop()
            self._bar = None


def run_campaign(config: CampaignConfig, *, client=None, scheduler_address: str | None = None,
                 n_workers: int | None = None, progress: bool = True, limit: int | None = None,
                 simulate: Callable[[CampaignTask], TaskResult] | None = None,
                 on_error: str = "record", diameters: Sequence[float] | None = None) -> CampaignSummary:
    """Run the pending part of ``config``'s design on Dask and append one record per sample to its store.

    ``client``: a ``distributed.Client`` to use (not closed); else ``scheduler_address`` ('tcp://host:port'
    of any Dask scheduler, e.g. a dask-jobqueue SLURMCluster; 'inline' = in-process, no Dask); else ('local') a
    ``LocalCluster(processes=True, threads_per_worker=1, n_workers=n_workers)`` started and closed here
    (default workers: 1 for a CUDA device, the core count for CPU).  ``limit``: run at most this many
    pending samples (a partial run; the next call continues).  ``simulate(task) -> TaskResult``: the task
    function (default :func:`simulate_task`; must be picklable for Dask).  ``on_error``: a task that raises
    writes 'failed' records (re-run by the next call) with 'record', or stops the campaign with 'raise'
    (records already written stay); 10 consecutive raising tasks stop it either way.  ``diameters`` [um]:
    run only the pending samples of these diameters of a multi-diameter design (e.g. one process per
    diameter sharing one GPU: the store takes whole-line appends from several processes).
    Returns a :class:`CampaignSummary` (counts by status, wall vs compute seconds).
    """
    if on_error not in ("record", "raise"):
        raise ValueError(f"on_error must be 'record' or 'raise', got {on_error!r}")
    if limit is not None and (not _is_int(limit) or limit < 0):
        raise ValueError(f"limit must be an integer >= 0 (samples), got {limit!r}")
    simulate = simulate or simulate_task
    if scheduler_address in ("", "local"):
        scheduler_address = None
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
    tasks = make_tasks(config, todo, design)
    counts = dict.fromkeys(RECORD_STATUSES, 0)
    written: set[str] = set()
    task_seconds: list[float] = []
    task_errors: list[str] = []
    design_hash = config.design_hash()
    version = code_version()
    consecutive_errors = 0

    def handle(task: CampaignTask, res: TaskResult | None, error: BaseException | None) -> int:
        nonlocal consecutive_errors
        if error is not None:
            consecutive_errors += 1
            msg = f"task {task.index} ({task.sample_ids[0]} ...): {type(error).__name__}: {error}"
            task_errors.append(msg)
            if on_error == "raise" or consecutive_errors >= _MAX_CONSECUTIVE_TASK_ERRORS:
                why = "" if on_error == "raise" else f" ({consecutive_errors} consecutive tasks raised)"
                raise CampaignError(f"campaign {config.name} stopped{why}: {msg}") from error
            recs = _records_for(config, task, None, code_version=version, design_hash=design_hash,
                                error=f"{type(error).__name__}: {error}"[:2000])
        else:
            consecutive_errors = 0
            task_seconds.append(res.compute_seconds)
            recs = _records_for(config, task, res, code_version=version, design_hash=design_hash)
        recs = [r for r in recs if r["sample_id"] not in written]  # never twice in one run
        store.append_many(recs)
        for r in recs:
            written.add(r["sample_id"])
            counts[r["status"]] += 1
        return len(recs)

    def stream(task: CampaignTask, t_task: float, r: int, y_row, status: str, info: Mapping) -> int:
        # one finished curve of a running task, written at once: an interrupted task keeps it (resume key)
        sid = task.sample_ids[r]
        if sid in written:
            return 0
        one = dataclasses.replace(task, indices=(task.indices[r],), sample_ids=(sid,), seeds=(task.seeds[r],),
                                  params={k: np.asarray(v)[r:r + 1] for k, v in task.params.items()})
        res = TaskResult(x=np.asarray(task.grid, dtype=np.float64), y=np.asarray(y_row, dtype=np.float64)[None, :],
                         status=[status], info=dict(info), compute_seconds=time.perf_counter() - t_task,
                         host=socket.gethostname(), pid=os.getpid())
        recs = _records_for(config, one, res, code_version=version, design_hash=design_hash,
                            provenance={"task": task.index, "replicas_in_task": task.n_replicas, "streamed": True})
        store.append_many(recs)
        written.add(sid)
        counts[recs[0]["status"]] += 1
        return 1

    bar = _Progress(False, 0, config.name)
    t_start = time.perf_counter()
    startup = 0.0
    own_client = own_cluster = None
    workers = 1
    scheduler = "inline"
    try:
        if not tasks:
            pass
        elif client is None and scheduler_address == "inline":
            bar = _Progress(progress, len(todo), config.name)
            streams = _takes_on_curve(simulate)
            for task in tasks:
                t_task = time.perf_counter()

                def on_curve(r, y_row, status, info, task=task, t_task=t_task):
                    bar.update(stream(task, t_task, r, y_row, status, info), counts)

                try:
                    res, err = _execute_task(simulate, task, on_curve if streams else None), None
                except Exception as exc:  # recorded or re-raised by handle()
                    res, err = None, exc
                bar.update(handle(task, res, err), counts)
        else:
            from distributed import Client, LocalCluster, as_completed

            if client is None:
                if scheduler_address:
                    own_client = client = Client(scheduler_address)
                else:
                    import logging

                    nw = n_workers or (1 if config.device.startswith("cuda") else (os.cpu_count() or 1))
                    own_cluster = LocalCluster(n_workers=nw, processes=True, threads_per_worker=1,
                                               dashboard_address=":0", silence_logs=logging.ERROR)
                    own_client = client = Client(own_cluster)
            workers = max(len(client.scheduler_info().get("workers", {})), 1)
            scheduler = str(client.scheduler_info().get("address", "?"))
            startup = time.perf_counter() - t_start
            bar = _Progress(progress, len(todo), config.name)
            t_start = time.perf_counter()
            token = hashlib.sha256(f"{time.time_ns()}-{os.getpid()}".encode()).hexdigest()[:8]
            futures = {}
            for task in tasks:
                fut = client.submit(_execute_task, simulate, task, key=f"{config.name}-t{task.index:05d}-{token}",
                                    pure=False)
                futures[fut.key] = (fut, task)
            try:
                for fut in as_completed([f for f, _ in futures.values()]):
                    task = futures[fut.key][1]
                    try:
                        res, err = fut.result(), None
                    except Exception as exc:  # recorded or re-raised by handle()
                        res, err = None, exc
                    bar.update(handle(task, res, err), counts)
                    fut.release()
            except BaseException:
                client.cancel([f for f, _ in futures.values()])
                raise
    finally:
        bar.close()
        wall = time.perf_counter() - t_start
        if own_client is not None:
            own_client.close()
        if own_cluster is not None:
            own_cluster.close()
    summary = CampaignSummary(
        name=config.name, store=str(config.store_path), n_design=config.n_design,
        n_done_before=config.n_design - n_pending, n_pending=n_pending, n_submitted=len(todo), n_tasks=len(tasks),
        n_written=len(written), counts=counts, store_counts=store.counts(), wall_seconds=wall,
        startup_seconds=startup, compute_seconds=float(sum(task_seconds)), task_seconds=task_seconds,
        n_workers=workers, scheduler=scheduler, task_errors=task_errors, retry_statuses=config.retry_statuses)
    return summary


# ------------------------------------------------------------------------------------------------
# status of a store
# ------------------------------------------------------------------------------------------------
@dataclass
class StoreStatus:
    """Counts of a campaign store: latest status per sample, design size (from the header), pending."""

    path: str
    name: str | None
    n_design: int | None
    counts: dict[str, int]
    n_records: int
    n_lines_skipped: int
    retry_statuses: tuple[str, ...]
    config: dict
    pending: int | None = None  # from the current config's pending_indices, when given

    @property
    def n_samples_stored(self) -> int:
        return sum(self.counts.values())

    @property
    def n_final(self) -> int:
        return sum(v for k, v in self.counts.items() if k not in self.retry_statuses)

    @property
    def n_pending(self) -> int | None:
        if self.pending is not None:
            return self.pending
        return None if self.n_design is None else self.n_design - self.n_final

    def as_dict(self) -> dict:
        return {"path": self.path, "name": self.name, "n_design": self.n_design, "counts": dict(self.counts),
                "n_records": self.n_records, "n_lines_skipped": self.n_lines_skipped, "n_final": self.n_final,
                "n_pending": self.n_pending}


def store_status(path: str | Path, retry_statuses: Sequence[str] | None = None) -> StoreStatus:
    """Read a campaign store (directory or .jsonl) and count statuses; pending needs the campaign header.

    ``retry_statuses``: the statuses counted as pending (default: those of the config the store was created
    with; pass the current config's when it retries more, e.g. 'unstable')."""
    store = CampaignStore(path)
    n_records = sum(1 for _ in store.iter_records())
    skipped = len(store.problems)
    meta = store.header().get("meta", {}) if store.header_path is not None else {}
    cfg = meta.get("campaign", {}) or {}
    n_design = None
    if isinstance(cfg.get("n_samples"), int):
        d = cfg.get("diameter_um")
        n_diameters = len(d) if isinstance(d, list) else 1
        n_design = cfg["n_samples"] * (n_diameters if cfg.get("design") == "grid" else 1)
    retry = tuple(cfg.get("retry_statuses", RETRY_STATUSES)) if retry_statuses is None else tuple(retry_statuses)
    return StoreStatus(path=str(path), name=cfg.get("name"), n_design=n_design, counts=store.counts(),
                       n_records=n_records, n_lines_skipped=skipped, retry_statuses=retry, config=cfg)
