"""Self-avoidance (vertex WCA) energy and forces, float64 NumPy (docs/physics.md section 3; DPD units)."""

from __future__ import annotations

import numpy as np

from bubblecal.sim.engine import ShellMesh, ShellParams
from bubblecal.sim.validation.shell_reference.common import row_dot, scatter_rows

__all__ = ["self_avoid_energy", "self_avoid_forces"]


def _sa_pairs(x: np.ndarray, mesh: ShellMesh, p: ShellParams):
    """Self-avoidance cut-off and the vertex pairs within it (scipy cKDTree)."""
    from scipy.spatial import cKDTree

    rc = p.self_avoid_cutoff * mesh.min_edge_length()
    pairs = cKDTree(x).query_pairs(rc, output_type="ndarray")
    return rc, pairs


def self_avoid_energy(x: np.ndarray, mesh: ShellMesh, p: ShellParams) -> float:
    """WCA energy 4 eps [(s/r)^12 - (s/r)^6] + eps for r < r_c, s = r_c / 2^(1/6).

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
        Energy (k_BT); 0 when self-avoidance is off.
    """
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
    """Self-avoidance (WCA) forces on the vertices.

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
        [N_v, 3] (DPD force); zeros when self-avoidance is off.
    """
    out = np.zeros((mesh.n_vertices, 3))
    if not p.self_avoid or p.self_avoid_epsilon == 0:
        return out
    x = np.asarray(x, dtype=np.float64)
    rc, pairs = _sa_pairs(x, mesh, p)
    if pairs.size == 0:
        return out
    d = x[pairs[:, 0]] - x[pairs[:, 1]]
    r2 = row_dot(d, d)
    s6 = (rc**6 / 2.0) / r2**3
    fmag = 24 * p.self_avoid_epsilon * (2 * s6**2 - s6) / r2  # times d gives the force on i
    fi = fmag[:, None] * d
    out += scatter_rows(mesh.n_vertices, pairs[:, 0], fi)
    out -= scatter_rows(mesh.n_vertices, pairs[:, 1], fi)
    return out
