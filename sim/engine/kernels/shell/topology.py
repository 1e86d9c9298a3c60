"""Host-side (NumPy) packing of R replicas' shell meshes and parameters into the device tables.

Replica r's N_v,r vertices live at global particle rows ``[offset_r, offset_r + N_v,r)``; its triangles and
dihedrals are stored with global row indices.  The gather kernel also needs, per shell vertex, the list of its
incident elements (CSR), indexed by the vertex's compact position among all shell vertices.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bubblecal.sim.engine.kernels.shell.layout import (
    N_PARAMS,
    P_A0TOT,
    P_A3,
    P_A4,
    P_B1,
    P_B2,
    P_C0,
    P_ETA,
    P_KA,
    P_KATOT,
    P_KB_JUL,
    P_KB_KANTOR,
    P_KVTOT,
    P_MU,
    P_PB,
    P_SA_EPS,
    P_SA_RC,
    P_V0,
)
from bubblecal.sim.engine.kernels.shell.params import ShellParams
from bubblecal.sim.engine.mesh import ShellMesh

__all__ = ["resolve_replicas", "param_row", "pack_topology", "vertex_csr"]


def _as_list(obj, n: int | None, what: str) -> list:
    """``obj`` as a list (a single object repeated ``n`` times)."""
    if isinstance(obj, (list, tuple)):
        return list(obj)
    if n is None:
        raise ValueError(f"{what}: give a list")
    return [obj] * n


def resolve_replicas(meshes_or_mesh: ShellMesh | Sequence[ShellMesh],
                     params_per_replica: ShellParams | Sequence[ShellParams], offsets: Sequence[int] | None):
    """Check and expand the replica description of a :class:`ShellForceField`.

    Parameters
    ----------
    meshes_or_mesh : ShellMesh or sequence of ShellMesh
        One mesh for every replica or one per replica.
    params_per_replica : ShellParams or sequence of ShellParams
        One parameter set for every replica or one per replica.
    offsets : sequence of int or None
        First global particle row of each replica's vertices (None: packed from row 0).

    Returns
    -------
    meshes : list of ShellMesh
    params : list of ShellParams
    offsets : numpy.ndarray
        [R] int64.
    n_vertices : numpy.ndarray
        [R] int64 vertices per replica.

    Raises
    ------
    ValueError
        On no replicas, mismatched counts, or negative or overlapping vertex ranges.
    TypeError
        When the parameters are not :class:`ShellParams`.
    """
    n_rep = len(params_per_replica) if isinstance(params_per_replica, (list, tuple)) else (
        len(meshes_or_mesh) if isinstance(meshes_or_mesh, (list, tuple)) else 1)
    meshes: list[ShellMesh] = _as_list(meshes_or_mesh, n_rep, "meshes")
    params: list[ShellParams] = _as_list(params_per_replica, n_rep, "params_per_replica")
    if len(meshes) != len(params):
        raise ValueError(f"{len(meshes)} meshes but {len(params)} parameter sets")
    for p in params:
        if not isinstance(p, ShellParams):
            raise TypeError(f"params_per_replica must hold ShellParams, got {type(p).__name__}")
    R = len(meshes)
    if R == 0:
        raise ValueError("no replicas")
    nv = np.array([m.n_vertices for m in meshes], dtype=np.int64)
    if offsets is None:
        offsets = np.concatenate([[0], np.cumsum(nv)[:-1]])
    offsets = np.asarray(offsets, dtype=np.int64)
    if offsets.shape != (R,) or np.any(offsets < 0):
        raise ValueError("offsets must hold one non-negative row per replica")
    order = np.argsort(offsets)
    if np.any(offsets[order][1:] < (offsets + nv)[order][:-1]):
        raise ValueError("replica vertex ranges overlap")
    return meshes, params, offsets, nv


def param_row(p: ShellParams, mesh: ShellMesh, area0: float, volume0: float) -> np.ndarray:
    """One row of the device parameter table (DPD units).

    Parameters
    ----------
    p : ShellParams
        The replica's shell parameters.
    mesh : ShellMesh
        The replica's reference mesh (its shortest edge scales the self-avoidance cut-off).
    area0, volume0 : float
        Reference area (DPD length^2) and enclosed volume (DPD length^3) of the global constraints.

    Returns
    -------
    numpy.ndarray
        [N_PARAMS] float64; the bending constant goes to the Kantor or the Juelicher column, terms that are
        off hold 0.
    """
    row = np.zeros(N_PARAMS)
    row[[P_KA, P_MU, P_A3, P_A4, P_B1, P_B2]] = [p.ka, p.mu, p.a3, p.a4, p.b1, p.b2]
    row[P_KB_KANTOR] = p.kb if p.bending == "kantor" else 0.0
    row[P_KB_JUL] = p.kb if p.bending == "juelicher" else 0.0
    row[P_C0] = p.c0
    row[[P_KATOT, P_KVTOT, P_PB]] = [p.ka_tot, p.kv_tot, p.p_back]
    row[P_A0TOT] = area0
    row[P_V0] = volume0
    row[P_SA_EPS] = p.self_avoid_epsilon if p.self_avoid else 0.0
    row[P_SA_RC] = p.self_avoid_cutoff * mesh.min_edge_length()
    row[P_ETA] = p.bond_viscosity
    return row


def pack_topology(meshes: Sequence[ShellMesh], offsets: np.ndarray) -> dict[str, np.ndarray]:
    """Triangles, dihedrals and reference data of every replica, packed over replicas (global rows).

    Parameters
    ----------
    meshes : sequence of ShellMesh
        One reference mesh per replica.
    offsets : numpy.ndarray
        [R] int64 first global particle row of each replica's vertices.

    Returns
    -------
    dict of numpy.ndarray
        ``tri`` [N_t, 3] and ``dih`` [N_e, 4] global rows; ``tri_rep``, ``edge_rep``, ``vrep`` replica of each
        triangle, edge, shell vertex; ``gidx`` global row of each shell vertex; ``coff`` [R] first compact
        shell-vertex index of each replica; ``ref`` [N_t, 4] Lim reference (l1^2, l2^2, d0, A0; DPD length^2);
        ``theta0`` [N_e] reference dihedral angles (radians).
    """
    nv = np.array([m.n_vertices for m in meshes], dtype=np.int64)
    return {
        "coff": np.concatenate([[0], np.cumsum(nv)[:-1]]),
        "tri": np.concatenate([m.faces.astype(np.int64) + o for m, o in zip(meshes, offsets, strict=True)]),
        "dih": np.concatenate([m.dihedrals.astype(np.int64) + o for m, o in zip(meshes, offsets, strict=True)]),
        "tri_rep": np.concatenate([np.full(m.n_faces, r) for r, m in enumerate(meshes)]),
        "edge_rep": np.concatenate([np.full(m.n_edges, r) for r, m in enumerate(meshes)]),
        "vrep": np.concatenate([np.full(m.n_vertices, r) for r, m in enumerate(meshes)]),
        "gidx": np.concatenate([np.arange(n) + o for n, o in zip(nv, offsets, strict=True)]),
        "ref": np.concatenate([np.stack([m.l1**2, m.l2**2, m.d0, m.A0], axis=1) for m in meshes]),
        "theta0": np.concatenate([m.theta0 for m in meshes]),
    }


def vertex_csr(elements: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertex -> incident elements (CSR) of the gather kernel.

    Parameters
    ----------
    elements : numpy.ndarray
        [N_el, k] compact shell-vertex indices of each element (k = 3 for triangles, 4 for dihedrals).
    n_vertices : int
        Number of shell vertices.

    Returns
    -------
    start, code : numpy.ndarray
        int32 row starts [n_vertices + 1] and codes ``element * 4 + corner`` (corner = the vertex's position
        in the element), sorted by vertex and, within a vertex, by element.

    Raises
    ------
    ValueError
        When a code does not fit in 32 bits.
    """
    n_el, k = elements.shape
    vert = elements.reshape(-1)
    code = (np.repeat(np.arange(n_el, dtype=np.int64), k) * 4 + np.tile(np.arange(k), n_el))
    order = np.argsort(vert, kind="stable")
    start = np.zeros(n_vertices + 1, dtype=np.int64)
    np.cumsum(np.bincount(vert, minlength=n_vertices), out=start[1:])
    if code.max(initial=0) >= 2**31:
        raise ValueError("too many shell elements for 32-bit element codes")
    return start.astype(np.int32), code[order].astype(np.int32)
