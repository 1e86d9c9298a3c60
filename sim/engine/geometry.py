"""Vectorised float64 geometry of triangulated shells: areas, volumes, dihedral angles, Lim reference, topology.

Conventions (orientation, dihedral quadruples, the sign of theta): :mod:`bubblecal.sim.engine.mesh`.
Lengths in DPD units (r_c = 250 nm).
"""

from __future__ import annotations

import numpy as np

__all__ = ["triangle_areas", "mesh_volume", "dihedral_angles", "lim_reference", "edges_and_dihedrals"]


def triangle_areas(x: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area of every triangle.

    Parameters
    ----------
    x : numpy.ndarray
        [N_v, 3] vertex positions (DPD length).
    faces : numpy.ndarray
        [N_t, 3] triangles.

    Returns
    -------
    numpy.ndarray
        [N_t] float64 areas (DPD length^2).
    """
    x = np.asarray(x, dtype=np.float64)
    n = np.cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]])
    return 0.5 * np.linalg.norm(n, axis=1)


def mesh_volume(x: np.ndarray, faces: np.ndarray) -> float:
    """Enclosed volume of a closed, outward-oriented triangulation (divergence theorem).

    Computed relative to the vertex centroid, which keeps float rounding small far from the origin.

    Parameters
    ----------
    x : numpy.ndarray
        [N_v, 3] vertex positions (DPD length).
    faces : numpy.ndarray
        [N_t, 3] outward-oriented triangles.

    Returns
    -------
    float
        Volume (DPD length^3).
    """
    x = np.asarray(x, dtype=np.float64)
    x = x - x.mean(axis=0)
    x0, x1, x2 = x[faces[:, 0]], x[faces[:, 1]], x[faces[:, 2]]
    return float(np.sum(np.einsum("ij,ij->i", x0, np.cross(x1, x2))) / 6.0)


def dihedral_angles(x: np.ndarray, dihedrals: np.ndarray) -> np.ndarray:
    """Signed dihedral angle of every edge (convention in the module docstring).

    Parameters
    ----------
    x : numpy.ndarray
        [N_v, 3] vertex positions (DPD length).
    dihedrals : numpy.ndarray
        [N_e, 4] quadruples (a, b, c, d).

    Returns
    -------
    numpy.ndarray
        [N_e] angles in (-pi, pi] (radians).
    """
    x = np.asarray(x, dtype=np.float64)
    a, b, c, d = (x[dihedrals[:, k]] for k in range(4))
    e = b - a
    n1 = np.cross(e, c - a)
    n2 = np.cross(-e, d - b)
    el = np.linalg.norm(e, axis=1)
    cos_t = np.einsum("ij,ij->i", n1, n2)
    sin_t = np.einsum("ij,ij->i", np.cross(n1, n2), e) / el
    return np.arctan2(sin_t, cos_t)


def lim_reference(x: np.ndarray, faces: np.ndarray) -> dict[str, np.ndarray]:
    """Lim reference quantities of every triangle.

    Parameters
    ----------
    x : numpy.ndarray
        [N_v, 3] reference positions (DPD length).
    faces : numpy.ndarray
        [N_t, 3] triangles.

    Returns
    -------
    dict of numpy.ndarray
        ``l1``, ``l2`` (lengths of e1 = X1 - X0 and e2 = X2 - X0, DPD length), ``d0`` = e1 . e2 and ``A0``
        (DPD length^2), each [N_t].
    """
    x = np.asarray(x, dtype=np.float64)
    e1 = x[faces[:, 1]] - x[faces[:, 0]]
    e2 = x[faces[:, 2]] - x[faces[:, 0]]
    return {
        "l1": np.linalg.norm(e1, axis=1),
        "l2": np.linalg.norm(e2, axis=1),
        "d0": np.einsum("ij,ij->i", e1, e2),
        "A0": 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1),
    }


def edges_and_dihedrals(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Unique edges and their dihedral quadruples of a closed, consistently oriented triangulation.

    Parameters
    ----------
    faces : numpy.ndarray
        [N_t, 3] outward-oriented triangles.
    n_vertices : int
        Number of vertices N_v.

    Returns
    -------
    edges : numpy.ndarray
        [N_e, 2] int32 (a < b), sorted.
    dihedrals : numpy.ndarray
        [N_e, 4] int32 quadruples (a, b, c, d) of the same edges (convention of :mod:`bubblecal.sim.engine.mesh`).

    Raises
    ------
    ValueError
        When the mesh is not consistently oriented, not manifold or not closed.
    """
    f = np.asarray(faces, dtype=np.int64)
    # directed half-edges (i -> j) with the opposite vertex k, in each face's cyclic order
    src = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
    dst = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    opp = np.concatenate([f[:, 2], f[:, 0], f[:, 1]])
    key = src * n_vertices + dst
    if np.unique(key).size != key.size:
        raise ValueError("mesh is not consistently oriented or not manifold (a directed edge repeats)")
    lookup = dict(zip(key.tolist(), opp.tolist(), strict=True))
    forward = src < dst
    a, b, c = src[forward], dst[forward], opp[forward]
    try:
        d = np.array([lookup[int(bb) * n_vertices + int(aa)] for aa, bb in zip(a, b, strict=True)],
                     dtype=np.int64)
    except KeyError as exc:  # an edge with one face only
        raise ValueError("mesh is not closed (an edge has a single adjacent face)") from exc
    order = np.lexsort((b, a))
    edges = np.stack([a, b], axis=1)[order]
    dih = np.stack([a, b, c, d], axis=1)[order]
    if 2 * edges.shape[0] != 3 * f.shape[0]:
        raise ValueError("mesh is not closed: 2 N_e != 3 N_t")
    return edges.astype(np.int32), dih.astype(np.int32)
