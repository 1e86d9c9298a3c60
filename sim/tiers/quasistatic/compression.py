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
from bubblecal.sim.tiers.quasistatic.grids import _refine_grid, _select_points, _sum_substeps
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
    sizes: _Sizes | None = None  # several bubble sizes: per-replica references, grids and plates


@dataclass
class _Sizes:
    """Per-replica geometry of a compression batch of several bubble sizes (one mesh topology, one chain length)."""

    meshes: list
    requested: np.ndarray  # [R, P] requested total displacements
    disp: np.ndarray  # [R, n] chain displacements
    radius: np.ndarray  # [R] mean vertex distance from the centroid
    zc: np.ndarray  # [R] reference centre heights
    plate: np.ndarray  # [R, n] top plate heights


def _geometry(mesh) -> tuple[float, float, float]:
    """(radius, z_c, h0) of a reference: mean vertex distance from the centroid, centre height, half extent."""
    radius = float(np.linalg.norm(mesh.vertices - mesh.vertices.mean(axis=0), axis=1).mean())
    zc = float(mesh.vertices[:, 2].mean())
    return radius, zc, float(np.max(np.abs(mesh.vertices[:, 2] - zc)))


def _sizes_plan(meshes, mesh, grids, n: int, contact, max_step: float, keep0: np.ndarray) -> _Sizes:
    """Check and lay out a batch of several sizes: one reference and one grid per replica, equal chains."""
    meshes = list(meshes) if meshes is not None else [mesh] * n
    if len(meshes) != n or len(grids) != n:
        raise ValueError(f"meshes / displacements_dpd: {len(meshes)} references and {len(grids)} grids for {n} "
                         "parameter sets")
    if any(not np.array_equal(m.faces, mesh.faces) for m in {id(m): m for m in meshes}.values()):
        raise ValueError("meshes: every reference must have the topology of mesh (one icosphere level)")
    rows = [_refine_grid(validate_grid(g, "displacements_dpd"), max_step) for g in grids]
    if any(len(d) != len(rows[0][0]) or not np.array_equal(k, keep0) for d, k in rows):
        raise ValueError("displacements_dpd: the replicas' grids refine to chains of different lengths "
                         "(max_plate_step); run each chain length as its own batch")
    geo = {id(m): _geometry(m) for m in meshes}
    radius, zc, h0 = (np.array([geo[id(m)][i] for m in meshes]) for i in range(3))
    disp = np.stack([d for d, _ in rows])
    if np.any(disp / 2 >= (h0 + contact.gap)[:, None]):
        raise ValueError("displacements_dpd must stay below 2 (h0 + gap) of each replica's reference")
    plate = (zc + h0 + contact.gap)[:, None] - disp / 2.0
    return _Sizes(meshes=meshes, requested=np.array([np.asarray(g, dtype=float) for g in grids]), disp=disp,
                  radius=radius, zc=zc, plate=plate)


def _compression_plan(params, mesh, displacements_dpd, *, gas, contact, thermal, fire, rupture_strain,
                      max_plate_step, schedule, max_replicas, meshes=None) -> _CompressionPlan:
    """Check the arguments of :func:`quasistatic_compression` and lay out the run."""
    grids = np.asarray(displacements_dpd, dtype=float) if np.ndim(displacements_dpd) == 2 else None
    requested = validate_grid(displacements_dpd if grids is None else grids[0], "displacements_dpd")
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
    sizes = None
    if meshes is not None or grids is not None:
        if schedule != "async":
            raise ValueError("several bubble sizes in one batch need schedule = 'async'")
        sizes = _sizes_plan(meshes, mesh, grids if grids is not None else [requested] * len(params), len(params),
                            contact, 2.0 * max_plate_step, keep)
    radius, zc, h0 = _geometry(mesh)
    if np.any(disp / 2 >= h0 + contact.gap):
        raise ValueError(f"displacements_dpd must stay below 2 (h0 + gap) = {2 * (h0 + contact.gap):.3f}")
    plate = zc + h0 + contact.gap - disp / 2.0  # top plate z; bottom = 2 zc - plate
    return _CompressionPlan(requested=requested, disp=disp, keep=keep, schedule=schedule, params=params,
                            radius=radius, zc=zc, h0=h0, plate=plate, sizes=sizes)


def _compression_settings(plan: _CompressionPlan, *, gas, contact, thermal, fire, rupture_strain, n_vertices,
                          dtype, extrapolate, max_replicas) -> dict:
    """The run's choices, as the result's ``settings`` (without the batch total ``fire_evaluations``)."""
    return {"gas": None if gas is None else {"p0": gas.p0, "p_ambient": gas.ambient},
                "contact": {**contact.__dict__, "cutoff": contact.cutoff},
                "thermal_contact": None if thermal is None else {
                    "kT": thermal.kT, "sigma": thermal.sigma if thermal.sigma is not None
                    else "kT R / (8 sqrt(kappa Y)), kappa = (sqrt 3 / 2) kb, Y = 4 ka mu / (ka + mu)",
                    "hard_wall": hard_wall_distance(contact, thermal.kT), "radius_dpd": plan.radius},
                "plates": "z = z_c +- (h0 + gap - d/2)", "h0": plan.h0, "com": "mean x, y force removed",
                "observable": "force on the top plate (one plate), positive compressive",
                "fire": fire.__dict__, "rupture_strain": rupture_strain, "n_vertices": n_vertices,
                "minimizer": "device", "dtype": _dtype_name(dtype),
                "start": "linear extrapolation" if extrapolate else "previous minimum",
                "schedule": plan.schedule, "max_replicas": max_replicas}


def _compression_result(plan: _CompressionPlan, out: dict, t0: float, settings: dict) -> CompressionResult:
    """The :class:`CompressionResult` of a finished chain (``out`` of the schedules) at the requested points."""
    items = list(settings.items())
    at = [k for k, _ in items].index("dtype") + 1  # the key order of the records' settings, as it always was
    settings = dict(items[:at] + [("fire_evaluations", out["fire_evaluations"])] + items[at:])
    keep = plan.keep
    out = _select_points(out, keep)
    nan = np.full((len(plan.params), len(keep)), np.nan)
    sizes = plan.sizes
    return CompressionResult(displacements=plan.requested if sizes is None else sizes.requested,
                             force=out["obs"].get("top", nan), force_bottom=out["obs"].get("bottom", nan),
                             n_contacts=out["obs"].get("contacts", nan),
                             plate_z=plan.plate[keep] if sizes is None else sizes.plate[:, keep],
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
                            progress: Callable[[int, int, float], None] | None = None,
                            meshes: Sequence[ShellMesh] | None = None,
                            on_curve: Callable[[int, dict], None] | None = None) -> CompressionResult:
    """Athermal quasi-static parallel-plate compression F(d) of R replicas of ``mesh``.

    Parameters
    ----------
    params : ShellParams or sequence of ShellParams
        One :class:`bubblecal.sim.engine.kernels.shell.ShellParams` per replica (DPD units).
    mesh : bubblecal.sim.engine.mesh.ShellMesh
        Stress-free reference shell (DPD length).
    displacements_dpd : sequence of float
        Imposed total plate displacement d at each point (DPD length, >= 0, strictly increasing); each plate
        moves d/2.  [R, P]: one grid per replica (several bubble sizes; equal chain lengths after sub-steps).
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

    meshes : sequence of ShellMesh, optional
        One stress-free reference per parameter set, with ``mesh``'s faces (icospheres of one level at several
        diameters): one pool then holds several bubble sizes, each with its own plates, thermal fluctuation and
        grid row, with the curves of separate runs (async schedule).  None: ``mesh`` for every replica.
    on_curve : callable, optional
        ``on_curve(i, row)`` as soon as ``params[i]`` has finished its curve (async schedule), ``row`` =
        {"force", "force_bottom" [P] (DPD force, one plate each), "status", "point_status", "fire_steps" [P],
        "fire_steps_chain" (per chain point, sub-steps included), "settings" (the result's, less the batch
        total ``fire_evaluations``)}: the same numbers as the returned rows.

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
                             max_replicas=max_replicas, meshes=meshes)
    nv, zc, plate, disp, sizes = mesh.n_vertices, plan.zc, plan.plate, plan.disp, plan.sizes
    settings = _compression_settings(plan, gas=gas, contact=contact, thermal=thermal, fire=fire,
                                     rupture_strain=rupture_strain, n_vertices=nv, dtype=dtype,
                                     extrapolate=extrapolate, max_replicas=max_replicas)
    keep = plan.keep
    finish = None
    if on_curve is not None:
        def finish(i, row):
            n = len(disp)
            top, bottom = (row["obs"].get(k, np.full(n, np.nan))[keep] for k in ("top", "bottom"))
            on_curve(i, {"force": top, "force_bottom": bottom, "status": row["status"],
                         "point_status": [row["point_status"][j] for j in keep],
                         "fire_steps": _sum_substeps(row["fire_steps"], keep),
                         "fire_steps_chain": np.asarray(row["fire_steps"]).copy(), "settings": settings})

    def make_chain(idx):
        ps = [plan.params[int(i)] for i in idx]
        common = dict(free_v=np.ones((nv, 3), dtype=bool), remove_mean=(True, True, False), contact=contact,
                      thermal=thermal, sync_every=sync_every)
        if sizes is None:
            return _DeviceChain(ps, mesh, gas, device, dtype, fire, radius_dpd=plan.radius,
                                loads=disp if extrapolate else None, **common)
        return _DeviceChain(ps, [sizes.meshes[int(i)] for i in idx], gas, device, dtype, fire,
                            replica_loads=sizes.disp[idx] if extrapolate else None, radii=sizes.radius[idx],
                            plate_heights=sizes.plate[idx], centers=sizes.zc[idx], **common)

    def load_slots(dc, slots, idx):
        dc.load_samples(slots, [plan.params[int(i)] for i in idx], [sizes.meshes[int(i)] for i in idx],
                        loads=sizes.disp[idx] if extrapolate else None, radii=sizes.radius[idx],
                        plate_heights=sizes.plate[idx], centers=sizes.zc[idx])

    if sizes is not None:
        out = _run_device_async(make_chain, plan.params, len(disp), rupture_strain,
                                lambda dc: dc.assign_plates, max_replicas, progress, on_finish=finish,
                                stop_unstable=fire.stop_at_max_steps, load_slots=load_slots)
    elif plan.schedule == "async":
        out = _run_device_async(make_chain, plan.params, len(disp), rupture_strain,
                                lambda dc: (lambda jj: dc.set_plate_rows(plate[jj], 2 * zc - plate[jj])),
                                max_replicas, progress, on_finish=finish, stop_unstable=fire.stop_at_max_steps)
    else:
        dc = make_chain(np.arange(len(plan.params)))
        out = _run_chain(dc, len(disp), rupture_strain,
                         set_point=lambda j: dc.set_plates(plate[j], 2 * zc - plate[j]), progress=progress,
                         stop_unstable=fire.stop_at_max_steps)
    return _compression_result(plan, out, t0, settings)


def compression_pools(params: Sequence[ShellParams], mesh: ShellMesh, meshes: Sequence[ShellMesh] | None,
                      grids: np.ndarray, *, max_plate_step: float = 0.06, **kwargs) -> CompressionResult:
    """Compression of replicas of several sizes or grids: one :func:`quasistatic_compression` pool per chain length.

    Replicas whose grids refine to the same chain (``max_plate_step`` sub-steps) share one pool, so every curve is
    the one a run of its own size gives.

    Parameters
    ----------
    params : sequence of ShellParams
        One parameter set per replica (DPD units).
    mesh : ShellMesh
        The topology (and the reference when ``meshes`` is None).
    meshes : sequence of ShellMesh or None
        One reference per replica with ``mesh``'s faces, or None.
    grids : numpy.ndarray
        [P] or [R, P] total displacements (DPD length).
    max_plate_step : float
        As in :func:`quasistatic_compression`.
    **kwargs
        The other keyword arguments of :func:`quasistatic_compression` (``schedule`` must be async).

    Returns
    -------
    CompressionResult
        Rows in ``params`` order; ``displacements`` and ``plate_z`` [R, P]; ``settings`` of the first pool with
        the pools' total ``fire_evaluations``; ``seconds`` their sum.

    Raises
    ------
    ValueError
        As :func:`quasistatic_compression`.
    """
    params = list(params)
    n = len(params)
    rows = np.broadcast_to(np.asarray(grids, dtype=float), (n, np.shape(grids)[-1]))
    refs = list(meshes) if meshes is not None else [mesh] * n
    groups: dict[int, list[int]] = {}
    for i in range(n):
        groups.setdefault(len(_refine_grid(validate_grid(rows[i], "displacements_dpd"), 2.0 * max_plate_step)[0]),
                          []).append(i)
    on_curve = kwargs.pop("on_curve", None)

    def stream(idx):  # group row k -> the caller's row idx[k]
        return None if on_curve is None else (lambda k, row: on_curve(idx[k], row))

    parts = [(idx, quasistatic_compression([params[i] for i in idx], mesh, rows[idx], meshes=[refs[i] for i in idx],
                                           max_plate_step=max_plate_step, on_curve=stream(idx), **kwargs))
             for idx in groups.values()]
    first = parts[0][1]
    merged = {}
    for name in ("displacements", "force", "force_bottom", "n_contacts", "plate_z", "volume", "max_area_strain",
                 "fmax", "fire_steps"):
        out = np.empty((n,) + getattr(first, name).shape[1:], dtype=getattr(first, name).dtype)
        for idx, res in parts:
            out[idx] = getattr(res, name)
        merged[name] = out
    status, point_status = [None] * n, [None] * n
    nv = mesh.n_vertices
    x = np.empty((n, nv, 3))
    for idx, res in parts:
        for k, i in enumerate(idx):
            status[i], point_status[i] = res.status[k], res.point_status[k]
        x[idx] = res.x_final.reshape(len(idx), nv, 3)
    settings = {**first.settings, "fire_evaluations": sum(r.settings["fire_evaluations"] for _, r in parts)}
    return CompressionResult(**merged, status=status, point_status=point_status, x_final=x.reshape(-1, 3),
                             settings=settings, seconds=sum(r.seconds for _, r in parts))
