"""Kantor and Juelicher bending energies and forces, float64 NumPy (docs/physics.md section 3; DPD units)."""

from __future__ import annotations

import numpy as np

from bubblecal.sim.engine import ShellMesh, ShellParams, dihedral_angles
from bubblecal.sim.validation.shell_reference.common import row_dot, scatter_rows
from bubblecal.sim.validation.shell_reference.constraints import area_gradient

__all__ = ["dihedral_angle_gradients", "kantor_energy", "kantor_forces", "juelicher_energy", "juelicher_forces"]


def dihedral_angle_gradients(x: np.ndarray, mesh: ShellMesh) -> tuple[np.ndarray, np.ndarray]:
    """Dihedral angles and their closed-form gradients.

    Parameters
    ----------
    x : numpy.ndarray
        [N_v, 3] positions (DPD length).
    mesh : ShellMesh
        The shell and its stress-free reference.

    Returns
    -------
    theta : numpy.ndarray
        [N_e] angles (radians).
    gradients : numpy.ndarray
        [N_e, 4, 3] d theta_e / d(a, b, c, d) (1 / DPD length).
    """
    x = np.asarray(x, dtype=np.float64)
    dh = mesh.dihedrals
    a, b, c, d = (x[dh[:, k]] for k in range(4))
    e = b - a
    n1 = np.cross(e, c - a)
    n2 = np.cross(-e, d - b)
    el2 = row_dot(e, e)
    el = np.sqrt(el2)
    theta = np.arctan2(row_dot(np.cross(n1, n2), e) / el, row_dot(n1, n2))
    gc = -(el / row_dot(n1, n1))[:, None] * n1
    gd = -(el / row_dot(n2, n2))[:, None] * n2
    sc = (row_dot(c - a, e) / el2)[:, None]
    sd = (row_dot(d - a, e) / el2)[:, None]
    ga = -(1.0 - sc) * gc - (1.0 - sd) * gd
    gb = -sc * gc - sd * gd
    return theta, np.stack([ga, gb, gc, gd], axis=1)


def kantor_energy(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> float:
    """Stress-free Kantor energy kb sum_e [1 - cos(theta_e - theta0_e)].

    Parameters
    ----------
    x : numpy.ndarray
        [N_v, 3] positions (DPD length).
    mesh : ShellMesh
        The shell and its stress-free reference.
    p : ShellParams
        Membrane parameters (DPD units).

    Returns
    -------
    float
        Energy (k_BT).
    """
    theta = dihedral_angles(x, mesh.dihedrals)
    return float(p.kb * np.sum(1.0 - np.cos(theta - mesh.theta0)))


def kantor_forces(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> np.ndarray:
    """Kantor bending forces on the vertices.

    Parameters
    ----------
    x : numpy.ndarray
        [N_v, 3] positions (DPD length).
    mesh : ShellMesh
        The shell and its stress-free reference.
    p : ShellParams
        Membrane parameters (DPD units).

    Returns
    -------
    numpy.ndarray
        [N_v, 3] (DPD force).
    """
    theta, g = dihedral_angle_gradients(x, mesh)
    coef = -p.kb * np.sin(theta - mesh.theta0)
    return scatter_rows(mesh.n_vertices, mesh.dihedrals.reshape(-1), (coef[:, None, None] * g).reshape(-1, 3))


def _juelicher_parts(x: np.ndarray, mesh: ShellMesh):
    """Juelicher ingredients: angles and gradients, edges and lengths, sum l_e theta_e and A_v per vertex."""
    x = np.asarray(x, dtype=np.float64)
    theta, g = dihedral_angle_gradients(x, mesh)
    e = x[mesh.edges[:, 1]] - x[mesh.edges[:, 0]]
    le = np.linalg.norm(e, axis=1)
    m = np.bincount(mesh.edges[:, 0], weights=le * theta, minlength=mesh.n_vertices)
    m += np.bincount(mesh.edges[:, 1], weights=le * theta, minlength=mesh.n_vertices)
    av = mesh.vertex_areas(x)
    return theta, g, e, le, m, av


def juelicher_energy(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> float:
    """Juelicher energy 2 kb sum_v A_v (H_v - c0/2)^2, H_v = sum_e l_e theta_e / (4 A_v), barycentric A_v.

    Parameters
    ----------
    x : numpy.ndarray
        [N_v, 3] positions (DPD length).
    mesh : ShellMesh
        The shell and its stress-free reference.
    p : ShellParams
        Membrane parameters (DPD units).

    Returns
    -------
    float
        Energy (k_BT).
    """
    *_, m, av = _juelicher_parts(x, mesh)
    h = m / (4.0 * av)
    return float(2.0 * p.kb * np.sum(av * (h - 0.5 * p.c0) ** 2))


def juelicher_forces(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> np.ndarray:
    """Juelicher bending forces on the vertices.

    Parameters
    ----------
    x : numpy.ndarray
        [N_v, 3] positions (DPD length).
    mesh : ShellMesh
        The shell and its stress-free reference.
    p : ShellParams
        Membrane parameters (DPD units).

    Returns
    -------
    numpy.ndarray
        [N_v, 3] (DPD force).
    """
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
    f = scatter_rows(mesh.n_vertices, mesh.dihedrals.reshape(-1), (-ce[:, None, None] * gl).reshape(-1, 3))
    ct = c_a[mesh.faces].sum(axis=1) / 3.0
    ga = area_gradient(x, mesh)
    f += scatter_rows(mesh.n_vertices, mesh.faces.reshape(-1), (-ct[:, None, None] * ga).reshape(-1, 3))
    return f
