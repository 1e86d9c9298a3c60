"""The quasi-static tier behind :func:`bubblecal.sim.tiers.get_tier` (``get_tier("quasistatic", **settings)``)."""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bubblecal.sim.tiers.base import CurveBatch, CurveRequest, register_tier
from bubblecal.sim.tiers.conventions import (
    DEFAULT_INDENTATION_CONVENTION,
    DISPLACEMENT_CONVENTION,
    IndentationConvention,
    indentation_convention,
)
from bubblecal.sim.tiers.quasistatic.collapse import check_max_depth_fall
from bubblecal.sim.tiers.quasistatic.settings import (
    MINIMIZERS,
    SCHEDULES,
    STATUS_COLLAPSED,
    STATUS_NONFINITE,
    STATUS_NOT_CONVERGED,
    STATUS_OK,
    STATUS_RUPTURED,
)

__all__ = ["QuasistaticTier"]

#: quasi-static verdict -> bubblecal.data.names.STATUSES
_QS_STATUS = {STATUS_OK: "ok", STATUS_NOT_CONVERGED: "unstable", STATUS_NONFINITE: "failed",
              STATUS_RUPTURED: "ruptured", STATUS_COLLAPSED: "unstable"}


@dataclass
class QuasistaticTier:
    """Athermal quasi-static tier: FIRE minimisation at every load point (:mod:`bubblecal.sim.tiers.quasistatic`),
    ideal gas p V = p0 V0 inside, analytic WCA plates.  Finished replicas skip the shell kernels, so a batch pays
    little for the few curves that need many FIRE steps.

    Parameters
    ----------
    subdivisions : int, optional
        Icosphere level; overrides the request's when given.
    gas_p0 : float
        Gas pressure at the reference volume (DPD pressure).
    overpressure : float
        Gas pressure minus ambient pressure at the reference volume (DPD pressure; 0 = the stress-free sphere
        is force-free).  A positive value inflates the shell until its membrane tension balances it, a
        pre-tension that stiffens the shell; for comparisons between tiers (docs/physics.md, "Reference pressure
        balance").
    ftol : float
        FIRE convergence: per-vertex force norm (DPD force).
    max_steps : int
        FIRE iterations per load point (soft shells need many at some points of the published indentation grid).
    rupture_strain : float
        Max triangle area strain above which a replica is 'ruptured'.
    dtype : str or warp scalar type, optional
        None = float64; ``"float32"`` / ``wp.float32`` for GPU production.
    self_avoid : bool
        The vertex-vertex repulsion (off by default: it never acts in athermal loading on the published grids).
    extrapolate : bool
        Start each point from the linear prediction of the last two minima (fewer FIRE steps, the same minima
        within ``ftol``).
    schedule : str
        ``"async"``: each replica moves to its next load point as soon as it has relaxed (same iterates and
        curves as ``"lockstep"``, where the whole batch waits for its slowest replica at every point).
    max_replicas : int, optional
        (async only) At most this many replicas relax at once and a slot whose curve is done takes the request's
        next parameter set (softest k_a first), so a request much larger than the GPU's batch runs at full
        occupancy: the wall time follows the mean FIRE work per curve instead of the slowest curve's.  None: one
        slot per replica of the request.
    thermal_contact : bool
        (compression only; indentation has no plates) The plates act through the mean force of each vertex's
        thermal normal fluctuation at temperature ``kT`` against the WCA's hard-wall distance
        (:mod:`bubblecal.sim.tiers.quasistatic.thermal_contact`): the entropic contact force of the thermal tiers.
    kT : float
        Thermal energy of the thermal contact (DPD energy).
    indentation_convention : str
        A key of :data:`bubblecal.sim.tiers.INDENTATION_CONVENTIONS`.
    stop_unstable : bool
        A curve whose FIRE reaches ``max_steps`` at a point ends there ('unstable', its converged prefix kept,
        later points NaN) instead of going on; off by default (the shipped training sets ran without it).
    first_load_ramp : int
        (indentation only) Reach the first positive force through this many halvings (F1/2^n ... F1/2, not
        reported), in [0, 20]; 0 (default, as the shipped training sets ran) = none.
    force_mode : str
        ``"auto"`` (per-vertex gather on a GPU, per-element scatter with atomics on the CPU), ``"gather"`` or
        ``"scatter"`` (:class:`bubblecal.sim.engine.kernels.shell.ShellForceField`): the same forces up to the
        summation order; a measurement knob (benchmarks/qs_iteration_cost.py ``--force-mode``).
    sync_every : int, optional
        Minimiser iterations between the host's status reads (one CUDA-graph replay); None: the minimiser's default
        (25 on CUDA, 4 on the CPU).  Scheduling only: the same iterates and curves.  A converged replica waits up to
        this many iterations before it is measured and moves on, which matters when points take few iterations.
    max_depth_fall : float, optional
        (indentation only) The collapse verdict, a fraction in (0, 1): a curve whose depth falls below its deepest
        earlier point by more than this fraction of it ends there ('unstable', its prefix kept, later points NaN):
        under a rising force a stable shell only gets deeper, so such a minimum lies on another branch
        (:mod:`bubblecal.sim.tiers.quasistatic.collapse`).  None (default; the FIRE training sets ran without it):
        no verdict.
    minimizer : str
        ``"fire"`` (default; the shipped training sets ran with it) or ``"cg"``, the force-only nonlinear
        conjugate gradient (:class:`FireSettings`): the same minima within ``ftol`` with far fewer force
        evaluations on buckled shells, so a campaign on large bubbles runs several times faster; ``max_steps``
        then counts force evaluations.
    name : str
        The tier's name.

    Raises
    ------
    ValueError
        If a setting is invalid (the message names it).
    """

    subdivisions: int | None = None
    gas_p0: float = 3.0
    overpressure: float = 0.0
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
    sync_every: int | None = None
    max_depth_fall: float | None = None
    minimizer: str = "fire"
    name: str = "quasistatic"

    def __post_init__(self) -> None:
        if isinstance(self.dtype, str) and self.dtype not in ("float64", "float32"):
            raise ValueError(f"quasistatic tier: dtype must be 'float64' or 'float32', got {self.dtype!r}")
        if not isinstance(self.stop_unstable, bool):
            raise ValueError(f"quasistatic tier: stop_unstable must be true or false, got {self.stop_unstable!r}")
        r = self.first_load_ramp
        if isinstance(r, bool) or not isinstance(r, int) or not 0 <= r <= 20:
            raise ValueError(f"quasistatic tier: first_load_ramp must be an integer in [0, 20], got {r!r}")
        # the Warp-free module: constructing a tier imports no Warp
        from bubblecal.sim.engine import FORCE_MODES

        if self.force_mode not in FORCE_MODES:
            raise ValueError(f"quasistatic tier: force_mode must be one of {FORCE_MODES}, got {self.force_mode!r}")
        n = self.sync_every
        if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 1):
            raise ValueError(f"quasistatic tier: sync_every must be an integer >= 1 or omitted, got {n!r}")
        try:
            check_max_depth_fall(self.max_depth_fall)
        except ValueError as exc:
            raise ValueError(f"quasistatic tier: {exc}") from None
        if self.minimizer not in MINIMIZERS:
            raise ValueError(f"quasistatic tier: minimizer must be one of {MINIMIZERS}, got {self.minimizer!r}")
        if self.schedule not in SCHEDULES:
            raise ValueError(f"quasistatic tier: schedule must be 'async' or 'lockstep', got {self.schedule!r}")
        if self.max_replicas is not None:
            m = self.max_replicas
            if isinstance(m, bool) or not isinstance(m, int) or m < 1:
                raise ValueError(f"quasistatic tier: max_replicas must be an integer >= 1, got {m!r}")
            if self.schedule != "async":
                raise ValueError("quasistatic tier: max_replicas needs schedule = 'async'")
        if isinstance(self.overpressure, bool) or not (isinstance(self.overpressure, (int, float))
                                                        and math.isfinite(self.overpressure)):
            raise ValueError(f"quasistatic tier: overpressure must be a finite number, got {self.overpressure!r}")
        if not isinstance(self.thermal_contact, bool):
            raise ValueError(f"quasistatic tier: thermal_contact must be true or false, got {self.thermal_contact!r}")
        if not (isinstance(self.kT, (int, float)) and math.isfinite(self.kT) and self.kT > 0):
            raise ValueError(f"quasistatic tier: kT must be a positive DPD energy, got {self.kT!r}")
        indentation_convention(self.indentation_convention)

    def run(self, request: CurveRequest, device: str = "cpu",
            on_curve: Callable[[int, np.ndarray, str, dict], None] | None = None) -> CurveBatch:
        """Simulate ``request`` on the Warp ``device``.

        Parameters
        ----------
        request : CurveRequest
            The curves (units: :class:`CurveRequest`); indentation may mix bubble sizes
            (``CurveRequest.diameters_um``), each curve then as in a request of its own size.
        device : str
            Warp device.
        on_curve : callable, optional
            ``on_curve(i, observable [P], status, info)``: each curve (async schedule) as soon as it is
            finished, with the row, tier status and per-curve info the returned batch will hold (its ``settings``
            less the batch total ``fire_evaluations``).

        Returns
        -------
        CurveBatch
            Observables (compression: both-plate force, DPD force; indentation: d(F), DPD length), statuses and
            ``info`` (mesh, conventions, ``fire_steps`` per curve, the run's ``settings``).

        Raises
        ------
        ValueError
            If ``first_load_ramp`` is set for compression, or the request does not fit the tier.
        """
        from bubblecal.sim.engine.mesh import mesh_for_diameter
        from bubblecal.sim.engine.system import resolve_dtype
        from bubblecal.sim.tiers.quasistatic import (
            FireSettings,
            IdealGas,
            ThermalContact,
            compression_pools,
            quasistatic_compression,
            quasistatic_indentation,
        )

        t0 = time.perf_counter()
        sub = self.subdivisions if self.subdivisions is not None else request.subdivisions
        mesh = mesh_for_diameter(request.diameter_um, sub)
        meshes = None
        if request.several_sizes:  # one pool of several sizes on one mesh level
            by_size = {d: mesh_for_diameter(d, mesh.subdivisions) for d in sorted(set(request.diameters_um))}
            meshes = [by_size[d] for d in request.diameters_um]
        fire = FireSettings(ftol=self.ftol, max_steps=self.max_steps, stop_at_max_steps=self.stop_unstable,
                            force_mode=self.force_mode, minimizer=self.minimizer)
        gas = IdealGas(p0=self.gas_p0, p_ambient=self.gas_p0 - self.overpressure)
        dtype = None if self.dtype is None else resolve_dtype(self.dtype)
        common = dict(gas=gas, device=device, dtype=dtype, fire=fire, rupture_strain=self.rupture_strain,
                      extrapolate=self.extrapolate, schedule=self.schedule, max_replicas=self.max_replicas,
                      sync_every=self.sync_every)
        grid = request.grid_array()
        conv = indentation_convention(self.indentation_convention)
        static = self._static_info(request, mesh, conv)
        params = [dataclasses.replace(p, self_avoid=bool(self.self_avoid))
                  for p in request.shell_params(conv.name)]
        if request.protocol == "indentation" and grid.ndim == 2:
            raise ValueError("quasistatic tier: indentation takes one force grid per request (CurveRequest.grids)")
        if request.protocol == "compression":
            if self.first_load_ramp:
                raise ValueError("quasistatic tier: first_load_ramp applies to indentation only (compression "
                                 "refines its plate steps itself)")
            if self.max_depth_fall is not None:
                raise ValueError("quasistatic tier: max_depth_fall applies to indentation only (a compressed shell "
                                 "that buckles does lose force: the training filter judges those curves)")
            thermal = ThermalContact(kT=float(self.kT)) if self.thermal_contact else None
            row_cb = None
            if on_curve is not None:
                def row_cb(i, row):
                    on_curve(i, row["force"] + row["force_bottom"], _QS_STATUS[row["status"]],
                             {**static, "fire_steps": int(np.sum(row["fire_steps"])),
                              "fire_steps_chain": [int(v) for v in row["fire_steps_chain"]],
                              "settings": row["settings"]})

            if meshes is None and grid.ndim == 1:
                res = quasistatic_compression(params, mesh, grid, thermal=thermal, on_curve=row_cb, **common)
            else:  # one pool per chain length (the plate sub-steps depend on each grid)
                res = compression_pools(params, mesh, meshes, grid, thermal=thermal, on_curve=row_cb, **common)
            obs = res.force + res.force_bottom  # both plates (DISPLACEMENT_CONVENTION)
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
                                          first_load_ramp=self.first_load_ramp, meshes=meshes,
                                          max_depth_fall=self.max_depth_fall, **common)
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
