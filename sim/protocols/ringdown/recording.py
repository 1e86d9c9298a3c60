"""Shared steps of the ringdown runners: equilibration, recording R(t), statuses and the common info."""

from __future__ import annotations

import math

import numpy as np

from bubblecal.sim.protocols.health_status import STATUS_MAP

__all__ = ["radius_from_volume"]


def _divisor_at_most(n: int, cap: int) -> int:
    """The largest divisor of ``n`` that is at most ``cap`` (engine steps per CUDA graph chunk)."""
    for d in range(min(n, cap), 0, -1):
        if n % d == 0:
            return d
    return 1


def _vertex_subset(n_vertices: int, max_vertices: int | None) -> np.ndarray:
    """First 10 4^k + 2 <= max_vertices vertex indices (a coarser icosphere); all if None."""
    if max_vertices is None or max_vertices >= n_vertices:
        return np.arange(n_vertices)
    k = 0
    while 10 * 4 ** (k + 1) + 2 <= max_vertices and 10 * 4 ** (k + 1) + 2 <= n_vertices:
        k += 1
    return np.arange(min(n_vertices, 10 * 4**k + 2))


def radius_from_volume(volume):
    """Radius of the sphere of an enclosed volume.

    Parameters
    ----------
    volume : array_like
        Enclosed volume V (DPD length^3).

    Returns
    -------
    numpy.ndarray
        R = (3 V / 4 pi)^(1/3) (DPD length); NaN where V <= 0.
    """
    v = np.asarray(volume, dtype=np.float64)
    return np.where(v > 0, np.cbrt(np.abs(3.0 * v / (4.0 * math.pi))), np.nan)


def _equilibrate(system, volumes, check, eq_steps: int, every: int, hev: int, report) -> np.ndarray:
    """Step ``eq_steps`` (``check()`` every ``hev`` steps); returns the mean R [R] over the last 10 %,
    sampled every ``every`` steps (DPD length)."""
    tail = max(every, eq_steps // 10) if eq_steps else 0
    head = eq_steps - tail
    done = 0
    while done < head:
        n = min(hev, head - done)
        system.step(n)
        done += n
        check()
        report("equilibration", done)
    r_eq = []
    while done < eq_steps:
        n = min(every, eq_steps - done)
        system.step(n)
        done += n
        r_eq.append(radius_from_volume(volumes()))
    return np.nanmean(np.array(r_eq), axis=0) if r_eq else radius_from_volume(volumes())


def _record(system, volumes, frame, vertex_every: int, check, rec_steps: int, every: int, dt: float, hev: int,
            report):
    """Record R(t) = (3 V / 4 pi)^(1/3) [R, T] (DPD length) every ``every`` steps over ``rec_steps``;
    ``frame()`` -> vertices [R, Nv', 3] every ``vertex_every``-th record when given (else None);
    ``check()`` every ``hev`` steps and at the end.  Returns (radius, frames or None, their times, last check)."""
    n_rec = rec_steps // every + 1
    radius = np.full((np.asarray(volumes()).shape[0], n_rec), np.nan)
    verts, vt = ([], []) if frame is not None else (None, None)

    def sample(k):
        radius[:, k] = radius_from_volume(volumes())
        if frame is not None and k % vertex_every == 0:
            verts.append(np.asarray(frame(), dtype=np.float32))
            vt.append(k * every * dt)

    sample(0)
    since, last = 0, None
    for k in range(1, n_rec):
        system.step(every)
        since += every
        sample(k)
        if since >= hev or k == n_rec - 1:
            last = check()
            since = 0
            report(k)
    return radius, verts, vt, last


def _replica_status(health_names, radius: np.ndarray) -> list[str]:
    """STATUSES per replica from the health verdicts; an 'ok' replica with a non-finite R(t) is 'failed'."""
    status = [STATUS_MAP.get(nm, "failed") for nm in health_names]
    return [("failed" if st == "ok" and not np.all(np.isfinite(radius[r])) else st) for r, st in enumerate(status)]


def _common_info(tier, diameter_um, dt, eq_steps, rec_steps, every, mass_factor, perturbation, mesh, m_v, r_equil,
                 p_gas, pred) -> dict:
    """The ``RingdownBatch.info`` entries both tiers report (DPD units)."""
    return {
        "tier": tier, "diameter_um": diameter_um, "dt": dt, "equilibration_steps": eq_steps,
        "record_steps": rec_steps, "record_every": every, "mass_factor": mass_factor,
        "perturbation": perturbation, "n_vertices": mesh.n_vertices, "vertex_mass": m_v,
        "shell_mass": mesh.n_vertices * m_v, "mesh_subdivisions": mesh.subdivisions,
        "radius_reference": mesh.radius_dpd, "radius_equilibrium": np.asarray(r_equil).tolist(),
        "p_gas": np.asarray(p_gas).tolist(), "prediction": {k: np.asarray(v).tolist() for k, v in pred.items()},
    }
