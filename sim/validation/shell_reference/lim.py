"""Lim in-plane energy and forces, float64 NumPy (docs/physics.md section 3; DPD units)."""

from __future__ import annotations

import numpy as np

from bubblecal.sim.engine import AREA_CLAMP, ShellMesh, ShellParams
from bubblecal.sim.validation.shell_reference.common import row_dot, scatter_rows

__all__ = ["lim_energy", "lim_triangle_forces", "lim_forces"]


def _lim_parts(x: np.ndarray, mesh: ShellMesh, p: ShellParams):
    """Lim geometry per triangle: edges, normal, clamped area, alpha and beta."""
    f = mesh.faces
    x12 = x[f[:, 1]] - x[f[:, 0]]
    x13 = x[f[:, 2]] - x[f[:, 0]]
    n = np.cross(x12, x13)
    nn = np.linalg.norm(n, axis=1)
    area = np.maximum(0.5 * nn, AREA_CLAMP)
    a0 = mesh.A0
    alpha = area / a0 - 1.0
    num = mesh.l1**2 * row_dot(x13, x13) + mesh.l2**2 * row_dot(x12, x12) - 2.0 * mesh.d0 * row_dot(x12, x13)
    beta = num / (8.0 * a0 * area) - 1.0
    return x12, x13, n, nn, area, alpha, beta


def lim_energy(x: np.ndarray, mesh: ShellMesh, p: ShellParams, per_triangle: bool = False):
    """Lim in-plane energy, total or per triangle.

    Parameters
    ----------
    x : numpy.ndarray
        [N_v, 3] positions (DPD length).
    mesh : ShellMesh
        The shell and its stress-free reference.
    p : ShellParams
        Membrane parameters (DPD units).
    per_triangle : bool, optional
        Return the [N_t] energies instead of their sum.

    Returns
    -------
    float or numpy.ndarray
        Energy (k_BT).
    """
    x = np.asarray(x, dtype=np.float64)
    *_, alpha, beta = _lim_parts(x, mesh, p)
    w = mesh.A0 * (0.5 * p.ka * (alpha**2 + p.a3 * alpha**3 + p.a4 * alpha**4)
                   + p.mu * (beta + p.b1 * alpha * beta + p.b2 * beta**2))
    return w if per_triangle else float(np.sum(w))


def lim_triangle_forces(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> np.ndarray:
    """Closed-form Lim forces -dW_t/dx on the corners of every triangle.

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
        [N_t, 3 corners, 3] (DPD force).
    """
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
    """Lim forces on the vertices.

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
    ft = lim_triangle_forces(x, mesh, p)
    return scatter_rows(mesh.n_vertices, mesh.faces.reshape(-1), ft.reshape(-1, 3))
