"""Quasi-static parallel-plate compression: analytic plates, F(d) from the plate reactions (package docstring)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from bubblecal.sim.protocols.loading import validate_grid
from bubblecal.sim.protocols.plates import PlateContact
from bubblecal.sim.tiers.quasistatic.backends import _DeviceChain
from bubblecal.sim.tiers.quasistatic.grids import _refine_grid, _select_points
from bubblecal.sim.tiers.quasistatic.results import CompressionResult
from bubblecal.sim.tiers.quasistatic.schedule import _run_chain, _run_device_async
from bubblecal.sim.tiers.quasistatic.settings import (
    FireSettings,
    IdealGas,
    _check_common,
    _check_max_replicas,
    _check_params,
    _dtype_name,
)
from bubblecal.sim.tiers.quasistatic.thermal_contact import ThermalContact, hard_wall_distance

if TYPE_CHECKING:
    from bubblecal.sim.engine.kernels.shell import ShellParams
    from bubblecal.sim.engine.mesh import ShellMesh

__all__ = ["quasistatic_compression"]


@dataclass
class _CompressionPlan:
    """A checked compression run before it is relaxed: grids, plate heights and the geometry they come from."""

    requested: np.ndarray  # the requested total displacements [P] (DPD length)
    disp: np.ndarray  # the displacements the chain relaxes at (sub-steps included)
    keep: np.ndarray  # indices of the requested displacements in disp
    schedule: str
    params: list
    radius: float  # mean vertex distance from the centroid (DPD length)
    zc: float  # reference centre height (DPD length)
    h0: float  # reference half extent in z (DPD length)
    plate: np.ndarray  # top plate height per chain point (DPD length); the bottom one is 2 zc - plate


def _compression_plan(params, mesh, displacements_dpd, *, gas, contact, thermal, fire, rupture_strain,
                      max_plate_step, schedule, max_replicas) -> _CompressionPlan:
    """Check the arguments of :func:`quasistatic_compression` and lay out the run."""
    requested = validate_grid(displacements_dpd, "displacements_dpd")
    schedule = _check_common(rupture_strain, fire, schedule)
    _check_max_replicas(max_replicas, schedule)
    if not (math.isfinite(max_plate_step) and max_plate_step > 0):
        raise ValueError(f"max_plate_step must be a positive finite DPD length, got {max_plate_step!r}")
    disp, keep = _refine_grid(requested, 2.0 * max_plate_step)
    if not isinstance(contact, PlateContact):
        raise ValueError(f"contact must be a PlateContact, got {type(contact).__name__}")
    if thermal is not None and not isinstance(thermal, ThermalContact):
        raise ValueError(f"thermal must be None or a ThermalContact, got {type(thermal).__name__}")
    params = _check_params(params, mesh, gas)
    radius = float(np.linalg.norm(mesh.vertices - mesh.vertices.mean(axis=0), axis=1).mean())
    zc = float(mesh.vertices[:, 2].mean())
    h0 = float(np.max(np.abs(mesh.vertices[:, 2] - zc)))
    if np.any(disp / 2 >= h0 + contact.gap):
        raise ValueError(f"displacements_dpd must stay below 2 (h0 + gap) = {2 * (h0 + contact.gap):.3f}")
    plate = zc + h0 + contact.gap - disp / 2.0  # top plate z; bottom = 2 zc - plate
    return _CompressionPlan(requested=requested, disp=disp, keep=keep, schedule=schedule, params=params,
                            radius=radius, zc=zc, h0=h0, plate=plate)


def _compression_result(plan: _CompressionPlan, out: dict, t0: float, *, gas, contact, thermal, fire,
                        rupture_strain, n_vertices, dtype, extrapolate, max_replicas) -> CompressionResult:
    """The :class:`CompressionResult` of a finished chain (``out`` of the schedules) at the requested points."""
    fire_evaluations = out["fire_evaluations"]
    keep = plan.keep
    out = _select_points(out, keep)
    nan = np.full((len(plan.params), len(keep)), np.nan)
    settings = {"gas": None if gas is None else {"p0": gas.p0, "p_ambient": gas.ambient},
                "contact": {**contact.__dict__, "cutoff": contact.cutoff},
                "thermal_contact": None if thermal is None else {
                    "kT": thermal.kT, "sigma": thermal.sigma if thermal.sigma is not None
                    else "kT R / (8 sqrt(kappa Y)), kappa = (sqrt 3 / 2) kb, Y = 4 ka mu / (ka + mu)",
                    "hard_wall": hard_wall_distance(contact, thermal.kT), "radius_dpd": plan.radius},
                "plates": "z = z_c +- (h0 + gap - d/2)", "h0": plan.h0, "com": "mean x, y force removed",
                "observable": "force on the top plate (one plate), positive compressive",
                "fire": fire.__dict__, "rupture_strain": rupture_strain, "n_vertices": n_vertices,
                "minimizer": "device", "dtype": _dtype_name(dtype), "fire_evaluations": fire_evaluations,
                "start": "linear extrapolation" if extrapolate else "previous minimum",
                "schedule": plan.schedule, "max_replicas": max_replicas}
    return CompressionResult(displacements=plan.requested, force=out["obs"].get("top", nan),
                             force_bottom=out["obs"].get("bottom", nan),
                             n_contacts=out["obs"].get("contacts", nan), plate_z=plan.plate[keep],
                             volume=out["volume"], max_area_strain=out["max_area_strain"], fmax=out["fmax"],
                             fire_steps=out["fire_steps"], status=out["status"],
                             point_status=out["point_status"], x_final=out["x"], settings=settings,
                             seconds=time.perf_counter() - t0)


def quasistatic_compression(params: Sequence[ShellParams] | ShellParams, mesh: ShellMesh,
                            displacements_dpd: Sequence[float] | np.ndarray, *,
                            gas: IdealGas | None = IdealGas(), contact: PlateContact = PlateContact(),
                            thermal: ThermalContact | None = None,
                            device: str = "cpu", dtype=None, fire: FireSettings = FireSettings(),
                            rupture_strain: float = 1.0, max_plate_step: float = 0.06,
                            sync_every: int | None = None, extrapolate: bool = True, schedule: str | None = None,
                            max_replicas: int | None = None,
                            progress: Callable[[int, int, float], None] | None = None) -> CompressionResult:
    """Athermal quasi-static parallel-plate compression F(d) of R replicas of ``mesh``.

    Parameters
    ----------
    params : ShellParams or sequence of ShellParams
        One :class:`bubblecal.sim.engine.kernels.shell.ShellParams` per replica (DPD units).
    mesh : bubblecal.sim.engine.mesh.ShellMesh
        Stress-free reference shell (DPD length).
    displacements_dpd : sequence of float
        Imposed total plate displacement d at each point (DPD length, >= 0, strictly increasing); each plate
        moves d/2.
    gas : IdealGas or None
        Enclosed ideal gas, or None.
    contact : bubblecal.sim.protocols.PlateContact
        The plate-vertex law.
    thermal : ThermalContact, optional
        None (athermal WCA plates) or the thermal contact: the plates act on each vertex through the mean force
        of its thermal normal fluctuation against the WCA's hard-wall distance
        (:mod:`bubblecal.sim.tiers.quasistatic.thermal_contact`), the entropic contact force of the thermal tiers.
    device, dtype, fire, rupture_strain, sync_every, extrapolate, schedule, max_replicas, progress
        As in :func:`~bubblecal.sim.tiers.quasistatic.quasistatic_indentation` (``progress`` after every
        sub-step).
    max_plate_step : float
        Largest plate move between two minimisations (DPD length); longer load steps are split into relaxed
        sub-steps (a 0.12 jump into the stiff WCA wall makes FIRE diverge).  0.06 = one minimisation per point
        of the published grid.

    Returns
    -------
    CompressionResult
        ``force`` in DPD force (on one plate), at the requested displacements only (sub-steps are not
        reported).

    Raises
    ------
    ValueError
        If an argument is invalid (the message names it), e.g. a displacement that would make the plates cross.
    """
    t0 = time.perf_counter()
    plan = _compression_plan(params, mesh, displacements_dpd, gas=gas, contact=contact, thermal=thermal, fire=fire,
                             rupture_strain=rupture_strain, max_plate_step=max_plate_step, schedule=schedule,
                             max_replicas=max_replicas)
    nv, zc, plate, disp = mesh.n_vertices, plan.zc, plan.plate, plan.disp

    def make_chain(ps):
        return _DeviceChain(ps, mesh, gas, device, dtype, fire, free_v=np.ones((nv, 3), dtype=bool),
                            remove_mean=(True, True, False), contact=contact, thermal=thermal,
                            radius_dpd=plan.radius, sync_every=sync_every, loads=disp if extrapolate else None)

    if plan.schedule == "async":
        out = _run_device_async(make_chain, plan.params, len(disp), rupture_strain,
                                lambda dc: (lambda jj: dc.set_plate_rows(plate[jj], 2 * zc - plate[jj])),
                                max_replicas, progress, stop_unstable=fire.stop_at_max_steps)
    else:
        dc = make_chain(plan.params)
        out = _run_chain(dc, len(disp), rupture_strain,
                         set_point=lambda j: dc.set_plates(plate[j], 2 * zc - plate[j]), progress=progress,
                         stop_unstable=fire.stop_at_max_steps)
    return _compression_result(plan, out, t0, gas=gas, contact=contact, thermal=thermal, fire=fire,
                               rupture_strain=rupture_strain, n_vertices=nv, dtype=dtype, extrapolate=extrapolate,
                               max_replicas=max_replicas)
