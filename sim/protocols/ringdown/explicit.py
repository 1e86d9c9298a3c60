"""Ringdown in the explicit tier: shell + explicit water and gas, the perturbation a homothety (package docstring)."""

from __future__ import annotations

import math

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.protocols.ringdown.prediction import _schedule, breathing_mode_prediction
from bubblecal.sim.protocols.ringdown.recording import (
    _common_info,
    _divisor_at_most,
    _equilibrate,
    _record,
    _replica_status,
    _vertex_subset,
)
from bubblecal.sim.protocols.ringdown.result import RingdownBatch


def _run_explicit(diameter_um, p, seeds, *, device, mass_factor, perturbation, equilibration_steps, record_steps,
                  record_every, dt, subdivisions, record_vertices, vertex_every, max_vertices, n_periods,
                  samples_per_period, health_every, progress, settings) -> RingdownBatch:
    """The explicit tier's ringdown (arguments checked and converted by :func:`ringdown_batch`)."""
    wp = require("warp", "sim")

    from bubblecal.sim.engine import ParticleSystem, bubble_spec
    from bubblecal.sim.engine.health import HealthConfig, HealthMonitor
    from bubblecal.sim.engine.particles import GAS, WATER

    known = {"dtype", "box", "p_back", "gas_density", "rho_shell_kg_m3", "a_vertex_water", "water_layer", "pin_com",
             "max_leaks", "check_leaks", "kbt"}
    unknown = sorted(set(settings) - known)
    if unknown:
        raise ValueError(f"unknown explicit-tier ringdown setting(s) {unknown}; allowed: {sorted(known)}")
    dtype = settings.get("dtype", "float32")
    water_layer = float(settings.get("water_layer", 2.0))
    if not water_layer > 0:
        raise ValueError(f"water_layer must be > 0, got {water_layer}")
    dt = 1e-4 if dt is None else float(dt)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be > 0, got {dt!r}")
    R = len(seeds)
    specs = []
    for r in range(R):
        spec = bubble_spec(diameter_um, subdivisions=subdivisions, box=settings.get("box"), seed=seeds[r],
                           ka=float(p["ka"][r]), kb=float(p["kb"][r]), p_back=float(settings.get("p_back", 91.0)),
                           gas_density=float(settings.get("gas_density", 3.0)), protocol="compression",
                           rho_shell_kg_m3=settings.get("rho_shell_kg_m3"), mass_factor=mass_factor,
                           a_vertex_water=settings.get("a_vertex_water"), kbt=float(settings.get("kbt", 1.0)),
                           b1=float(p["b1"][r]), b2=float(p["b2"][r]), a3=float(p["a3"][r]), a4=float(p["a4"][r]))
        spec.pin_com = bool(settings.get("pin_com", False))
        specs.append(spec)
    mesh = specs[0].mesh
    nv = mesh.n_vertices
    m_v = float(specs[0].pairs.mass[2])
    shell_mass = nv * m_v
    box = np.asarray(specs[0].box, dtype=np.float64)
    p_gas0 = float(settings.get("gas_density", 3.0)) * float(settings.get("kbt", 1.0))
    pred0 = breathing_mode_prediction(p["ka"], mesh.radius_dpd, p_gas0, shell_mass, explicit=True, box=box)
    eq_steps, rec_steps, every = _schedule(pred0["omega0_water"], dt, equilibration_steps, record_steps,
                                           record_every, n_periods, samples_per_period)
    hev = int(health_every) if health_every is not None else max(every, (5000 // every) * every)
    system = ParticleSystem(specs, dt=dt, device=device, dtype=dtype, chunk=_divisor_at_most(every, 50))
    monitor = HealthMonitor(HealthConfig(max_leaks=int(settings.get("max_leaks", 5)),
                                         check_leaks=bool(settings.get("check_leaks", True))))
    total = eq_steps + rec_steps

    def report(phase, done):
        if progress is not None:
            progress(phase, int(done), int(total))

    # ---- equilibration (mean R over its last 10 %) ----
    def volumes():
        return system.shell_area_volume()[1]

    r_equil = _equilibrate(system, volumes, lambda: monitor.check(system), eq_steps, every, hev, report)
    if eq_steps:
        monitor.check(system)
        report("equilibration", eq_steps)
    # gas pressure inside from the ideal-gas law (gas-gas a = 0)
    _, vol = system.shell_area_volume()
    n_gas = system.solvent_counts()[:, GAS].astype(np.float64)
    kbt = np.asarray(system.kbt_np, dtype=np.float64)
    p_gas = n_gas * kbt / vol

    # ---- perturbation: homothety of shell + gas + near water about the centroid ----
    npf = system.np_dtype
    xv = system.xv.numpy().astype(np.float64)
    x = system.x.numpy().astype(np.float64)
    rep = system.rep.numpy()
    typ = system.typ.numpy()
    status_now = system.status_numpy()
    s = float(perturbation)
    for r in range(R):
        if status_now[r] != 0:
            continue
        o, n = int(system.vertex_offset[r]), int(system.vertex_count[r])
        c = xv[o:o + n].mean(axis=0)
        dv = xv[o:o + n] - c
        r_a = float(np.linalg.norm(dv, axis=1).max())
        xv[o:o + n] = c + (1.0 + s) * dv
        L = system.boxes[r]
        sel = np.flatnonzero(rep == r)
        dx = x[sel] - c
        dx -= L * np.round(dx / L)
        dist = np.linalg.norm(dx, axis=1)
        is_gas = typ[sel] == GAS
        is_water = typ[sel] == WATER
        # gas: the homothety (stays inside); water: homothety up to r_a, then a linear taper to 0
        shift = np.where(dist <= r_a, s * dist, s * r_a * np.clip(1.0 - (dist - r_a) / water_layer, 0.0, 1.0))
        shift = np.where(is_gas, s * dist, np.where(is_water, shift, 0.0))
        unit = dx / np.maximum(dist, 1e-12)[:, None]
        newx = c + dx + unit * shift[:, None]
        x[sel] = newx - L * np.floor(newx / L)
    system.xv.assign(xv.astype(npf))
    system.x.assign(x.astype(npf))
    system.rebuild()
    rep_after = monitor.check(system) if bool(settings.get("check_leaks", True)) else None

    # ---- record ----
    vidx = _vertex_subset(nv, max_vertices) if record_vertices else None

    def frame():
        allv = system.xv.numpy()
        return np.stack([allv[int(system.vertex_offset[r]) + vidx] for r in range(R)])

    radius, verts, vt, _ = _record(
        system, lambda: system.shell_area_volume()[1], frame if record_vertices else None, vertex_every,
        lambda: monitor.check(system), rec_steps, every, dt, hev, lambda k: report("record", eq_steps + k * every))
    final = monitor.reports[-1] if monitor.reports else None
    names = final.status if final is not None else ["OK"] * R
    status = _replica_status(names, radius)
    pred = breathing_mode_prediction(p["ka"], r_equil, p_gas, shell_mass, explicit=True, box=box,
                                     area_ratio=mesh.area() / (4.0 * math.pi * mesh.radius_dpd**2))
    info = {
        **_common_info("explicit", diameter_um, dt, eq_steps, rec_steps, every, mass_factor, perturbation, mesh, m_v,
                       r_equil, p_gas, pred),
        "box": box.tolist(),
        "n_particles": int(system.N), "device": str(system.device), "dtype": str(np.dtype(npf)),
        "water_layer": water_layer, "pin_com": bool(settings.get("pin_com", False)),
        "health_after_perturbation": None if rep_after is None else rep_after.as_dict(),
        "health_final": None if final is None else final.as_dict(),
        "neighbor_rebuilds": int(system.n_rebuilds), "warp_version": wp.config.version,
    }
    return RingdownBatch(t=np.arange(radius.shape[1]) * every * dt, radius=radius, status=status, params=p, seeds=seeds,
                         info=info, vertices=None if verts is None else np.stack(verts, axis=1),
                         vertex_t=None if vt is None else np.asarray(vt), vertex_indices=vidx)
