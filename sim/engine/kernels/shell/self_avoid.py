"""Self-avoidance of one shell (docs/physics.md section 3): WCA Lennard-Jones between its own vertices.

U = 4 eps [(sigma/r)^12 - (sigma/r)^6] + eps for r < r_c = 2^(1/6) sigma, where r_c is ``self_avoid_cutoff`` x
the shortest reference edge (DPD length) and eps ``self_avoid_epsilon`` (k_BT).  Pairs come from a
``wp.HashGrid`` built on the shell vertices moved into per-replica slots of one search lattice
(:func:`self_avoid_grid_plan`), so that replicas sharing coordinates rarely share a cell; pairs are filtered by
replica and by the true distance, so aliasing costs only time.
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator
from bubblecal.sim.engine.kernels.shell.layout import E_SA, P_SA_EPS, P_SA_RC
from bubblecal.sim.engine.mesh import ShellMesh

wp = require("warp", "sim")

__all__ = ["self_avoid_kernels", "SelfAvoidGridPlan", "self_avoid_grid_plan"]


@dataclass(frozen=True)
class SelfAvoidGridPlan:
    """Where each replica's vertices go in the self-avoidance search lattice.

    Attributes
    ----------
    anchors : numpy.ndarray
        [R, 2] int32 global rows of an antipodal vertex pair per replica; their midpoint is the replica centre.
    slots : numpy.ndarray
        [R, 3] float64 centre of each replica's slot (DPD length).
    query_radius : float
        Hash-grid query radius: the largest cut-off x 1.001 (DPD length).
    cell : float
        Hash-grid cell size, 2 x ``query_radius`` (DPD length).
    dims : list of int
        Hash-grid cells per axis (4 to 128).
    """

    anchors: np.ndarray
    slots: np.ndarray
    query_radius: float
    cell: float
    dims: list


def self_avoid_grid_plan(meshes: Sequence[ShellMesh], offsets: Sequence[int], max_cutoff: float) -> SelfAvoidGridPlan:
    """Give every replica its own slot of one 3-D search lattice.

    Replicas usually share coordinates (each in its own box), so their vertices are moved into disjoint slots
    (centre = midpoint of an antipodal vertex pair, slot width 3 R_max + 2 cells, room for 50 % deformation);
    the hash grid (cell = 2 x the largest cut-off, at most 128 cells per axis) then rarely aliases two
    replicas into one cell.

    Parameters
    ----------
    meshes : sequence of ShellMesh
        The replicas' reference meshes (DPD length).
    offsets : sequence of int
        First global particle row of each replica's vertices.
    max_cutoff : float
        Largest self-avoidance cut-off over the replicas (DPD length; 0 when self-avoidance is off).

    Returns
    -------
    SelfAvoidGridPlan
    """
    R = len(meshes)
    anchors = np.zeros((R, 2), dtype=np.int32)
    ext = 0.0
    for r, (m, o) in enumerate(zip(meshes, offsets, strict=True)):
        v = m.vertices
        b = int(np.argmax(np.linalg.norm(v - v[0], axis=1)))
        anchors[r] = (o, o + b)
        c = 0.5 * (v[0] + v[b])
        ext = max(ext, float(np.max(np.abs(v - c))))
    query_radius = float(max_cutoff) * 1.001
    cell = 2.0 * query_radius
    n_axis = int(math.ceil(R ** (1.0 / 3.0) - 1e-9))
    slot_cells = int(math.ceil((3.0 * ext) / cell)) + 2
    width = slot_cells * cell
    ijk = np.stack(np.unravel_index(np.arange(R), (n_axis, n_axis, n_axis)), axis=1)
    used = [int(ijk[:, k].max()) + 1 for k in range(3)]
    dims = [int(min(128, max(4, u * slot_cells))) for u in used]
    return SelfAvoidGridPlan(anchors=anchors, slots=(ijk + 0.5) * width, query_radius=query_radius, cell=cell,
                             dims=dims)


@functools.cache
def self_avoid_kernels(dtype) -> dict:
    """Build (once per scalar type) the self-avoidance kernels; ``dtype`` is ``wp.float32`` or ``wp.float64``.
    Returns a dict: ``"grid_positions_kernel"`` (shell vertices moved into their replica's slot, float32 for the
    hash grid) and ``"self_avoid_kernel"`` (one thread per shell vertex: WCA forces and energy from the grid
    query).
    """
    T = dtype
    V = wp.vec3d if T is wp.float64 else wp.vec3f
    kern = kernel_decorator(dtype, "shell")

    @kern
    def grid_positions_kernel(x: wp.array(dtype=V), gidx: wp.array(dtype=wp.int32), vrep: wp.array(dtype=wp.int32),
                              anchor: wp.array(dtype=wp.vec2i), slot: wp.array(dtype=wp.vec3),
                              xs: wp.array(dtype=wp.vec3)):
        # shell vertices relative to their replica's centre (midpoint of an antipodal vertex pair,
        # exact under rigid motions), moved to the replica's own slot of the search grid
        s = wp.tid()
        r = vrep[s]
        ab = anchor[r]
        c = T(0.5) * (x[ab[0]] + x[ab[1]])
        xs[s] = wp.vec3(x[gidx[s]] - c) + slot[r]


    @kern
    def self_avoid_kernel(grid: wp.uint64, xs: wp.array(dtype=wp.vec3), x: wp.array(dtype=V),
                          f: wp.array(dtype=V), gidx: wp.array(dtype=wp.int32), vrep: wp.array(dtype=wp.int32),
                          params: wp.array2d(dtype=T), query_radius: float, energy: wp.array2d(dtype=T),
                          want_energy: wp.int32, skip: wp.array(dtype=wp.int32)):
        s = wp.tid()
        r = vrep[s]
        eps = params[r, P_SA_EPS]
        if eps == T(0.0) or skip[r] != 0:
            return
        rc = params[r, P_SA_RC]
        rc2 = rc * rc
        sig6 = rc2 * rc2 * rc2 / T(2.0)
        gi = gidx[s]
        xi = x[gi]
        fi = V()
        en = T(0.0)
        neighbors = wp.hash_grid_query(grid, xs[s], query_radius)
        for j in neighbors:
            if j != s and vrep[j] == r:
                d = xi - x[gidx[j]]
                r2 = wp.dot(d, d)
                if r2 < rc2:
                    s6 = sig6 / (r2 * r2 * r2)
                    fi = fi + (T(24.0) * eps * (T(2.0) * s6 * s6 - s6) / r2) * d
                    en = en + T(0.5) * (T(4.0) * eps * (s6 * s6 - s6) + eps)
        f[gi] = f[gi] + fi
        if want_energy != 0:
            wp.atomic_add(energy, r, E_SA, en)

    return {"grid_positions_kernel": grid_positions_kernel, "self_avoid_kernel": self_avoid_kernel}
