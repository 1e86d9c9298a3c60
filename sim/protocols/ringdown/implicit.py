"""Ringdown in the implicit tier: only the shell vertices are scaled; the gas law follows the volume."""

from __future__ import annotations

import math

import numpy as np

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


def _run_implicit(diameter_um, p, seeds, *, device, mass_factor, perturbation, equilibration_steps, record_steps,
                  record_every, dt, subdivisions, record_vertices, vertex_every, max_vertices, n_periods,
                  samples_per_period, health_every, progress, settings) -> RingdownBatch:
    """The implicit tier's ringdown (arguments checked and converted by :func:`ringdown_batch`)."""
    from bubblecal.sim.engine import (
        HealthThresholds,
        ImplicitShellSystem,
        default_vertex_friction,
        shell_params_from_arrays,
    )
    from bubblecal.sim.engine.mesh import mesh_for_diameter
    from bubblecal.sim.engine.particles import RHO_SHELL_KG_M3

    known = {"dtype", "p0", "p_back", "p_water", "gamma", "kbt", "rho_shell_kg_m3", "rupture_strain"}
    unknown = sorted(set(settings) - known)
    if unknown:
        raise ValueError(f"unknown implicit-tier ringdown setting(s) {unknown}; allowed: {sorted(known)}")
    mesh = mesh_for_diameter(diameter_um, subdivisions)
    nv = mesh.n_vertices
    m_v = mesh.vertex_mass(float(settings.get("rho_shell_kg_m3", RHO_SHELL_KG_M3)), mass_factor=mass_factor)
    shell_mass = nv * m_v
    if dt is None:
        # fastest in-plane vertex mode omega_max ~ sqrt(12 ka / m_v): dt = 0.1 / omega_max, at most 1e-3
        dt = min(1e-3, 0.1 * math.sqrt(m_v / (12.0 * float(np.max(p["ka"])))))
    dt = float(dt)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be > 0, got {dt!r}")
    p0 = float(settings.get("p0", 3.0))
    pred0 = breathing_mode_prediction(p["ka"], mesh.radius_dpd, p0, shell_mass)
    eq_steps, rec_steps, every = _schedule(pred0["omega0"], dt, equilibration_steps, record_steps, record_every,
                                           n_periods, samples_per_period)
    hev = int(health_every) if health_every is not None else max(every, (5000 // every) * every)
    params = shell_params_from_arrays(p)
    gamma = settings.get("gamma")
    gamma = default_vertex_friction(mesh) if gamma is None else float(gamma)
    system = ImplicitShellSystem(mesh, params, p0=p0, p_back=float(settings.get("p_back", 91.0)),
                                 p_water=settings.get("p_water"), kbt=float(settings.get("kbt", 1.0)), gamma=gamma,
                                 vertex_mass=m_v, dt=dt, device=device, dtype=settings.get("dtype", "float32"),
                                 seed=list(seeds), pin_com=True, chunk=_divisor_at_most(every, 50))
    thresholds = HealthThresholds(rupture_strain=float(settings.get("rupture_strain", 1.0)))
    total = eq_steps + rec_steps

    def report(phase, done):
        if progress is not None:
            progress(phase, int(done), int(total))

    r_equil = _equilibrate(system, system.volumes, lambda: system.check_health(thresholds), eq_steps, every, hev,
                           report)
    p_gas = system.gas_pressure()
    h_eq = system.check_health(thresholds)
    report("equilibration", eq_steps)

    # perturbation: homothety of every live shell about its centroid (the gas law follows V)
    x = np.asarray(system.vertices(), dtype=np.float64)
    live = np.array([nm == "OK" for nm in h_eq["status"]])
    c = x.mean(axis=1, keepdims=True)
    x = np.where(live[:, None, None], c + (1.0 + float(perturbation)) * (x - c), x)
    system.set_vertices(x)

    vidx = _vertex_subset(nv, max_vertices) if record_vertices else None
    radius, verts, vt, health = _record(
        system, system.volumes, (lambda: np.asarray(system.vertices())[:, vidx]) if record_vertices else None,
        vertex_every, lambda: system.check_health(thresholds), rec_steps, every, dt, hev,
        lambda k: report("record", eq_steps + k * every))
    health = health or h_eq
    status = _replica_status(health["status"], radius)
    pred = breathing_mode_prediction(p["ka"], r_equil, p_gas, shell_mass,
                                     area_ratio=mesh.area() / (4.0 * math.pi * mesh.radius_dpd**2))
    info = {
        **_common_info("implicit", diameter_um, dt, eq_steps, rec_steps, every, mass_factor, perturbation, mesh, m_v,
                       r_equil, p_gas, pred),
        "device": str(system.device), "system": system.settings(),
        "health_final": {k: (np.asarray(v).tolist() if not isinstance(v, list) else v) for k, v in health.items()},
    }
    info["system"].pop("n_vertices", None)
    return RingdownBatch(t=np.arange(radius.shape[1]) * every * dt, radius=radius, status=status, params=p, seeds=seeds,
                         info=info, vertices=None if verts is None else np.stack(verts, axis=1),
                         vertex_t=None if vt is None else np.asarray(vt), vertex_indices=vidx)
