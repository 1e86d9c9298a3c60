"""Helpers of the NumPy shell reference: finite-difference forces and row scatter / dot products."""

from __future__ import annotations

import numpy as np

__all__ = ["finite_difference_forces", "scatter_rows", "row_dot"]


def finite_difference_forces(energy, x: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Forces -dE/dx by central differences (a test helper).

    Parameters
    ----------
    energy : callable
        ``energy(x) -> float`` (k_BT).
    x : numpy.ndarray
        [N_v, 3] positions (DPD length).
    h : float, optional
        Difference step (DPD length).

    Returns
    -------
    numpy.ndarray
        [N_v, 3] forces (DPD force).
    """
    g = np.zeros_like(x)
    for i in range(x.shape[0]):
        for k in range(3):
            xp, xm = x.copy(), x.copy()
            xp[i, k] += h
            xm[i, k] -= h
            g[i, k] = (energy(xp) - energy(xm)) / (2 * h)
    return -g


def scatter_rows(n_vertices: int, idx: np.ndarray, vals: np.ndarray) -> np.ndarray:
    """Sum the rows of ``vals`` into the vertices ``idx``.

    Parameters
    ----------
    n_vertices : int
        Number of vertices.
    idx : numpy.ndarray
        [M] vertex of each row.
    vals : numpy.ndarray
        [M, 3] rows.

    Returns
    -------
    numpy.ndarray
        [n_vertices, 3].
    """
    out = np.zeros((n_vertices, 3))
    for k in range(3):
        out[:, k] = np.bincount(idx, weights=vals[:, k], minlength=n_vertices)
    return out


def row_dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product.

    Parameters
    ----------
    a, b : numpy.ndarray
        [M, 3] arrays.

    Returns
    -------
    numpy.ndarray
        [M].
    """
    return np.einsum("ij,ij->i", a, b)
