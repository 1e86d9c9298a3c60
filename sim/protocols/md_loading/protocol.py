"""The chained MD loading protocol shared by the explicit and implicit tiers (package docstring)."""

from __future__ import annotations

import math
import time

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.protocols.health_status import STATUS_MAP
from bubblecal.sim.protocols.md_loading.steps import ProtocolSteps
from bubblecal.sim.protocols.plates import PlateContact, plate_cap_distance

__all__ = ["run_md_protocol"]


def run_md_protocol(adapter, mesh, protocol: str, grid: np.ndarray, steps: ProtocolSteps,
                    contact: PlateContact = PlateContact(), pole_patch: dict | None = None,
                    max_seconds: float | None = None, progress=None) -> dict:
    """Run the chained loading protocol (package docstring) on an adapted MD system.

    Parameters
    ----------
    adapter : ImplicitAdapter or ExplicitAdapter
        The system (:mod:`bubblecal.sim.protocols.md_loading.adapters`), R replicas of one mesh.
    mesh : bubblecal.sim.engine.mesh.ShellMesh
        The shared reference mesh, centred at the origin (DPD length).
    protocol : str
        'compression' or 'indentation'.
    grid : numpy.ndarray
        Total displacements [P] (compression, DPD length) or forces per pole [P] (indentation, DPD force).
    steps : ProtocolSteps
        Step counts.
    contact : PlateContact
        The plates' law (compression).
    pole_patch : dict, optional
        Keyword arguments of :func:`bubblecal.sim.engine.pole_patches` (default ``{"fraction": 0.01}``).
    max_seconds : float, optional
        Wall-time budget (s); replicas still running when it is spent become 'timeout'.
    progress : callable, optional
        ``progress(points_done, P, seconds)`` after every point.

    Returns
    -------
    dict
        ``observable`` [R, P] (compression: both-plate force, DPD force; indentation: d(F), DPD length),
        ``status`` [R] and ``point_status`` [R][P] (:data:`bubblecal.data.names.STATUSES`), ``health`` [R] (the
        health verdict and where it came, or None), ``steps`` (MD steps run), ``seconds``; compression adds
        ``force_top``, ``force_bottom``, ``force_sem`` [R, P]; indentation ``axial_diameter``, ``axial_sem``
        [R, P], ``axial_diameter_equilibrated`` [R] and ``initial_diameter_reference`` (2 R, DPD length).

    Raises
    ------
    ValueError
        If a compression displacement brings the plates within half the LJ range of the reference's centre.
    """
    wp = require("warp", "sim")

    from bubblecal.sim.engine import pole_patches
    from bubblecal.sim.protocols.md_loading.kernels import md_loading_kernels

    t0 = time.perf_counter()
    k = md_loading_kernels(adapter.dtype)
    dev, R, P = adapter.device, adapter.R, len(grid)
    z0 = mesh.vertices[:, 2]
    state = wp.array(np.zeros(4), dtype=wp.float64, device=dev)
    status = ["ok"] * R
    point_status = [["ok"] * P for _ in range(R)]
    # the health check's own verdict (e.g. NAN vs LEAK, both 'failed') and the point it came at, per replica
    health = [None] * R
    obs = np.full((R, P), np.nan)
    extra: dict[str, np.ndarray] = {}
    offsets = np.asarray(adapter.offsets, dtype=np.int64)
    N = int(np.max(offsets + np.asarray(adapter.counts)))

    if protocol == "compression":
        h0 = float(np.max(np.abs(z0 - z0.mean())))
        hcap = plate_cap_distance(contact.epsilon, contact.sigma, contact.force_cap)
        lj = wp.array(np.array([contact.epsilon, contact.sigma, contact.cutoff, hcap, contact.force_cap],
                               dtype=adapter.np_dtype), dtype=adapter.dtype, device=dev)
        zc = wp.array(adapter.zc.astype(adapter.np_dtype), dtype=adapter.dtype, device=dev)
        acc = wp.zeros((R, 2), dtype=wp.float64, device=dev)
        values = h0 + contact.gap - np.asarray(grid) / 2.0  # plate half-gap g per point
        start_value = h0 + contact.gap
        if np.any(values <= 0.5 * contact.cutoff):
            raise ValueError(f"compression grid too large for this bubble: d must stay below {2 * h0:.3f}")

        def plates_cb():
            wp.launch(k["plates"], dim=N, inputs=[adapter.x, adapter.f(), adapter.vrep, adapter.status, zc, state,
                                                  adapter.step_counter, lj, acc], device=dev)

        adapter.add_callback(plates_cb)
        extra["force_top"] = np.full((R, P), np.nan)
        extra["force_bottom"] = np.full((R, P), np.nan)
        extra["force_sem"] = np.full((R, P), np.nan)
    else:
        top, bottom = pole_patches(mesh.vertices, **(pole_patch or {"fraction": 0.01}))
        kk = len(top)
        rows = np.concatenate([np.concatenate([o + top, o + bottom]) for o in offsets]).astype(np.int32)
        sign = np.tile(np.concatenate([-np.ones(kk), np.ones(kk)]), R).astype(adapter.np_dtype)
        rows_w = wp.array(rows, dtype=wp.int32, device=dev)
        sign_w = wp.array(sign, dtype=adapter.dtype, device=dev)
        inv_k = adapter.dtype(1.0 / kk)

        def poles_cb():
            wp.launch(k["pole_forces"], dim=len(rows), inputs=[adapter.f(), rows_w, sign_w, adapter.vrep,
                                                               adapter.status, state, adapter.step_counter, inv_k],
                      device=dev)

        adapter.add_callback(poles_cb)
        equator = np.nonzero(np.abs(z0 - z0.mean()) < 0.25 * mesh.min_edge_length())[0]
        adapter.anchor(np.concatenate([o + equator for o in offsets]).astype(np.int64))
        values = np.asarray(grid, dtype=np.float64)
        start_value = 0.0
        zmax = wp.zeros(R, dtype=adapter.dtype, device=dev)
        zmin = wp.zeros(R, dtype=adapter.dtype, device=dev)
        big = 1e30 if adapter.dtype is wp.float64 else 3e38
        d_ref = 2.0 * float(mesh.radius_dpd if mesh.radius_dpd > 0 else np.max(z0) - np.min(z0))
        extra["axial_diameter"] = np.full((R, P), np.nan)
        extra["axial_sem"] = np.full((R, P), np.nan)

        def extent():
            zmax.fill_(-big)
            zmin.fill_(big)
            wp.launch(k["z_extent"], dim=N, inputs=[adapter.x, adapter.vrep, zmax, zmin], device=dev)
            return zmax.numpy().astype(np.float64) - zmin.numpy().astype(np.float64)
    if hasattr(adapter, "finalize_callbacks"):
        adapter.finalize_callbacks()

    def set_ramp(v_from, v_to, n_ramp):
        state.assign(np.array([v_from, v_to, float(adapter_steps[0]), float(n_ramp)]))

    adapter_steps = [0]  # steps advanced so far (the device step counter starts at 0)

    def advance(n):
        adapter.advance(n)
        adapter_steps[0] += n

    def apply_health(j_done: int, where: str | None = None):
        names = adapter.health()
        for r, nm in enumerate(names):
            ts = STATUS_MAP.get(nm, "failed")
            if status[r] == "ok" and ts != "ok":
                status[r] = ts
                health[r] = {"check": nm, "at": where or f"point {j_done + 1}"}
                for jj in range(max(j_done, 0), P):
                    point_status[r][jj] = ts
                if j_done >= 0 and j_done < P:
                    obs[r, j_done:] = np.nan

    def timed_out() -> bool:
        return max_seconds is not None and time.perf_counter() - t0 > max_seconds

    set_ramp(start_value, start_value, 0)
    advance(steps.equilibration_steps)
    apply_health(0, "equilibration")
    h_eq = extent() if protocol == "indentation" else None
    prev = start_value
    n_samples = steps.hold_steps // steps.sample_every
    for j in range(P):
        if timed_out():
            for r in range(R):
                if status[r] == "ok":
                    status[r] = "timeout"
                    for jj in range(j, P):
                        point_status[r][jj] = "timeout"
            break
        target = float(values[j])
        ramp = steps.ramp_steps if target != prev else 0
        set_ramp(prev, target, ramp)
        advance(ramp)
        set_ramp(target, target, 0)
        samples = []
        if protocol == "compression":
            acc.zero_()
            last = np.zeros((R, 2))
            for _ in range(n_samples):
                advance(steps.sample_every)
                a = acc.numpy().copy()
                samples.append((a - last) / steps.sample_every)
                last = a
            s = np.asarray(samples)  # [S, R, 2] block means
            top, bot = s[:, :, 0].mean(axis=0), s[:, :, 1].mean(axis=0)
            tot = s.sum(axis=2)
            obs[:, j] = top + bot
            extra["force_top"][:, j] = top
            extra["force_bottom"][:, j] = bot
            extra["force_sem"][:, j] = tot.std(axis=0, ddof=1) / math.sqrt(len(tot)) if len(tot) > 1 else np.nan
        else:
            for _ in range(n_samples):
                advance(steps.sample_every)
                samples.append(extent())
            s = np.asarray(samples)  # [S, R]
            keep = s[int(math.floor(steps.discard_fraction * len(s))):] if len(s) > 1 else s
            obs[:, j] = d_ref - keep.mean(axis=0)
            extra["axial_diameter"][:, j] = keep.mean(axis=0)
            extra["axial_sem"][:, j] = keep.std(axis=0, ddof=1) / math.sqrt(len(keep)) if len(keep) > 1 else np.nan
        prev = target
        apply_health(j)
        if progress is not None:
            progress(j + 1, P, time.perf_counter() - t0)
    for r in range(R):
        if status[r] != "ok":
            for j in range(P):
                if point_status[r][j] != "ok":
                    obs[r, j] = np.nan
    out = {"observable": obs, "status": status, "point_status": point_status, "health": health,
           "steps": adapter_steps[0],
           "seconds": time.perf_counter() - t0, **{k_: v.tolist() for k_, v in extra.items()}}
    if h_eq is not None:
        out["axial_diameter_equilibrated"] = h_eq.tolist()
        out["initial_diameter_reference"] = d_ref
    return out
