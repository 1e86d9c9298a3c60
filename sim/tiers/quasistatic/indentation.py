"""Quasi-static indentation: opposed pole loads, d(F) from the axial extent (package docstring)."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from bubblecal.sim.protocols.loading import validate_grid
from bubblecal.sim.tiers.quasistatic.backends import _DeviceChain
from bubblecal.sim.tiers.quasistatic.collapse import check_max_depth_fall, cut_collapsed
from bubblecal.sim.tiers.quasistatic.grids import _ramp_grid, _select_points, _sum_substeps
from bubblecal.sim.tiers.quasistatic.results import IndentationResult
from bubblecal.sim.tiers.quasistatic.schedule import _run_chain, _run_device_async
from bubblecal.sim.tiers.quasistatic.settings import (
    FireSettings,
    IdealGas,
    _check_common,
    _check_max_replicas,
    _check_params,
    _dtype_name,
)

if TYPE_CHECKING:
    from bubblecal.sim.engine.kernels.shell import ShellParams
    from bubblecal.sim.engine.mesh import ShellMesh

__all__ = ["quasistatic_indentation"]


@dataclass
class _IndentationPlan:
    """A checked indentation run before it is relaxed: grids, loaded and anchored vertices, static settings."""

    forces: np.ndarray  # the requested forces [P] (DPD force)
    chain_forces: np.ndarray  # the forces the chain relaxes at (first-load ramp included)
    keep: np.ndarray  # indices of the requested forces in chain_forces
    schedule: str
    params: list
    z0: np.ndarray  # reference z of every vertex (DPD length)
    top: np.ndarray  # loaded vertices of the top pole
    bottom: np.ndarray  # loaded vertices of the bottom pole
    h0: np.ndarray  # [R] reference axial extent of each replica's mesh (DPD length)
    free_v: np.ndarray  # [Nv, 3] movable components (the equator is anchored in z)
    unit: np.ndarray  # [Nv, 3] pole-load direction per unit total load
    static_settings: dict
    meshes: list | None = None  # one reference per replica (same topology), or None: ``mesh`` for all
    max_depth_fall: float | None = None  # the collapse verdict's tolerance (None: off)


def _anchored_equator(mesh) -> np.ndarray:
    """Vertices within 0.25 l_min of the reference's mid-height (anchored in z)."""
    z = mesh.vertices[:, 2]
    return np.nonzero(np.abs(z - float(z.mean())) < 0.25 * mesh.min_edge_length())[0]


def _replica_meshes(meshes, mesh, n: int, patch_kw: dict, anchors: np.ndarray) -> list | None:
    """Check per-replica references: one per parameter set, ``mesh``'s faces, the same sets of loaded and anchored
    vertices (a scaled copy of ``mesh`` has them)."""
    from bubblecal.sim.engine import pole_patches

    if meshes is None:
        return None
    meshes = list(meshes)
    if len(meshes) != n:
        raise ValueError(f"meshes: {len(meshes)} references for {n} parameter sets")
    # as sets: vertices of one ring tie in distance to the pole, so rounding orders them differently per size
    top, bottom = (np.sort(p) for p in pole_patches(mesh.vertices, **patch_kw))
    for m in {id(m): m for m in meshes}.values():
        t, b = (np.sort(p) for p in pole_patches(m.vertices, **patch_kw))
        if not (np.array_equal(m.faces, mesh.faces) and np.array_equal(t, top) and np.array_equal(b, bottom)
                and np.array_equal(_anchored_equator(m), anchors)):
            raise ValueError("meshes: every reference must have the topology, loaded poles and anchored equator "
                             "of mesh (e.g. icospheres of one subdivision level)")
    return meshes


def _indentation_plan(params, mesh, forces_dpd, *, gas, fire, rupture_strain, fraction_loaded, pole_patch,
                      dtype, extrapolate, schedule, max_replicas, first_load_ramp, meshes=None,
                      max_depth_fall=None) -> _IndentationPlan:
    """Check the arguments of :func:`quasistatic_indentation` and lay out the run."""
    from bubblecal.sim.engine import pole_patches

    forces = validate_grid(forces_dpd, "forces_dpd")
    if isinstance(first_load_ramp, bool) or not isinstance(first_load_ramp, (int, np.integer)) \
            or not 0 <= first_load_ramp <= 20:
        raise ValueError(f"first_load_ramp must be an integer in [0, 20], got {first_load_ramp!r}")
    # the chain runs on the grid with the ramp's sub-points; results keep the requested points only
    chain_forces, keep = _ramp_grid(forces, int(first_load_ramp))
    schedule = _check_common(rupture_strain, fire, schedule)
    _check_max_replicas(max_replicas, schedule)
    max_depth_fall = check_max_depth_fall(max_depth_fall)
    if pole_patch is not None and fraction_loaded is not None:
        raise ValueError("give fraction_loaded or pole_patch, not both")
    patch_kw = dict(pole_patch) if pole_patch is not None else {"fraction": 0.01 if fraction_loaded is None
                                                                 else fraction_loaded}
    if patch_kw.get("fraction") is not None and not (0 < patch_kw["fraction"] < 0.5):
        raise ValueError(f"fraction_loaded must lie in (0, 0.5), got {patch_kw['fraction']!r}")
    params = _check_params(params, mesh, gas)
    nv = mesh.n_vertices
    z0 = mesh.vertices[:, 2]
    top, bottom = pole_patches(mesh.vertices, **patch_kw)
    k = len(top)
    equator = _anchored_equator(mesh)
    meshes = _replica_meshes(meshes, mesh, len(params), patch_kw, equator)
    h0 = np.array([float(np.ptp(m.vertices[:, 2])) for m in meshes]) if meshes else np.full(len(params),
                                                                                            float(np.ptp(z0)))
    free_v = np.ones((nv, 3), dtype=bool)
    free_v[equator, 2] = False
    unit = np.zeros((nv, 3))
    unit[top, 2] = -1.0 / k
    unit[bottom, 2] = 1.0 / k
    static_settings = {"k_loaded_per_pole": k, "n_equator_anchored": int(equator.size),
                       "pole_patch": {key: v for key, v in patch_kw.items() if v is not None},
                       "gas": None if gas is None else {"p0": gas.p0, "p_ambient": gas.ambient},
                       "com": "mean force removed (x, y, z)", "equator": "|z - z_c| < 0.25 l_min anchored in z",
                       "observable": "d = H0 - H, H = max z - min z", "fire": fire.__dict__,
                       "rupture_strain": rupture_strain, "n_vertices": nv, "minimizer": "device",
                       "dtype": _dtype_name(dtype),
                       "start": "linear extrapolation" if extrapolate else "previous minimum",
                       "schedule": schedule, "max_replicas": max_replicas, "first_load_ramp": int(first_load_ramp)}
    if max_depth_fall is not None:  # only when set: runs without the verdict record the settings they always had
        static_settings["max_depth_fall"] = max_depth_fall
    return _IndentationPlan(forces=forces, chain_forces=chain_forces, keep=keep, schedule=schedule, params=params,
                            z0=z0, top=top, bottom=bottom, h0=h0, free_v=free_v, unit=unit,
                            static_settings=static_settings, meshes=meshes, max_depth_fall=max_depth_fall)


def _indentation_result(plan: _IndentationPlan, out: dict, t0: float) -> IndentationResult:
    """The :class:`IndentationResult` of a finished chain (``out`` of the schedules) at the requested points."""
    out = _select_points(out, plan.keep)
    R, nf = len(plan.params), len(plan.forces)
    z0, top, bottom = plan.z0, plan.top, plan.bottom
    refs = plan.meshes or [None] * R
    patch0 = np.array([float(z[top].mean() - z[bottom].mean())
                       for z in ((z0 if m is None else m.vertices[:, 2]) for m in refs)])
    H = out["obs"].get("H", np.full((R, nf), np.nan)).copy()
    P = out["obs"].get("patch", np.full((R, nf), np.nan)).copy()
    volume, strain = out["volume"].copy(), out["max_area_strain"].copy()
    status, point_status = list(out["status"]), [list(ps) for ps in out["point_status"]]
    for r in range(R):
        _, status[r], point_status[r], j = cut_collapsed(plan.h0[r] - H[r], status[r], point_status[r],
                                                         plan.max_depth_fall)
        if j is not None:  # the cut curve reports nothing past its collapse, as a failed one
            for a in (H, P, volume, strain):
                a[r, j:] = np.nan
    settings = {**plan.static_settings, "fire_evaluations": out["fire_evaluations"]}
    return IndentationResult(forces=plan.forces, displacement=plan.h0[:, None] - H, axial_diameter=H,
                             axial_diameter0=plan.h0.copy(), d_patch=patch0[:, None] - P, volume=volume,
                             max_area_strain=strain, fmax=out["fmax"],
                             fire_steps=out["fire_steps"], status=status,
                             point_status=point_status, x_final=out["x"], settings=settings,
                             seconds=time.perf_counter() - t0)


def quasistatic_indentation(params: Sequence[ShellParams] | ShellParams, mesh: ShellMesh,
                            forces_dpd: Sequence[float] | np.ndarray, *, gas: IdealGas | None = IdealGas(),
                            device: str = "cpu", dtype=None, fire: FireSettings = FireSettings(),
                            rupture_strain: float = 1.0, fraction_loaded: float | None = None,
                            pole_patch: dict | None = None,
                            sync_every: int | None = None, extrapolate: bool = True, schedule: str | None = None,
                            max_replicas: int | None = None, first_load_ramp: int = 0,
                            progress: Callable[[int, int, float], None] | None = None,
                            on_curve: Callable[[int, dict], None] | None = None,
                            meshes: Sequence[ShellMesh] | None = None,
                            max_depth_fall: float | None = None) -> IndentationResult:
    """Athermal quasi-static indentation d(F) of R replicas (one per ``params``) of ``mesh``.

    Parameters
    ----------
    params : ShellParams or sequence of ShellParams
        One :class:`bubblecal.sim.engine.kernels.shell.ShellParams` per replica (moduli in DPD units).
    mesh : bubblecal.sim.engine.mesh.ShellMesh
        Stress-free reference shell (DPD length), shared by all replicas.
    forces_dpd : sequence of float
        Total force per pole at each load point (DPD force, >= 0, strictly increasing).
    gas : IdealGas or None
        Enclosed ideal gas (pressures in DPD units), or None for a shell without gas.
    device : str
        Warp device.
    dtype : warp scalar type, optional
        Float type; None = ``wp.float64``.
    fire : FireSettings
        FIRE controls (ftol in DPD force per vertex).
    rupture_strain : float
        Max triangle area strain abs(A/A0 - 1) above which a replica is 'ruptured'.
    fraction_loaded : float, optional
        k = max(1, floor(fraction_loaded N_v)) loaded vertices per pole, in (0, 0.5) (the default 0.01 when
        neither this nor ``pole_patch`` is given).
    pole_patch : dict, optional
        Keyword arguments of :func:`bubblecal.sim.engine.pole_patches` (``{"cap_deg": 4.6}`` for a polar
        cap); excludes ``fraction_loaded``.
    sync_every : int, optional
        Device FIRE iterations between host status checks (default 25 CUDA / 4 CPU).
    extrapolate : bool
        Start each load point from the linear extrapolation of the last two minima instead of the last one:
        same minima (within ``fire.ftol``), fewer FIRE iterations.
    schedule : str, optional
        ``"async"`` (default: each replica advances to its next load point as soon as it has relaxed, so the
        batch never waits for its slowest replica at every point; same FIRE iterates and curves as lock-step)
        or ``"lockstep"`` (every replica at the same point).
    max_replicas : int, optional
        (async only) At most this many replicas relax at once; a slot whose curve is finished takes the next
        parameter set (softest k_a first), so a large batch runs at full occupancy and its wall time follows
        the total FIRE work, not the slowest curve.  Same curves as one slot per parameter set.  None: one slot
        per parameter set.
    first_load_ramp : int
        Relax through this many geometric sub-points F1/2^n ... F1/2 before the first positive force F1, in
        [0, 20] (the curve keeps the requested points, whose FIRE steps include their sub-points'; the curves
        move within the FIRE tolerance).  0: none.
    progress : callable, optional
        ``progress(j, n_points, seconds)`` after every load point; with slot refill
        ``progress(k, n_params, seconds)`` after every finished curve.
    on_curve : callable, optional
        ``on_curve(i, row)`` as soon as ``params[i]`` has finished its curve (async schedule), ``row`` =
        {"displacement" [P] (DPD length), "status", "point_status", "fire_steps" [P], "fire_steps_chain" (FIRE
        updates per chain point, the ramp's sub-points included), "settings" (the result's, less the batch total
        ``fire_evaluations``)}: the same numbers as the returned rows.
    meshes : sequence of ShellMesh, optional
        One stress-free reference per parameter set, each with ``mesh``'s faces, loaded poles and anchored
        equator (icospheres of one level at several diameters): one pool then holds several bubble sizes, each
        replica's depth measured from its own reference extent, with the curves of separate runs.  None:
        ``mesh`` for every replica.
    max_depth_fall : float, optional
        The collapse verdict (:mod:`bubblecal.sim.tiers.quasistatic.collapse`), in (0, 1): a curve still 'ok'
        or 'not_converged' whose depth falls below its deepest earlier point by more than this fraction of it
        ends there, 'collapsed', with its prefix kept and NaN from that point on (depth, extents, volume,
        strain).  None: no verdict.

    Returns
    -------
    IndentationResult
        Displacements in DPD length.

    Raises
    ------
    ValueError
        If an argument is invalid (the message names it).
    """
    t0 = time.perf_counter()
    plan = _indentation_plan(params, mesh, forces_dpd, gas=gas, fire=fire, rupture_strain=rupture_strain,
                             fraction_loaded=fraction_loaded, pole_patch=pole_patch, dtype=dtype,
                             extrapolate=extrapolate, schedule=schedule, max_replicas=max_replicas,
                             first_load_ramp=first_load_ramp, meshes=meshes, max_depth_fall=max_depth_fall)
    nv, chain_forces, keep = mesh.n_vertices, plan.chain_forces, plan.keep
    tag = np.zeros(nv, dtype=np.int32)
    tag[plan.top], tag[plan.bottom] = 1, -1

    def make_chain(idx):
        ms = None if plan.meshes is None else [plan.meshes[int(i)] for i in idx]
        return _DeviceChain([plan.params[int(i)] for i in idx], ms or mesh, gas, device, dtype, fire,
                            free_v=plan.free_v, remove_mean=(True, True, True), unit=plan.unit, tag=tag,
                            sync_every=sync_every, loads=chain_forces if extrapolate else None)

    def load_slots(dc, slots, idx):
        dc.load_samples(slots, [plan.params[int(i)] for i in idx], [plan.meshes[int(i)] for i in idx])

    if plan.schedule == "async":
        finish = None
        if on_curve is not None:
            def finish(i, row):
                h = row["obs"].get("H", np.full(len(chain_forces), np.nan))[keep]
                depth, status, point_status, _ = cut_collapsed(plan.h0[i] - h, row["status"],
                                                               [row["point_status"][j] for j in keep],
                                                               plan.max_depth_fall)
                on_curve(i, {"displacement": depth, "status": status, "point_status": point_status,
                             "fire_steps": _sum_substeps(row["fire_steps"], keep),
                             "fire_steps_chain": np.asarray(row["fire_steps"]).copy(),
                             "settings": plan.static_settings})

        out = _run_device_async(make_chain, plan.params, len(chain_forces), rupture_strain,
                                lambda dc: (lambda jj: dc.set_load_rows(chain_forces[jj])), max_replicas,
                                progress, on_finish=finish, stop_unstable=fire.stop_at_max_steps,
                                load_slots=None if plan.meshes is None else load_slots)
    else:
        dc = make_chain(np.arange(len(plan.params)))
        out = _run_chain(dc, len(chain_forces), rupture_strain, set_point=lambda j: dc.set_load(chain_forces[j]),
                         progress=progress, stop_unstable=fire.stop_at_max_steps)
    return _indentation_result(plan, out, t0)
