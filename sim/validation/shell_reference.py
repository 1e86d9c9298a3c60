"""Pure NumPy float64 reference of the shell energies and forces (physics.md section 3).

Slow but transparent: the ground truth for the Warp kernels in :mod:`bubblecal.sim.engine.kernels.shell`
and for finite-difference tests.  Geometric conventions: :mod:`bubblecal.sim.engine.mesh`.

Energy terms, in the order of :data:`ENERGY_TERMS` (also the columns of
``ShellForceField.energies``):

* ``in_plane``      Lim: sum_t A0 [(ka/2)(alpha^2 + a3 alpha^3 + a4 alpha^4) + mu (beta + b1 alpha beta + b2 beta^2)]
* ``bending``       Kantor kb sum_e [1 - cos(theta_e - theta0_e)]  or  Juelicher 2 kb sum_v A_v (H_v - c0/2)^2
* ``area``          ka_tot (A - A0)^2 / (2 A0)
* ``volume``        kv_tot (V - V0)^2 / (2 V0)
* ``back_pressure`` -p_back (V - V0)   (the work of the constant outward back pressure)
* ``self_avoid``    WCA Lennard-Jones between the vertices of one shell
"""

from __future__ import annotations

import numpy as np

from bubblecal.sim.engine import ShellMesh, ShellParams
from bubblecal.sim.engine.mesh import dihedral_angles

__all__ = [
    "ENERGY_TERMS",
    "AREA_CLAMP",
    "lim_energy",
    "lim_forces",
    "kantor_energy",
    "kantor_forces",
    "juelicher_energy",
    "juelicher_forces",
    "dihedral_angle_gradients",
    "area_gradient",
    "volume_gradient",
    "constraint_energies",
    "constraint_forces",
    "self_avoid_energy",
    "self_avoid_forces",
    "shell_energies",
    "shell_forces",
    "finite_difference_forces",
]

ENERGY_TERMS = ("in_plane", "bending", "area", "volume", "back_pressure", "self_avoid")

#: Lower clamp of the current triangle area in the Lim energy (physics.md section 3).
AREA_CLAMP = 1e-6


def finite_difference_forces(energy, x: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Forces -dE/dx [DPD force] by central differences of ``energy(x) -> float`` over positions x [Nv, 3]."""
    g = np.zeros_like(x)
    for i in range(x.shape[0]):
        for k in range(3):
            xp, xm = x.copy(), x.copy()
            xp[i, k] += h
            xm[i, k] -= h
            g[i, k] = (energy(xp) - energy(xm)) / (2 * h)
    return -g


def _scatter(n_vertices: int, idx: np.ndarray, vals: np.ndarray) -> np.ndarray:
    """Sum rows of ``vals [M,3]`` into vertices ``idx [M]``."""
    out = np.zeros((n_vertices, 3))
    for k in range(3):
        out[:, k] = np.bincount(idx, weights=vals[:, k], minlength=n_vertices)
    return out


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


# ----------------------------------------------------------------------------------------------
# Lim in-plane energy
# ----------------------------------------------------------------------------------------------
def _lim_parts(x: np.ndarray, mesh: ShellMesh, p: ShellParams):
    f = mesh.faces
    x12 = x[f[:, 1]] - x[f[:, 0]]
    x13 = x[f[:, 2]] - x[f[:, 0]]
    n = np.cross(x12, x13)
    nn = np.linalg.norm(n, axis=1)
    area = np.maximum(0.5 * nn, AREA_CLAMP)
    a0 = mesh.A0
    alpha = area / a0 - 1.0
    num = mesh.l1**2 * _dot(x13, x13) + mesh.l2**2 * _dot(x12, x12) - 2.0 * mesh.d0 * _dot(x12, x13)
    beta = num / (8.0 * a0 * area) - 1.0
    return x12, x13, n, nn, area, alpha, beta


def lim_energy(x: np.ndarray, mesh: ShellMesh, p: ShellParams, per_triangle: bool = False):
    """Lim in-plane energy (total, or per triangle)."""
    x = np.asarray(x, dtype=np.float64)
    *_, alpha, beta = _lim_parts(x, mesh, p)
    w = mesh.A0 * (0.5 * p.ka * (alpha**2 + p.a3 * alpha**3 + p.a4 * alpha**4)
                   + p.mu * (beta + p.b1 * alpha * beta + p.b2 * beta**2))
    return w if per_triangle else float(np.sum(w))


def lim_triangle_forces(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> np.ndarray:
    """Closed-form Lim forces -dW_t/dx per triangle corner: [Nt, 3 corners, 3]."""
    x = np.asarray(x, dtype=np.float64)
    x12, x13, n, nn, area, alpha, beta = _lim_parts(x, mesh, p)
    a0 = mesh.A0
    dw_da = a0 * (0.5 * p.ka * (2 * alpha + 3 * p.a3 * alpha**2 + 4 * p.a4 * alpha**3) + p.mu * p.b1 * beta)
    dw_db = a0 * p.mu * (1.0 + p.b1 * alpha + 2.0 * p.b2 * beta)
    # dA/dx (zero where the clamp is active)
    active = (0.5 * nn) > AREA_CLAMP
    nhat = n / np.maximum(nn, 1e-300)[:, None]
    x23 = x13 - x12  # x3 - x2
    ga = np.stack([0.5 * np.cross(nhat, x23), 0.5 * np.cross(nhat, -x13), 0.5 * np.cross(nhat, x12)], axis=1)
    ga *= active[:, None, None]
    # dN/dx
    gn2 = 2.0 * mesh.l2[:, None] ** 2 * x12 - 2.0 * mesh.d0[:, None] * x13
    gn3 = 2.0 * mesh.l1[:, None] ** 2 * x13 - 2.0 * mesh.d0[:, None] * x12
    gn = np.stack([-(gn2 + gn3), gn2, gn3], axis=1)
    inv = 1.0 / (8.0 * a0 * area)
    dbeta = gn * inv[:, None, None] - ((beta + 1.0) / area)[:, None, None] * ga
    dalpha = ga / a0[:, None, None]
    return -(dw_da[:, None, None] * dalpha + dw_db[:, None, None] * dbeta)


def lim_forces(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> np.ndarray:
    """Lim forces on the vertices [Nv,3]."""
    ft = lim_triangle_forces(x, mesh, p)
    return _scatter(mesh.n_vertices, mesh.faces.reshape(-1), ft.reshape(-1, 3))


# ----------------------------------------------------------------------------------------------
# bending
# ----------------------------------------------------------------------------------------------
def dihedral_angle_gradients(x: np.ndarray, mesh: ShellMesh) -> tuple[np.ndarray, np.ndarray]:
    """theta_e [Ne] and d theta_e / d(a, b, c, d) [Ne, 4, 3] (closed form)."""
    x = np.asarray(x, dtype=np.float64)
    dh = mesh.dihedrals
    a, b, c, d = (x[dh[:, k]] for k in range(4))
    e = b - a
    n1 = np.cross(e, c - a)
    n2 = np.cross(-e, d - b)
    el2 = _dot(e, e)
    el = np.sqrt(el2)
    theta = np.arctan2(_dot(np.cross(n1, n2), e) / el, _dot(n1, n2))
    gc = -(el / _dot(n1, n1))[:, None] * n1
    gd = -(el / _dot(n2, n2))[:, None] * n2
    sc = (_dot(c - a, e) / el2)[:, None]
    sd = (_dot(d - a, e) / el2)[:, None]
    ga = -(1.0 - sc) * gc - (1.0 - sd) * gd
    gb = -sc * gc - sd * gd
    return theta, np.stack([ga, gb, gc, gd], axis=1)


def kantor_energy(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> float:
    """Stress-free Kantor energy kb sum_e [1 - cos(theta_e - theta0_e)]."""
    theta = dihedral_angles(x, mesh.dihedrals)
    return float(p.kb * np.sum(1.0 - np.cos(theta - mesh.theta0)))


def kantor_forces(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> np.ndarray:
    theta, g = dihedral_angle_gradients(x, mesh)
    coef = -p.kb * np.sin(theta - mesh.theta0)
    return _scatter(mesh.n_vertices, mesh.dihedrals.reshape(-1), (coef[:, None, None] * g).reshape(-1, 3))


def _juelicher_parts(x: np.ndarray, mesh: ShellMesh):
    x = np.asarray(x, dtype=np.float64)
    theta, g = dihedral_angle_gradients(x, mesh)
    e = x[mesh.edges[:, 1]] - x[mesh.edges[:, 0]]
    le = np.linalg.norm(e, axis=1)
    m = np.bincount(mesh.edges[:, 0], weights=le * theta, minlength=mesh.n_vertices)
    m += np.bincount(mesh.edges[:, 1], weights=le * theta, minlength=mesh.n_vertices)
    av = mesh.vertex_areas(x)
    return theta, g, e, le, m, av


def juelicher_energy(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> float:
    """Juelicher energy 2 kb sum_v A_v (H_v - c0/2)^2, H_v = sum_e l_e theta_e / (4 A_v), barycentric A_v."""
    *_, m, av = _juelicher_parts(x, mesh)
    h = m / (4.0 * av)
    return float(2.0 * p.kb * np.sum(av * (h - 0.5 * p.c0) ** 2))


def juelicher_forces(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    theta, g, e, le, m, av = _juelicher_parts(x, mesh)
    h = m / (4.0 * av)
    c_m = p.kb * (h - 0.5 * p.c0)                     # dE/dM_v
    c_a = 2.0 * p.kb * (0.25 * p.c0**2 - h**2)        # dE/dA_v
    ce = c_m[mesh.edges[:, 0]] + c_m[mesh.edges[:, 1]]
    ehat = e / le[:, None]
    # d(l theta) = theta dl + l dtheta
    gl = le[:, None, None] * g
    gl[:, 0] -= theta[:, None] * ehat
    gl[:, 1] += theta[:, None] * ehat
    f = _scatter(mesh.n_vertices, mesh.dihedrals.reshape(-1), (-ce[:, None, None] * gl).reshape(-1, 3))
    ct = c_a[mesh.faces].sum(axis=1) / 3.0
    ga = area_gradient(x, mesh)
    f += _scatter(mesh.n_vertices, mesh.faces.reshape(-1), (-ct[:, None, None] * ga).reshape(-1, 3))
    return f


# ----------------------------------------------------------------------------------------------
# global constraints, back pressure
# ----------------------------------------------------------------------------------------------
def area_gradient(x: np.ndarray, mesh: ShellMesh) -> np.ndarray:
    """dA_t/dx per triangle corner [Nt,3,3]."""
    f = mesh.faces
    x0, x1, x2 = x[f[:, 0]], x[f[:, 1]], x[f[:, 2]]
    n = np.cross(x1 - x0, x2 - x0)
    nhat = n / np.linalg.norm(n, axis=1, keepdims=True)
    return 0.5 * np.stack([np.cross(nhat, x2 - x1), np.cross(nhat, x0 - x2), np.cross(nhat, x1 - x0)], axis=1)


def volume_gradient(x: np.ndarray, mesh: ShellMesh) -> np.ndarray:
    """dV/dx_v [Nv,3] = sum over adjacent triangles of n_t / 6 (n_t = unnormalised outward normal)."""
    f = mesh.faces
    n = np.cross(x[f[:, 1]] - x[f[:, 0]], x[f[:, 2]] - x[f[:, 0]]) / 6.0
    return _scatter(mesh.n_vertices, f.reshape(-1), np.repeat(n, 3, axis=0))


def constraint_energies(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> tuple[float, float, float]:
    """(area constraint, volume constraint, back-pressure work) energies."""
    a, v = mesh.area(x), mesh.volume(x)
    a0, v0 = mesh.area(), mesh.volume()
    return (p.ka_tot * (a - a0) ** 2 / (2 * a0), p.kv_tot * (v - v0) ** 2 / (2 * v0), -p.p_back * (v - v0))


def constraint_forces(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    a, v = mesh.area(x), mesh.volume(x)
    a0, v0 = mesh.area(), mesh.volume()
    ga = _scatter(mesh.n_vertices, mesh.faces.reshape(-1), area_gradient(x, mesh).reshape(-1, 3))
    gv = volume_gradient(x, mesh)
    return -(p.ka_tot * (a - a0) / a0) * ga - (p.kv_tot * (v - v0) / v0 - p.p_back) * gv


# ----------------------------------------------------------------------------------------------
# self-avoidance
# ----------------------------------------------------------------------------------------------
def _sa_pairs(x: np.ndarray, mesh: ShellMesh, p: ShellParams):
    from scipy.spatial import cKDTree

    rc = p.self_avoid_cutoff * mesh.min_edge_length()
    pairs = cKDTree(x).query_pairs(rc, output_type="ndarray")
    return rc, pairs


def self_avoid_energy(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> float:
    """WCA energy 4 eps [(s/r)^12 - (s/r)^6] + eps for r < r_c, s = r_c / 2^(1/6)."""
    if not p.self_avoid or p.self_avoid_epsilon == 0:
        return 0.0
    x = np.asarray(x, dtype=np.float64)
    rc, pairs = _sa_pairs(x, mesh, p)
    if pairs.size == 0:
        return 0.0
    r = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)
    s6 = (rc / r) ** 6 / 2.0  # (sigma/r)^6 with sigma^6 = rc^6 / 2
    return float(np.sum(4 * p.self_avoid_epsilon * (s6**2 - s6) + p.self_avoid_epsilon))


def self_avoid_forces(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> np.ndarray:
    out = np.zeros((mesh.n_vertices, 3))
    if not p.self_avoid or p.self_avoid_epsilon == 0:
        return out
    x = np.asarray(x, dtype=np.float64)
    rc, pairs = _sa_pairs(x, mesh, p)
    if pairs.size == 0:
        return out
    d = x[pairs[:, 0]] - x[pairs[:, 1]]
    r2 = _dot(d, d)
    s6 = (rc**6 / 2.0) / r2**3
    fmag = 24 * p.self_avoid_epsilon * (2 * s6**2 - s6) / r2  # times d gives the force on i
    fi = fmag[:, None] * d
    out += _scatter(mesh.n_vertices, pairs[:, 0], fi)
    out -= _scatter(mesh.n_vertices, pairs[:, 1], fi)
    return out


# ----------------------------------------------------------------------------------------------
# totals
# ----------------------------------------------------------------------------------------------
def shell_energies(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> np.ndarray:
    """All energy terms in the order of :data:`ENERGY_TERMS`."""
    x = np.asarray(x, dtype=np.float64)
    eb = kantor_energy(x, mesh, p) if p.bending == "kantor" else juelicher_energy(x, mesh, p)
    ea, ev, ep = constraint_energies(x, mesh, p)
    return np.array([lim_energy(x, mesh, p), eb, ea, ev, ep, self_avoid_energy(x, mesh, p)])


def shell_forces(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> np.ndarray:
    """Total conservative shell force -dE/dx [Nv,3]."""
    x = np.asarray(x, dtype=np.float64)
    fb = kantor_forces(x, mesh, p) if p.bending == "kantor" else juelicher_forces(x, mesh, p)
    return (lim_forces(x, mesh, p) + fb + constraint_forces(x, mesh, p) + self_avoid_forces(x, mesh, p))
