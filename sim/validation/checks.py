"""Shell (membrane) verification checks of docs/physics.md section 6 (checks 3-5) for ``bubblecal sim verify``.

Each check is ``check_xxx(quick: bool = True, device: str = "cpu") -> CheckResult`` and runs the Warp
kernels of :mod:`bubblecal.sim.engine.kernels.shell` on ``device`` (float64 wherever a tolerance needs it;
Warp runs float64 on CUDA as well).  ``ALL_SHELL_CHECKS`` lists them; the Reissner point load (check 5) is in
:mod:`bubblecal.sim.validation.reissner`.  Units: DPD (length r_c = 250 nm, energy k_BT, force k_BT / r_c).
"""

from __future__ import annotations

import math
import time

import numpy as np

from bubblecal.sim.validation.reissner import KA_REISSNER, KB_REISSNER, R_REISSNER, check_reissner_point_load
from bubblecal.sim.validation.result import CheckResult
from bubblecal.sim.validation.shell_field import float64_field, to_device, warp_quiet

__all__ = [
    "ALL_SHELL_CHECKS",
    "check_lim_finite_differences",
    "check_zero_force_reference",
    "check_bending_energies_icosphere",
    "check_constraint_scaling",
]


# ----------------------------------------------------------------------------------------------
# (a) Lim force = -grad W by finite differences; zero net force and torque per triangle
# ----------------------------------------------------------------------------------------------
def check_lim_finite_differences(quick: bool = True, device: str = "cpu") -> CheckResult:
    """Check 3: Lim force = -grad W by finite differences; zero net force and torque per triangle and in total.

    Parameters
    ----------
    quick : bool, optional
        Subdivision 1 (quick) or 2.
    device : str, optional
        Warp device.

    Returns
    -------
    CheckResult
        Measured: the largest relative deviation from the finite-difference forces (float64).
    """
    from bubblecal.sim.engine import ShellParams, icosphere
    from bubblecal.sim.validation.shell_reference import finite_difference_forces, lim_triangle_forces

    t0 = time.perf_counter()
    sub = 1 if quick else 2
    mesh = icosphere(2.0, sub)
    rng = np.random.default_rng(11)
    x = mesh.vertices + 0.1 * rng.standard_normal(mesh.vertices.shape)
    p = ShellParams(ka=50.0, mu=20.0, a3=-2.0, a4=8.0, b1=0.7, b2=0.75, kb=0.0, self_avoid=False)
    ff = float64_field(mesh, p, device)
    _, f = ff.energy_forces_numpy(x, with_energy=False)
    h = 1e-5
    f_fd = finite_difference_forces(lambda y: ff.energy_forces_numpy(y)[0][0, 0], x, h=h)
    rel = float(np.max(np.abs(f - f_fd)) / np.max(np.abs(f_fd)))
    ft = lim_triangle_forces(x, mesh, p)  # same closed form as the kernel, per triangle corner
    scale = float(np.max(np.abs(ft)))
    net = float(np.max(np.abs(ft.sum(axis=1)))) / scale
    xc = x[mesh.faces]
    torque = float(np.max(np.abs(np.cross(xc - xc.mean(axis=1, keepdims=True), ft).sum(axis=1)))) / (
        scale * float(np.max(mesh.edge_lengths(x))))
    net_kernel = float(np.max(np.abs(f.sum(axis=0)))) / float(np.max(np.abs(f)))
    torque_kernel = float(np.max(np.abs(np.cross(x - x.mean(axis=0), f).sum(axis=0)))) / (
        float(np.max(np.abs(f))) * 2.0)
    passed = rel < 1e-6 and net < 1e-12 and torque < 1e-12 and net_kernel < 1e-12 and torque_kernel < 1e-12
    return CheckResult(
        name="lim_force_fd", expected="F = -grad W; per-triangle net force and torque 0",
        measured=rel, tolerance="rel 1e-6 (FD); net/torque rel 1e-12", passed=passed,
        details={"subdivisions": sub, "fd_step": h, "per_triangle_net_force_rel": net,
                 "per_triangle_torque_rel": torque, "total_net_force_rel": net_kernel,
                 "total_torque_rel": torque_kernel, "dtype": "float64", "device": device,
                 "seconds": time.perf_counter() - t0})


# ----------------------------------------------------------------------------------------------
# (b) zero force at the reference
# ----------------------------------------------------------------------------------------------
def check_zero_force_reference(quick: bool = True, device: str = "cpu") -> CheckResult:
    """Check 3: zero force at the stress-free reference (float64; float32 too on a GPU or in the full check).

    Parameters
    ----------
    quick : bool, optional
        Subdivision 3 (quick) or 4.
    device : str, optional
        Warp device.

    Returns
    -------
    CheckResult
        Measured: max |F| / (ka 0.01 l_min) in float64.
    """
    wp = warp_quiet()
    from bubblecal.sim.engine import ShellParams, icosphere

    t0 = time.perf_counter()
    sub = 3 if quick else 4
    mesh = icosphere(R_REISSNER, sub)
    p = ShellParams(ka=KA_REISSNER, kb=KB_REISSNER, a3=-2.0, a4=8.0, b1=0.7, b2=0.75)
    out = {}
    dtypes = [("float64", wp.float64)] + ([("float32", wp.float32)] if device != "cpu" or not quick else [])
    for name, dt in dtypes:
        ff = float64_field(mesh, p, device, dt)
        e, f = ff.energy_forces_numpy(mesh.vertices)
        out[name] = (float(np.max(np.linalg.norm(f, axis=1))), e[0].tolist())
    # force scale: a 1 % edge stretch of one triangle
    fscale = KA_REISSNER * 0.01 * mesh.min_edge_length()
    rel64 = out["float64"][0] / fscale
    passed = rel64 < 1e-10 and abs(out["float64"][1][0]) < 1e-8 and abs(out["float64"][1][1]) < 1e-8
    details = {"subdivisions": sub, "force_scale": fscale, "device": device,
               "max_force_float64": out["float64"][0], "energies_float64": out["float64"][1]}
    if "float32" in out:
        rel32 = out["float32"][0] / fscale
        details["max_force_rel_float32"] = rel32
        passed = passed and rel32 < 1e-3
    details["seconds"] = time.perf_counter() - t0
    return CheckResult(name="zero_force_reference", expected="0 (stress-free reference)", measured=rel64,
                       tolerance="max|F| / (ka 0.01 l_min) < 1e-10 (float64), < 1e-3 (float32 round-off of positions)",
                       passed=passed, details=details)


# ----------------------------------------------------------------------------------------------
# (c) Juelicher / Kantor energies on icospheres
# ----------------------------------------------------------------------------------------------
JUELICHER_EXPECTED = {3: 25.180, 4: 25.145}


def check_bending_energies_icosphere(quick: bool = True, device: str = "cpu") -> CheckResult:
    """Check 4: Juelicher bending energy of unit-kb icospheres against the published values; Kantor 0.

    Parameters
    ----------
    quick : bool, optional
        Subdivision 3 only (quick) or 3 and 4.
    device : str, optional
        Warp device.

    Returns
    -------
    CheckResult
        Measured: the Juelicher energies (k_BT per unit kb).
    """
    from bubblecal.sim.engine import ShellParams, icosphere

    t0 = time.perf_counter()
    subs = (3,) if quick else (3, 4)
    measured = {}
    kantor = {}
    ok = True
    for s in subs:
        mesh = icosphere(1.7, s)
        ff = float64_field(mesh, ShellParams(ka=1.0, kb=1.0, bending="juelicher", self_avoid=False), device)
        ej = float(ff.energies(to_device(ff, mesh.vertices))[0, 1])
        fk = float64_field(mesh, ShellParams(ka=1.0, kb=1.0, bending="kantor", self_avoid=False), device)
        ek = float(fk.energies(to_device(fk, mesh.vertices))[0, 1])
        measured[s] = ej
        kantor[s] = ek
        ok = ok and abs(ej - JUELICHER_EXPECTED[s]) < 1e-3 and abs(ek) < 1e-10
    return CheckResult(
        name="bending_energy_icosphere",
        expected=", ".join(f"Juelicher {JUELICHER_EXPECTED[s]} (s{s})" for s in subs) + "; Kantor 0",
        measured=", ".join(f"{measured[s]:.4f}" for s in subs), tolerance="abs 1e-3 (Juelicher), 1e-10 (Kantor)",
        passed=ok, details={"juelicher_over_kb": measured, "kantor_over_kb": kantor, "8pi": 8 * math.pi,
                            "vertex_area": "barycentric", "seconds": time.perf_counter() - t0})


# ----------------------------------------------------------------------------------------------
# (d) energies under uniform scaling (analytic)
# ----------------------------------------------------------------------------------------------
def check_constraint_scaling(quick: bool = True, device: str = "cpu") -> CheckResult:
    """Energies under uniform scaling against their closed forms (Lim with beta = 0, U_A, U_V, -p_b dV; Kantor 0).

    Parameters
    ----------
    quick : bool, optional
        Subdivision 2 (quick) or 3.
    device : str, optional
        Warp device.

    Returns
    -------
    CheckResult
        Measured: the largest relative error over the scales 0.97 and 1.02.
    """
    from bubblecal.sim.engine import ShellParams, icosphere

    t0 = time.perf_counter()
    mesh = icosphere(3.0, 2 if quick else 3)
    p = ShellParams(ka=100.0, a3=-2.0, a4=8.0, b1=0.7, b2=0.75, kb=10.0, ka_tot=500.0, kv_tot=300.0,
                    p_back=7.0, self_avoid=False)
    ff = float64_field(mesh, p, device)
    a0, v0 = mesh.area(), mesh.volume()
    c = mesh.vertices.mean(axis=0)
    worst = 0.0
    rows = {}
    for lam in (0.97, 1.02):
        x = c + lam * (mesh.vertices - c)
        e = ff.energies(to_device(ff, x))[0]
        alpha = lam**2 - 1
        expect = np.array([
            a0 * 0.5 * p.ka * (alpha**2 + p.a3 * alpha**3 + p.a4 * alpha**4),  # Lim (beta = 0)
            0.0,                                                                 # Kantor is scale free
            p.ka_tot * a0 * (lam**2 - 1) ** 2 / 2,
            p.kv_tot * v0 * (lam**3 - 1) ** 2 / 2,
            -p.p_back * v0 * (lam**3 - 1),
        ])
        err = np.abs(e[:5] - expect) / np.maximum(np.abs(expect), 1e-300)
        err[1] = abs(e[1])
        rows[str(lam)] = {"measured": e[:5].tolist(), "expected": expect.tolist()}
        worst = max(worst, float(err.max()))
    return CheckResult(name="energies_under_scaling",
                       expected="Lim A0 ka/2 (a^2+a3 a^3+a4 a^4), U_A, U_V, -p_b dV analytic; Kantor 0",
                       measured=worst, tolerance="rel 1e-9", passed=worst < 1e-9,
                       details={"scales": rows, "seconds": time.perf_counter() - t0})


ALL_SHELL_CHECKS = [
    check_lim_finite_differences,
    check_zero_force_reference,
    check_bending_energies_icosphere,
    check_constraint_scaling,
    check_reissner_point_load,
]
