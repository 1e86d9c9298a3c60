"""Fluid, gas and impermeability checks of docs/physics.md section 6 (checks 1, 2, 6) and the bubble test.

Each ``check_xxx(quick=True, device="cpu") -> CheckResult`` (the row type of :mod:`bubblecal.sim.validation.result`).
Quick versions run on one CPU core within the default test budget: small boxes and few thousand
steps; their tolerances are the physics tolerances *plus* three standard errors of the measured mean
(block averages), and the standard error is reported -- so a quick check is wider, not meaningless.
Full versions (``quick=False``, meant for the GPU) use several replicas batched in one system for
statistics and the published step counts (10^5 steps for leaks and the bubble shape).

Expected numbers: DPD fluid rho = 3, kBT = 1: p = 23.64 (a = 25) and 89.05 (a = 100), independent
of gamma and s; <m v^2>/3 = 1 within 1 %; total momentum conserved to round-off; ideal gas in a
closed (here frozen) shell: p = N_g kBT / V_in; no water inside / gas outside the shell.  Units: DPD
(length r_c = 250 nm, energy k_BT, pressure k_BT / r_c^3).
"""

from __future__ import annotations

import functools
import math
import time

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.engine import bubble_spec
from bubblecal.sim.validation.result import CheckResult

__all__ = ["check_eos_a25", "check_eos_a100", "check_temperature", "check_momentum",
           "check_ideal_gas_pressure", "check_no_leaks", "check_bubble_shape", "ALL_FLUID_CHECKS",
           "block_mean_sem"]


def block_mean_sem(samples: np.ndarray, n_blocks: int = 10) -> tuple[float, float]:
    """Mean and standard error from block averages.

    Parameters
    ----------
    samples : numpy.ndarray
        Samples along axis 0 (flattened).
    n_blocks : int, optional
        Number of blocks (at least 2, at most half the samples).

    Returns
    -------
    mean, sem : float
    """
    s = np.asarray(samples, dtype=np.float64).reshape(-1)
    nb = max(2, min(n_blocks, len(s) // 2))
    blocks = np.array([b.mean() for b in np.array_split(s, nb)])
    return float(s.mean()), float(blocks.std(ddof=1) / math.sqrt(nb))


def _wp_quiet():
    """Warp with its messages off."""
    wp = require("warp", "sim")

    wp.config.quiet = True
    return wp


# ----------------------------------------------------------------------------------------------
# DPD fluid run shared by the EOS, temperature and momentum checks
# ----------------------------------------------------------------------------------------------
@functools.cache
def _fluid_run(quick: bool, device: str) -> dict:
    """Replicas of a = 25 and a = 100 (gamma = 4.5, s = 0.5 / 0.25) advanced in the same launches."""
    _wp_quiet()
    from bubblecal.sim.engine import ParticleSystem, ReplicaSpec, fluid_pair_table

    if quick:
        box, n_each, t_eq, t_prod, dt = (6.0, 6.0, 6.0), 1, 4.0, 10.0, 0.0025
    else:
        box, n_each, t_eq, t_prod, dt = (10.0, 10.0, 10.0), 4, 5.0, 40.0, 0.0025
    specs = []
    for k in range(n_each):
        specs.append(ReplicaSpec(box=box, pairs=fluid_pair_table(25.0, 4.5, 0.5), seed=11 + k))
        specs.append(ReplicaSpec(box=box, pairs=fluid_pair_table(100.0, 4.5, 0.25), seed=101 + k))
    t0 = time.perf_counter()
    ps = ParticleSystem(specs, dt=dt, device=device, dtype="float32", skin=0.4, chunk=25)
    ps.step(int(round(t_eq / dt)))
    p_start = ps.total_momentum()
    steps0 = ps.steps_done
    every = int(round(0.05 / dt))
    n_samples = int(round(t_prod / dt)) // every
    P, T = [], []
    for _ in range(n_samples):
        ps.step(every)
        p, t = ps.virial_pressure()
        P.append(p)
        T.append(ps.kinetic_temperature())
    p_end = ps.total_momentum()
    sol = ps.solvent_numpy()
    speed_sum = np.zeros(ps.R)
    np.add.at(speed_sum, sol["replica"], np.linalg.norm(sol["v"], axis=1))  # all masses 1
    P, T = np.array(P), np.array(T)
    a25 = np.arange(0, ps.R, 2)
    a100 = np.arange(1, ps.R, 2)
    return {
        "P25": P[:, a25].mean(axis=1), "P100": P[:, a100].mean(axis=1), "T": T.mean(axis=1),
        "T25": T[:, a25].mean(axis=1), "T100": T[:, a100].mean(axis=1),
        "dP": p_end - p_start, "speed_sum": speed_sum, "n_per_replica": ps.solvent_counts()[:, 0],
        "steps": ps.steps_done - steps0, "dt": dt, "box": box, "replicas": ps.R, "device": device,
        "wall_s": time.perf_counter() - t0, "rebuilds": ps.n_rebuilds, "overruns": ps.n_overruns,
    }


def _eos(quick: bool, device: str, key: str, a: float, expected: float, tol: float) -> CheckResult:
    """Equation-of-state row: block mean of the virial pressure against ``expected`` within ``tol`` + 3 SE."""
    run = _fluid_run(quick, device)
    mean, sem = block_mean_sem(run[key])
    width = tol + 3.0 * sem
    return CheckResult(
        name=f"EOS pressure a={a:g}", expected=f"{expected} (rho=3, kBT=1)", measured=round(mean, 4),
        tolerance=f"±{tol} + 3·SE = ±{width:.3f}", passed=bool(abs(mean - expected) <= width),
        details={"standard_error": sem, "replicas": run["replicas"] // 2, "box": run["box"], "dt": run["dt"],
                 "production_steps": run["steps"], "device": device, "gamma": 4.5, "s": 0.5 if a == 25 else 0.25})


def check_eos_a25(quick: bool = True, device: str = "cpu") -> CheckResult:
    """Check 1: virial pressure (kinetic + conservative) of the a = 25 fluid, 23.64 +- 0.1 (DPD pressure).

    Parameters
    ----------
    quick : bool, optional
        One small replica per fluid (quick) or four larger ones.
    device : str, optional
        Warp device.

    Returns
    -------
    CheckResult
    """
    return _eos(quick, device, "P25", 25.0, 23.64, 0.1)


def check_eos_a100(quick: bool = True, device: str = "cpu") -> CheckResult:
    """Check 1: virial pressure of the a = 100 fluid, 89.05 +- 0.5 (DPD pressure).

    Parameters
    ----------
    quick : bool, optional
        One small replica per fluid (quick) or four larger ones.
    device : str, optional
        Warp device.

    Returns
    -------
    CheckResult
    """
    return _eos(quick, device, "P100", 100.0, 89.05, 0.5)


def check_temperature(quick: bool = True, device: str = "cpu") -> CheckResult:
    """Check 1: <m v^2>/3 = 1 within 1 % (both fluids, kick-drift integrator at dt = 0.0025).

    Parameters
    ----------
    quick : bool, optional
        One small replica per fluid (quick) or four larger ones.
    device : str, optional
        Warp device.

    Returns
    -------
    CheckResult
    """
    run = _fluid_run(quick, device)
    mean, sem = block_mean_sem(run["T"])
    width = 0.01 + 3.0 * sem
    return CheckResult(
        name="temperature <mv²>/3", expected="1.0", measured=round(mean, 5),
        tolerance=f"±1% + 3·SE = ±{width:.4f}", passed=bool(abs(mean - 1.0) <= width),
        details={"standard_error": sem, "T_a25": float(run["T25"].mean()), "T_a100": float(run["T100"].mean()),
                 "dt": run["dt"]})


def check_momentum(quick: bool = True, device: str = "cpu") -> CheckResult:
    """Check 2: total momentum of the periodic fluid conserved to round-off over the production run.

    Bound: |dP| <= 10 eps32 sqrt(N steps) v_rms per replica (a random walk of float32 rounding); a non-symmetric
    random force would drift by ~ sigma sqrt(dt N_pairs steps), orders larger.

    Parameters
    ----------
    quick : bool, optional
        One small replica per fluid (quick) or four larger ones.
    device : str, optional
        Warp device.

    Returns
    -------
    CheckResult
    """
    run = _fluid_run(quick, device)
    eps = float(np.finfo(np.float32).eps)
    n = run["n_per_replica"].astype(float)
    bound = 10.0 * eps * np.sqrt(n * run["steps"]) * math.sqrt(3.0)
    dp = np.linalg.norm(run["dP"], axis=1)
    ratio = float(np.max(dp / bound))
    rel = float(np.max(dp / run["speed_sum"]))
    return CheckResult(
        name="momentum conservation", expected="|ΔP| at round-off", measured=f"{float(dp.max()):.2e}",
        tolerance=f"≤ 10·ε·√(N·steps)·v_rms = {float(bound.min()):.1e}", passed=bool(ratio <= 1.0),
        details={"dP_over_bound": ratio, "dP_over_sum_m_abs_v": rel, "steps": run["steps"]})


# ----------------------------------------------------------------------------------------------
# ideal gas in a closed, frozen shell
# ----------------------------------------------------------------------------------------------
def check_ideal_gas_pressure(quick: bool = True, device: str = "cpu") -> CheckResult:
    """Check 6: mechanical pressure of the gas on a closed (frozen) shell = N_g k_BT / V_in.

    The pressure is the outward normal momentum the bounce-back hands to the triangles per unit time and area
    (vertex-gas (0, gamma_fsi, 0.5) pairs have zero mean force on a resting wall).  The ideal-gas law does not
    depend on the bead mass or the friction, so the check uses a gas bead of mass 0.1 and gas-gas (0, 1, 0.5) at
    dt = 1e-3, which resolves the gas dynamics (gamma dt / m = 0.01) at a tenth of the steps.  The published gas
    (m = 0.0112, gamma = 11) has gamma dt / m ~ 1 at dt = 1e-3 and needs the production dt = 1e-4, where the
    kick-drift integrator still shows an O(gamma dt / m) temperature bias (benchmarks/RESULTS.md).

    Parameters
    ----------
    quick : bool, optional
        One R = 3 shell for 6 time units (quick) or eight R = 4 shells for 20.
    device : str, optional
        Warp device.

    Returns
    -------
    CheckResult
        Measured: p / (N_g k_BT / V_in).
    """
    _wp_quiet()
    from bubblecal.sim.engine import (
        GAS,
        ParticleSystem,
        ReplicaSpec,
        ShellParams,
        icosphere,
        published_pair_table,
    )

    if quick:
        radius, subdiv, n_rep, t_prod, dt = 3.0, 3, 1, 6.0, 1e-3
    else:
        radius, subdiv, n_rep, t_prod, dt = 4.0, 3, 8, 20.0, 1e-3
    mesh = icosphere(radius, subdiv)
    tab = published_pair_table(mesh.n_vertices / mesh.area(), m_vertex=mesh.vertex_mass())
    tab.set(GAS, GAS, 0.0, 1.0, 0.5)
    tab.mass[GAS] = 0.1
    box = (2 * radius + 3.0,) * 3
    specs = [ReplicaSpec(box=box, pairs=tab, seed=500 + k, water_density=0.0, gas_density=3.0, mesh=mesh,
                         shell=ShellParams(ka=100.0, kb=10.0, self_avoid=False), frozen_shell=True)
             for k in range(n_rep)]
    ps = ParticleSystem(specs, dt=dt, device=device, skin=0.4, chunk=20)
    ps.step(int(round(0.5 / dt)))
    ps.impulse.zero_()
    ps.nbounce.zero_()
    n_blocks = 10
    steps_block = int(round(t_prod / dt)) // n_blocks
    area, vol = ps.shell_area_volume()
    ng = ps.solvent_counts()[:, 1].astype(float)
    expected = ng * np.asarray(ps.kbt_np) / vol
    blocks = []
    last = np.zeros(ps.R)
    for _ in range(n_blocks):
        ps.step(steps_block)
        imp = ps.impulse.numpy().astype(np.float64)
        blocks.append((imp - last) / (area * steps_block * dt) / expected)
        last = imp
    ratios = np.array(blocks).mean(axis=1)  # measured / expected per block, averaged over replicas
    mean, sem = float(ratios.mean()), float(ratios.std(ddof=1) / math.sqrt(n_blocks))
    tol = 0.02
    width = tol + 3 * sem
    return CheckResult(
        name="ideal-gas pressure in shell", expected="p/(N_g kBT/V_in) = 1", measured=round(mean, 4),
        tolerance=f"±2% + 3·SE = ±{width:.3f}", passed=bool(abs(mean - 1.0) <= width),
        details={"standard_error": sem, "N_g": ng.tolist(), "V_in": vol.tolist(), "p_expected": expected.tolist(),
                 "bounces": ps.nbounce.numpy().tolist(), "radius": radius, "replicas": n_rep, "dt": dt})


# ----------------------------------------------------------------------------------------------
# explicit-solvent bubble: leaks and shape
# ----------------------------------------------------------------------------------------------
@functools.cache
def _bubble_run(quick: bool, device: str) -> dict:
    """Explicit-solvent bubble run shared by the leak and shape checks (cached per quick / device)."""
    _wp_quiet()
    from bubblecal.sim.engine import HealthConfig, HealthMonitor, ParticleSystem

    if quick:
        # 1.5 um bubble (R = 3, subdivision 3) in a 9^3 box, 3,000 steps
        specs = [bubble_spec(1.5, 3, box=(9.0, 9.0, 9.0), seed=7)]
        n_steps, every = 3000, 500
    else:
        # the published 3 um bubble (R = 6, subdivision 4) in a 17 x 17 x 22 box, 10^5 steps
        specs = [bubble_spec(3.0, 4, box=(17.0, 17.0, 22.0), seed=7 + k) for k in range(2)]
        n_steps, every = 100_000, 5000
    t0 = time.perf_counter()
    ps = ParticleSystem(specs, dt=1e-4, device=device, skin=0.4, chunk=10)
    hm = HealthMonitor(HealthConfig(max_leaks=10**9))  # count leaks, do not freeze on them
    a0, v0 = ps.shell_area_volume()
    vol_hist, rad_dev = [], []
    max_leaks = np.zeros(ps.R, dtype=int)
    for _ in range(n_steps // every):
        ps.step(every)
        rep = hm.check(ps)
        max_leaks = np.maximum(max_leaks, np.array(rep.water_inside) + np.array(rep.gas_outside))
        _, vol = ps.shell_area_volume()
        vol_hist.append(vol / v0)
        devs = []
        for r in range(ps.R):
            xv = ps.vertices_numpy(r)
            rr = np.linalg.norm(xv - xv.mean(axis=0), axis=1)
            devs.append(float(rr.std() / rr.mean()))
        rad_dev.append(devs)
    return {"status": rep.status, "max_leaks": max_leaks, "vol": np.array(vol_hist), "rad_dev": np.array(rad_dev),
            "steps": ps.steps_done, "n_solvent": ps.N, "n_vertices": ps.Nv, "replicas": ps.R,
            "wall_s": time.perf_counter() - t0, "max_strain": rep.max_area_strain, "overruns": ps.n_overruns,
            "counts": ps.solvent_counts().tolist()}


def check_no_leaks(quick: bool = True, device: str = "cpu") -> CheckResult:
    """Check 6: no water inside and no gas outside the shell at any health check of the bubble run.

    Parameters
    ----------
    quick : bool, optional
        A 1.5 um bubble for 3,000 steps (quick) or two published 3 um bubbles for 10^5 steps.
    device : str, optional
        Warp device.

    Returns
    -------
    CheckResult
    """
    run = _bubble_run(quick, device)
    leaks = int(run["max_leaks"].max())
    return CheckResult(
        name="no leaks through shell", expected="0 water inside, 0 gas outside", measured=leaks,
        tolerance="0", passed=bool(leaks == 0 and all(s in ("OK",) for s in run["status"])),
        details={"steps": run["steps"], "replicas": run["replicas"], "status": run["status"],
                 "counts_per_type": run["counts"], "wall_s": run["wall_s"]})


def check_bubble_shape(quick: bool = True, device: str = "cpu") -> CheckResult:
    """The bubble holds its shape at the published parameters.

    |V/V0 - 1| <= 10 % and vertex-radius scatter <= 5 % of the mean radius over the second half of the run; no
    inversion, rupture or NaN.

    Parameters
    ----------
    quick : bool, optional
        A 1.5 um bubble for 3,000 steps (quick) or two published 3 um bubbles for 10^5 steps.
    device : str, optional
        Warp device.

    Returns
    -------
    CheckResult
    """
    run = _bubble_run(quick, device)
    half = run["vol"][len(run["vol"]) // 2:]
    vdev = float(np.max(np.abs(half - 1.0)))
    rdev = float(np.max(run["rad_dev"][len(run["rad_dev"]) // 2:]))
    ok = vdev <= 0.10 and rdev <= 0.05 and all(s == "OK" for s in run["status"])
    return CheckResult(
        name="bubble holds shape", expected="V/V0≈1, sphere", measured=f"max|V/V0-1|={vdev:.3f}, σr/r={rdev:.3f}",
        tolerance="≤0.10, ≤0.05", passed=bool(ok),
        details={"steps": run["steps"], "status": run["status"], "final_V_over_V0": run["vol"][-1].tolist(),
                 "max_area_strain": run["max_strain"], "n_solvent": run["n_solvent"],
                 "n_vertices": run["n_vertices"], "wall_s": run["wall_s"], "overruns": run["overruns"]})


ALL_FLUID_CHECKS = [check_eos_a25, check_eos_a100, check_temperature, check_momentum, check_ideal_gas_pressure,
                    check_no_leaks, check_bubble_shape]
