"""Global area / volume constraints and back pressure, float64 NumPy (docs/physics.md section 3; DPD units)."""

from __future__ import annotations

import numpy as np

from bubblecal.sim.engine import ShellMesh, ShellParams
from bubblecal.sim.validation.shell_reference.common import scatter_rows

__all__ = ["area_gradient", "volume_gradient", "constraint_energies", "constraint_forces"]


def area_gradient(x: np.ndarray, mesh: ShellMesh) -> np.ndarray:
    """dA_t/dx on the corners of every triangle.

    Parameters
    ----------
    x : numpy.ndarray
        [N_v, 3] positions (DPD length).
    mesh : ShellMesh
        The shell and its stress-free reference.

    Returns
    -------
    numpy.ndarray
        [N_t, 3 corners, 3] (DPD length).
    """
    f = mesh.faces
    x0, x1, x2 = x[f[:, 0]], x[f[:, 1]], x[f[:, 2]]
    n = np.cross(x1 - x0, x2 - x0)
    nhat = n / np.linalg.norm(n, axis=1, keepdims=True)
    return 0.5 * np.stack([np.cross(nhat, x2 - x1), np.cross(nhat, x0 - x2), np.cross(nhat, x1 - x0)], axis=1)


def volume_gradient(x: np.ndarray, mesh: ShellMesh) -> np.ndarray:
    """dV/dx_v = sum over the adjacent triangles of n_t / 6 (n_t the unnormalised outward normal).

    Parameters
    ----------
    x : numpy.ndarray
        [N_v, 3] positions (DPD length).
    mesh : ShellMesh
        The shell and its stress-free reference.

    Returns
    -------
    numpy.ndarray
        [N_v, 3] (DPD length^2).
    """
    f = mesh.faces
    n = np.cross(x[f[:, 1]] - x[f[:, 0]], x[f[:, 2]] - x[f[:, 0]]) / 6.0
    return scatter_rows(mesh.n_vertices, f.reshape(-1), np.repeat(n, 3, axis=0))


def constraint_energies(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> tuple[float, float, float]:
    """Global area-constraint, volume-constraint and back-pressure energies.

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
    tuple of float
        (ka_tot (A - A0)^2 / (2 A0), kv_tot (V - V0)^2 / (2 V0), -p_back (V - V0)), k_BT.
    """
    a, v = mesh.area(x), mesh.volume(x)
    a0, v0 = mesh.area(), mesh.volume()
    return (p.ka_tot * (a - a0) ** 2 / (2 * a0), p.kv_tot * (v - v0) ** 2 / (2 * v0), -p.p_back * (v - v0))


def constraint_forces(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> np.ndarray:
    """Forces of the global constraints and the back pressure on the vertices.

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
    a, v = mesh.area(x), mesh.volume(x)
    a0, v0 = mesh.area(), mesh.volume()
    ga = scatter_rows(mesh.n_vertices, mesh.faces.reshape(-1), area_gradient(x, mesh).reshape(-1, 3))
    gv = volume_gradient(x, mesh)
    return -(p.ka_tot * (a - a0) / a0) * ga - (p.kv_tot * (v - v0) / v0 - p.p_back) * gv
