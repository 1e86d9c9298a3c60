"""Fidelity tiers behind one interface (physics.md section 7).

A *tier* turns a batch of shell parameter sets into loading curves on one grid:

    tier = get_tier("quasistatic", subdivisions=3)
    batch = tier.run(CurveRequest(protocol="compression", diameter_um=2.1, grid=..., params=..., seeds=...))
    batch.observable  # [R, P]: F(d) for compression (DPD force), d(F) for indentation (DPD length)

Tiers: ``explicit`` (shell + explicit water and gas, the reference), ``implicit`` (shell + ideal-gas
pressure-volume law + back pressure + Langevin thermostat on the vertices) and ``quasistatic``
(athermal energy minimisation at each load point).  Every tier batches its R replicas into the same
kernel launches and reports one status per replica from :data:`STATUSES`.

Compression convention (one place, every tier): the grid value ``d`` is the TOTAL imposed
displacement (each plate moves d/2, the gap shrinks by d) and the observable is the SUM of the
reaction forces on both plates (= 2x the force on one plate at equilibrium).  This is the convention
of the published Mirheo training data (``F_Delta.dat``): on the 2.1 um training rows our quasi-static
both-plate force / published force is flat at 0.93-0.98 over d = 0.24 ... 1.68, whereas the
alternative reading "d per plate, one-plate force" drifts from 0.98 to 1.21 along the curve
(benchmarks/RESULTS.md).  Note that an AFM measures the force on ONE plate at total displacement d;
calibrating with this convention reproduces the published study, see :mod:`bubblecal.models.mechanical`.

Bending convention (per protocol, :data:`KB_KERNEL_SCALE`): the published ``kb`` is the field's
value; our Kantor kernel gets ``kb * KB_KERNEL_SCALE[protocol]``.  Our kernel's effective rigidity is
kappa = (sqrt 3 / 2) kb (measured, benchmarks/RESULTS.md); the published indentation data follow
kappa = kb / sqrt 3 (physics.md section 6) -> scale 2/3: with it the quasi-static d(F) / published
d(F) on the 3.2 um training rows is 1.00 +- 0.02 along the whole curve (0.85 without), while the
explicit and implicit tiers (unscaled) are 18 % stiffer than the published curves.  The published
compression data follow our kernel's convention (scale 1: both-plate force / published 0.93-0.98;
scale 2/3 would give 0.80).

Indentation convention (tier setting ``indentation_convention``, :data:`INDENTATION_CONVENTIONS`): the scale 2/3
above was fitted at 3.2 um with physics.md's k = floor(0.01 N_v) loaded vertices per pole (``bubblecal-v1``,
the tiers' default; the SonoVue training sets of sessions 5-10 used it, the shipped ones since session 11 use
``mirheo``).  It compensated the loaded patch, not the
bending modulus: at 5.8 um it leaves a 10-28 % gap that depends on ka / kb.  The published curves' compliance
exponents are reproduced only by a patch of ~7 vertices per pole on the subdivision-4 mesh with the
compression data's kb (scale 1): ``mirheo``, 0.97-0.98 x the published d(F) at 3.2 and 5.8 um.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from bubblecal.data import LOADING_PROTOCOLS, SHELL_PARAMETERS, STATUSES

__all__ = [
    "TIER_NAMES",
    "DISPLACEMENT_CONVENTION",
    "KB_KERNEL_SCALE",
    "IndentationConvention",
    "INDENTATION_CONVENTIONS",
    "DEFAULT_INDENTATION_CONVENTION",
    "indentation_convention",
    "CurveRequest",
    "CurveBatch",
    "Tier",
    "register_tier",
    "get_tier",
    "QuasistaticTier",
]

TIER_NAMES = ("explicit", "implicit", "quasistatic")
#: See the module docstring: grid d = total displacement; F = sum of the forces on both plates.
DISPLACEMENT_CONVENTION = "total_displacement_both_plates_force"
#: Published kb -> our Kantor kernel's kb, per protocol (module docstring), under the default indentation
#: convention ``bubblecal-v1``; the ``mirheo`` convention maps indentation's kb like compression's (scale 1).
KB_KERNEL_SCALE = {"compression": 1.0, "indentation": 2.0 / 3.0}


@dataclass(frozen=True)
class IndentationConvention:
    """How a published indentation parameter set maps onto our kernels and loading.

    ``kb_scale``: published kb -> our Kantor kernel's kb.  The pole force F is shared by the vertices of
    :func:`bubblecal.sim.engine.pole_patches`: ``loaded_fraction`` (k = max(1, floor(loaded_fraction N_v))
    top-most and as many bottom-most vertices) or ``loaded_cap_deg`` (every vertex within that polar angle of
    a pole, the same patch on every mesh level).
    """

    name: str
    kb_scale: float
    loaded_fraction: float | None
    description: str
    loaded_cap_deg: float | None = None

    def pole_patch(self) -> dict:
        """Keyword arguments of :func:`bubblecal.sim.engine.pole_patches` (``fraction`` or ``cap_deg``)."""
        return {"fraction": self.loaded_fraction, "cap_deg": self.loaded_cap_deg}


#: Named indentation conventions (a tier setting, ``indentation_convention``; benchmarks/RESULTS.md, session 9).
#: ``bubblecal-v1``: physics.md's k = floor(0.01 N_v) (25 vertices on the subdivision-4 mesh) with kb x 2/3,
#: fitted on the 3.2 um training rows only; the SonoVue training sets of sessions 5-10 used it.  Its
#: compliance d/F ~ ka^-0.64 kb^-0.39 (3.2 um), ka^-0.68 kb^-0.46 (5.8 um) has other exponents than the
#: published curves' (ka^-0.58 kb^-0.46, ka^-0.57 kb^-0.55; 16 rows each): a loaded patch wider than the
#: published one (0.87-1.10 x the published d at 3.2 um, 0.72-1.18 x at 5.8 um, depending on ka / kb).
#: ``mirheo``: the published curves' convention as found from those exponents: the pole vertex and its first
#: ring on the subdivision-4 mesh (7 vertices, a polar cap of 4.6 deg) and the compression data's kb (scale 1).
#: The exponents then agree (ka^-0.58 kb^-0.45 at 3.2 um, ka^-0.58 kb^-0.52 at 5.8 um) and the quasi-static
#: d(F) is 0.97 x the published at both diameters (median; rows 0.97-0.98 and 0.91-1.02).  The patch is a
#: cap, not a vertex fraction: 0.28 % of the subdivision-5 mesh (28 vertices, two rings and half of the third)
#: is 4 % stiffer at 5.8 um than the same cap's 19 vertices, which reproduce subdivision 4 (session 10).
INDENTATION_CONVENTIONS = {
    "bubblecal-v1": IndentationConvention(
        "bubblecal-v1", 2.0 / 3.0, 0.01, "k = floor(0.01 N_v) loaded vertices per pole, kernel kb = 2/3 published kb"),
    "mirheo": IndentationConvention(
        "mirheo", 1.0, None, "the vertices within 4.6 deg of each pole carry the pole force (the pole vertex and "
        "its first ring at subdivision 4: 7; two rings at 5: 19), kernel kb = published kb", loaded_cap_deg=4.6),
}
DEFAULT_INDENTATION_CONVENTION = "bubblecal-v1"


def indentation_convention(name: str) -> IndentationConvention:
    """The :class:`IndentationConvention` called ``name`` (a key of :data:`INDENTATION_CONVENTIONS`)."""
    if name not in INDENTATION_CONVENTIONS:
        raise ValueError(f"indentation_convention must be one of {sorted(INDENTATION_CONVENTIONS)}, got {name!r}")
    return INDENTATION_CONVENTIONS[name]


@dataclass(frozen=True)
class CurveRequest:
    """R curves to simulate on one loading grid.

    ``protocol``: 'compression' (grid = total displacements d, DPD length) or 'indentation'
    (grid = total force per pole, DPD force).  ``diameter_um``: bubble diameter (um; radius_dpd
    from :mod:`bubblecal.data.units`).  ``params``: each of :data:`SHELL_PARAMETERS` -> array [R]
    (ka DPD modulus, kb DPD energy, b1..a4 dimensionless).  ``seeds``: one int per replica.
    ``subdivisions``: icosphere level (None = the mesh's default for the diameter).
    """

    protocol: str
    diameter_um: float
    grid: tuple[float, ...]
    params: Mapping[str, np.ndarray]
    seeds: tuple[int, ...]
    subdivisions: int | None = None

    def __post_init__(self) -> None:
        if self.protocol not in LOADING_PROTOCOLS:
            raise ValueError(f"CurveRequest.protocol must be one of {LOADING_PROTOCOLS}, got {self.protocol!r}")
        d = self.diameter_um
        if isinstance(d, bool) or not isinstance(d, (int, float)) or not (math.isfinite(d) and 0.5 <= d <= 20.0):
            raise ValueError(f"CurveRequest.diameter_um must lie in [0.5, 20] um, got {d!r}")
        grid = np.asarray(self.grid, dtype=np.float64)
        if grid.ndim != 1 or grid.size < 2 or not np.all(np.isfinite(grid)) or np.any(grid < 0) \
                or np.any(np.diff(grid) <= 0):
            raise ValueError(f"CurveRequest.grid must be >= 2 finite, non-negative, strictly increasing values, "
                             f"got {self.grid!r}")
        object.__setattr__(self, "grid", tuple(float(v) for v in grid))
        missing = [k for k in SHELL_PARAMETERS if k not in self.params]
        if missing:
            raise ValueError(f"CurveRequest.params is missing {missing} (needs {list(SHELL_PARAMETERS)})")
        arrays = {k: np.atleast_1d(np.asarray(self.params[k], dtype=np.float64)) for k in SHELL_PARAMETERS}
        sizes = {a.shape for a in arrays.values()}
        if len(sizes) != 1 or len(next(iter(sizes))) != 1:
            raise ValueError(f"CurveRequest.params arrays must all have shape [R], got "
                             f"{ {k: a.shape for k, a in arrays.items()} }")
        for k, a in arrays.items():
            if not np.all(np.isfinite(a)):
                raise ValueError(f"CurveRequest.params[{k!r}] must be finite")
        if np.any(arrays["ka"] <= 0) or np.any(arrays["kb"] < 0):
            raise ValueError("CurveRequest.params: ka must be > 0 and kb >= 0 (DPD units)")
        object.__setattr__(self, "params", arrays)
        seeds = tuple(int(s) for s in self.seeds)
        if len(seeds) != self.n_replicas:
            raise ValueError(f"CurveRequest.seeds must have one seed per replica ({self.n_replicas}), "
                             f"got {len(seeds)}")
        object.__setattr__(self, "seeds", seeds)

    @property
    def n_replicas(self) -> int:
        return int(self.params["ka"].shape[0])

    def grid_array(self) -> np.ndarray:
        """The loading grid [P] (DPD length for compression, DPD force for indentation)."""
        return np.asarray(self.grid, dtype=np.float64)

    def shell_params(self, convention: str = DEFAULT_INDENTATION_CONVENTION) -> list:
        """One :class:`bubblecal.sim.engine.ShellParams` per replica (mu = ka / 3), with the
        published kb mapped to our kernel's by :data:`KB_KERNEL_SCALE` (module docstring), or for indentation
        by the named :data:`INDENTATION_CONVENTIONS` entry."""
        from bubblecal.sim.engine import shell_params_from_arrays

        conv = indentation_convention(convention)  # checked for compression too: a typo never passes
        scale = conv.kb_scale if self.protocol == "indentation" else KB_KERNEL_SCALE[self.protocol]
        return shell_params_from_arrays(self.params, scale)


@dataclass
class CurveBatch:
    """Curves of one :class:`CurveRequest`: ``observable [R, P]`` (compression: sum of the forces on
    both plates, DPD force; indentation: pole-to-pole distance reduction, DPD length), ``status`` [R] from
    :data:`STATUSES` (non-'ok' rows may hold NaN), ``info`` (tier settings, mesh, steps), ``seconds``."""

    tier: str
    request: CurveRequest
    observable: np.ndarray
    status: list[str]
    info: dict = field(default_factory=dict)
    seconds: float = 0.0

    def __post_init__(self) -> None:
        R, P = self.request.n_replicas, len(self.request.grid)
        self.observable = np.asarray(self.observable, dtype=np.float64)
        if self.observable.shape != (R, P):
            raise ValueError(f"CurveBatch.observable must have shape {(R, P)}, got {self.observable.shape}")
        bad = [s for s in self.status if s not in STATUSES]
        if len(self.status) != R or bad:
            raise ValueError(f"CurveBatch.status must be {R} values from {STATUSES}, got {self.status!r}")

    @property
    def ok(self) -> np.ndarray:
        """Boolean mask [R] of replicas with status 'ok' and a finite curve."""
        return np.array([s == "ok" for s in self.status]) & np.all(np.isfinite(self.observable), axis=1)


class Tier(Protocol):
    """A fidelity tier: ``run(request, device)`` -> :class:`CurveBatch` (R replicas batched)."""

    name: str

    def run(self, request: CurveRequest, device: str = "cpu") -> CurveBatch: ...


_REGISTRY: dict[str, Callable[..., Tier]] = {}


def register_tier(name: str, factory: Callable[..., Tier]) -> None:
    """Make ``get_tier(name, **settings)`` call ``factory(**settings)``."""
    if name not in TIER_NAMES:
        raise ValueError(f"tier name must be one of {TIER_NAMES}, got {name!r}")
    _REGISTRY[name] = factory


def get_tier(name: str, **settings) -> Tier:
    """The tier called ``name`` (one of :data:`TIER_NAMES`), configured by ``settings``."""
    _load_builtin_tiers()
    if name not in _REGISTRY:
        raise ValueError(f"tier must be one of {sorted(_REGISTRY) or TIER_NAMES}, got {name!r}")
    return _REGISTRY[name](**settings)


def _load_builtin_tiers() -> None:
    # the MD tiers live in their own module (Warp kernels); import lazily so that configuration code
    # can validate requests without compiling anything
    if "explicit" not in _REGISTRY:
        import bubblecal.sim.protocols.md_loading  # noqa: F401  (registers explicit / implicit)


# ------------------------------------------------------------------------------------------------
# athermal quasi-static tier
# ------------------------------------------------------------------------------------------------
_QS_STATUS = {"ok": "ok", "not_converged": "unstable", "nonfinite": "failed", "ruptured": "ruptured"}


@dataclass
class QuasistaticTier:
    """Athermal quasi-static tier (:mod:`bubblecal.sim.tiers.quasistatic`): FIRE minimisation at
    every load point, ideal gas p V = p0 V0 inside (``gas_p0`` DPD pressure), analytic WCA plates.

    ``subdivisions`` overrides the request's mesh level when given; ``ftol`` (DPD force per vertex) and
    ``max_steps`` (per load point) control FIRE; ``rupture_strain`` is the max triangle area strain.
    ``max_steps`` 100,000: soft shells (k_a below ~40,000 at 3.2 um) need more than 20,000 FIRE steps at some
    points of the published indentation grid (RESULTS.md); finished replicas skip the shell kernels, so the
    batch pays little for the few that need them.
    ``self_avoid`` (default off): the vertex-vertex repulsion never acts in athermal loading on the published
    grids (curves bit-identical with and without on 6 random 3.0 um rows, benchmarks/RESULTS.md) and costs
    ~35-60 % of a force evaluation.  ``extrapolate`` starts each point from the linear prediction of the last
    two minima (1.8x fewer FIRE steps in compression, 4.8x in indentation; curves within 1.5e-3).
    ``dtype`` None = float64; ``"float32"`` / ``wp.float32`` for GPU production.
    ``schedule`` ``"async"``: each replica moves to its next load point as soon as it has relaxed (same
    iterates and curves as ``"lockstep"``, where the whole batch waits for its slowest replica at every point).
    ``max_replicas`` (async only): at most this many replicas relax at once and a slot whose curve is done takes
    the request's next parameter set (softest k_a first), so a request much larger than the GPU's batch runs at
    full occupancy: the task's wall time follows the mean FIRE work per curve instead of the slowest curve's
    (at 3.2 um the slowest needs ~100x the median).  None: one slot per replica of the request.
    ``stop_unstable``: a curve whose FIRE reaches ``max_steps`` at a point ends there ('unstable', its converged
    prefix kept, later points NaN) instead of going on; off by default (the shipped sets ran without it).  The
    slowest curves of a campaign pool are mostly such curves (benchmarks/RESULTS.md, session 11).
    ``first_load_ramp`` (indentation only): reach the first positive force through this many halvings
    (F1/2^n ... F1/2, not reported): the first point from the unloaded shape took ~58 % of all FIRE work at
    3.2 um, and 6 halvings leave 0.54x / 0.57x / 0.75x of the work at 3.2 / 3.4 / 5.8 um (benchmarks/RESULTS.md,
    session 12); 0 (default) = none, as the shipped sets ran.  Part of the design (curves move by <= 0.5 %; gates unchanged).
    ``force_mode``: ``"auto"`` (default: per-vertex gather on a GPU, per-element scatter with atomics on the CPU),
    ``"gather"`` or ``"scatter"`` (:class:`~bubblecal.sim.engine.kernels.shell.ShellForceField`): the same forces up to the
    summation order; a measurement knob (benchmarks/qs_iteration_cost.py ``--force-mode``).
    ``thermal_contact`` (compression only; indentation has no plates): the plates act through the mean force of
    each vertex's thermal normal fluctuation at temperature ``kT`` (DPD energy) against the WCA's hard-wall
    distance (:mod:`bubblecal.sim.tiers.thermal_contact`): the entropic contact force of the thermal tiers.
    """

    subdivisions: int | None = None
    gas_p0: float = 3.0
    ftol: float = 0.05
    max_steps: int = 100_000
    rupture_strain: float = 1.0
    dtype: object = None
    self_avoid: bool = False
    extrapolate: bool = True
    schedule: str = "async"
    max_replicas: int | None = None
    thermal_contact: bool = False
    kT: float = 1.0
    indentation_convention: str = DEFAULT_INDENTATION_CONVENTION
    stop_unstable: bool = False
    first_load_ramp: int = 0
    force_mode: str = "auto"
    name: str = "quasistatic"

    def __post_init__(self) -> None:
        if isinstance(self.dtype, str) and self.dtype not in ("float64", "float32"):
            raise ValueError(f"quasistatic tier: dtype must be 'float64' or 'float32', got {self.dtype!r}")
        if not isinstance(self.stop_unstable, bool):
            raise ValueError(f"quasistatic tier: stop_unstable must be true or false, got {self.stop_unstable!r}")
        r = self.first_load_ramp
        if isinstance(r, bool) or not isinstance(r, int) or not 0 <= r <= 20:
            raise ValueError(f"quasistatic tier: first_load_ramp must be an integer in [0, 20], got {r!r}")
        from bubblecal.sim.engine import FORCE_MODES

        if self.force_mode not in FORCE_MODES:
            raise ValueError(f"quasistatic tier: force_mode must be one of {FORCE_MODES}, got {self.force_mode!r}")
        if self.schedule not in ("async", "lockstep"):
            raise ValueError(f"quasistatic tier: schedule must be 'async' or 'lockstep', got {self.schedule!r}")
        if self.max_replicas is not None:
            m = self.max_replicas
            if isinstance(m, bool) or not isinstance(m, int) or m < 1:
                raise ValueError(f"quasistatic tier: max_replicas must be an integer >= 1, got {m!r}")
            if self.schedule != "async":
                raise ValueError("quasistatic tier: max_replicas needs schedule = 'async'")
        if not isinstance(self.thermal_contact, bool):
            raise ValueError(f"quasistatic tier: thermal_contact must be true or false, got {self.thermal_contact!r}")
        if not (isinstance(self.kT, (int, float)) and math.isfinite(self.kT) and self.kT > 0):
            raise ValueError(f"quasistatic tier: kT must be a positive DPD energy, got {self.kT!r}")
        indentation_convention(self.indentation_convention)

    def run(self, request: CurveRequest, device: str = "cpu",
            on_curve: Callable[[int, np.ndarray, str, dict], None] | None = None) -> CurveBatch:
        """Simulate ``request`` (see :class:`CurveRequest` for units) on Warp ``device``.

        ``on_curve(i, observable [P], status, info)``: indentation (async schedule) reports each curve as soon
        as it is finished, with the row, tier status and per-curve info the returned batch will hold (its
        ``settings`` less the batch total ``fire_evaluations``).
        """
        from bubblecal.sim.engine.mesh import mesh_for_diameter
        from bubblecal.sim.engine.system import resolve_dtype
        from bubblecal.sim.tiers.quasistatic import (
            FireSettings,
            IdealGas,
            ThermalContact,
            quasistatic_compression,
            quasistatic_indentation,
        )

        t0 = time.perf_counter()
        sub = self.subdivisions if self.subdivisions is not None else request.subdivisions
        mesh = mesh_for_diameter(request.diameter_um, sub)
        fire = FireSettings(ftol=self.ftol, max_steps=self.max_steps, stop_at_max_steps=self.stop_unstable,
                            force_mode=self.force_mode)
        gas = IdealGas(p0=self.gas_p0)
        dtype = None if self.dtype is None else resolve_dtype(self.dtype)
        common = dict(gas=gas, device=device, dtype=dtype, fire=fire, rupture_strain=self.rupture_strain,
                      extrapolate=self.extrapolate, schedule=self.schedule, max_replicas=self.max_replicas)
        grid = request.grid_array()
        conv = indentation_convention(self.indentation_convention)
        static = self._static_info(request, mesh, conv)
        params = [dataclasses.replace(p, self_avoid=bool(self.self_avoid))
                  for p in request.shell_params(conv.name)]
        if request.protocol == "compression":
            if self.first_load_ramp:
                raise ValueError("quasistatic tier: first_load_ramp applies to indentation only (compression "
                                 "refines its plate steps itself)")
            thermal = ThermalContact(kT=float(self.kT)) if self.thermal_contact else None
            res = quasistatic_compression(params, mesh, grid, thermal=thermal, **common)
            obs = res.force + res.force_bottom  # both plates (module docstring)
        else:
            row_cb = None
            if on_curve is not None:
                def row_cb(i, row):
                    on_curve(i, row["displacement"], _QS_STATUS[row["status"]],
                             {**static, "fire_steps": int(np.sum(row["fire_steps"])),
                              # per chain point (ramp sub-points included): what a max_steps choice would cut
                              "fire_steps_chain": [int(v) for v in row["fire_steps_chain"]],
                              "settings": row["settings"]})

            res = quasistatic_indentation(params, mesh, grid, pole_patch=conv.pole_patch(), on_curve=row_cb,
                                          first_load_ramp=self.first_load_ramp, **common)
            obs = res.displacement
        status = [_QS_STATUS[s] for s in res.status]
        info = {**static, "fire_steps": res.fire_steps.sum(axis=1).tolist(), "settings": res.settings}
        return CurveBatch(tier=self.name, request=request, observable=obs, status=status, info=info,
                          seconds=time.perf_counter() - t0)

    def _static_info(self, request: CurveRequest, mesh, conv: IndentationConvention) -> dict:
        """The info keys that do not depend on the simulation's outcome (one dict for batch and per-curve)."""
        return {"tier": self.name, "mesh_subdivisions": mesh.subdivisions, "n_vertices": mesh.n_vertices,
                "displacement_convention": DISPLACEMENT_CONVENTION if request.protocol == "compression" else None,
                "self_avoid": bool(self.self_avoid),
                "thermal_contact": bool(self.thermal_contact and request.protocol == "compression"),
                "indentation_convention": conv.name if request.protocol == "indentation" else None}


register_tier("quasistatic", QuasistaticTier)
