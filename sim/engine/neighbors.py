"""Cell lists, sorting for locality and Verlet neighbour lists over many periodic replicas.

Every replica has its own periodic box ``[0, L)`` cut into ``n = floor(L / (r_c + skin))`` cells per
axis (at least 3); the replicas' cells are numbered consecutively (``cell_offset[rep]``), so one
radix sort orders the whole solvent by (replica, cell) -- replicas stay contiguous, particles of a
cell are contiguous, and nothing ever looks into another replica's cells: replicas never interact.

A rebuild (:meth:`NeighbourLists.rebuild`, run by :class:`bubblecal.sim.engine.system.ParticleSystem` when any
particle or vertex may have moved more than ``skin / 2`` since the last one) does:

1. wrap solvent positions into their box, compute cell ids, radix-sort (key = global cell) and
   permute every per-particle array into cell order (locality for the force kernels);
2. cell start/end tables;
3. the solvent -> solvent Verlet list within ``r_c + skin`` (full: both directions), stored
   column-major ``nbr[k, i]`` for coalesced reads;
4. the vertex -> solvent list within ``r_c + skin``;
5. the particle -> triangle candidate lists (CSR) for bounce-back: a particle is a candidate of a
   triangle when it lies within ``circumradius + skin`` of the triangle's centroid (both moved by at
   most ``skin / 2`` since, so every crossing in between is found).

Lists that overflow their capacity are detected at build time (one host read per rebuild) and the
capacity is grown and the list rebuilt.
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import functools
import math
import time

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.common import kernel_decorator, min_image

wp = require("warp", "sim")

__all__ = ["neighbor_kernels", "grid_for_boxes", "NeighbourLists"]


@functools.cache
def neighbor_kernels(dtype):
    """Build (once per scalar type) the cell-list, sorting and neighbour-list kernels (module docstring); ``dtype``
    is ``wp.float32`` or ``wp.float64``. Returns a dict: Name -> ``wp.Kernel``.
    """
    vec3 = wp.types.vector(3, dtype)
    kern = kernel_decorator(dtype, "nbr")

    @wp.func
    def cell_coord(p: dtype, L: dtype, n: wp.int32) -> wp.int32:
        q = p - L * wp.floor(p / L)
        c = wp.int32(q / L * dtype(n))
        return wp.clamp(c, 0, n - 1)

    @wp.func
    def wrap_int(c: wp.int32, n: wp.int32) -> wp.int32:
        return ((c % n) + n) % n

    @wp.func
    def cell_of(p: vec3, L: vec3, n: wp.vec3i) -> wp.vec3i:
        """Cell coordinates of position p in a periodic box L split into n cells per axis."""
        return wp.vec3i(cell_coord(p[0], L[0], n[0]), cell_coord(p[1], L[1], n[1]), cell_coord(p[2], L[2], n[2]))

    @wp.func
    def stencil_cell(home: wp.vec3i, n: wp.vec3i, off: wp.int32, q: wp.int32) -> wp.int32:
        """Global index of the q-th (0..26) periodic neighbour cell of ``home`` in a replica starting at off."""
        ix = wrap_int(home[0] + q // 9 - 1, n[0])
        iy = wrap_int(home[1] + (q // 3) % 3 - 1, n[1])
        iz = wrap_int(home[2] + q % 3 - 1, n[2])
        return off + (ix * n[1] + iy) * n[2] + iz


    @wp.func
    def finite3(p: vec3) -> wp.bool:
        return wp.isfinite(p[0]) and wp.isfinite(p[1]) and wp.isfinite(p[2])

    @kern
    def compute_cells(x: wp.array(dtype=vec3), rep: wp.array(dtype=wp.int32), box: wp.array(dtype=vec3),
                      ncell: wp.array(dtype=wp.vec3i), cell_offset: wp.array(dtype=wp.int32),
                      keys: wp.array(dtype=wp.int32), vals: wp.array(dtype=wp.int32)):
        i = wp.tid()
        r = rep[i]
        L = box[r]
        n = ncell[r]
        p = x[i]
        c = cell_offset[r]
        if finite3(p):
            # wrap the stored position into [0, L)
            q = vec3(p[0] - L[0] * wp.floor(p[0] / L[0]), p[1] - L[1] * wp.floor(p[1] / L[1]),
                     p[2] - L[2] * wp.floor(p[2] / L[2]))
            x[i] = q
            cx = cell_coord(q[0], L[0], n[0])
            cy = cell_coord(q[1], L[1], n[1])
            cz = cell_coord(q[2], L[2], n[2])
            c = c + (cx * n[1] + cy) * n[2] + cz
        keys[i] = c
        vals[i] = i

    @kern
    def cell_ranges(keys: wp.array(dtype=wp.int32), n: wp.int32, start: wp.array(dtype=wp.int32),
                    end: wp.array(dtype=wp.int32)):
        k = wp.tid()
        c = keys[k]
        if k == 0:
            start[c] = k
        elif keys[k - 1] != c:
            start[c] = k
        if k == n - 1:
            end[c] = k + 1
        elif keys[k + 1] != c:
            end[c] = k + 1

    @kern
    def build_solvent_list(x: wp.array(dtype=vec3), rep: wp.array(dtype=wp.int32), box: wp.array(dtype=vec3),
                           ncell: wp.array(dtype=wp.vec3i), cell_offset: wp.array(dtype=wp.int32),
                           start: wp.array(dtype=wp.int32), end: wp.array(dtype=wp.int32), rlist2: dtype,
                           nbr: wp.array2d(dtype=wp.int32), ncount: wp.array(dtype=wp.int32),
                           xref: wp.array(dtype=vec3), maxcount: wp.array(dtype=wp.int32)):
        i = wp.tid()
        r = rep[i]
        L = box[r]
        n = ncell[r]
        p = x[i]
        xref[i] = p
        cap = nbr.shape[0]
        cnt = wp.int32(0)
        if finite3(p):
            home = cell_of(p, L, n)
            off = cell_offset[r]
            for q in range(27):  # 27 > max_unroll: a real loop (small code, fast compile)
                c = stencil_cell(home, n, off, q)
                for j in range(start[c], end[c]):
                    if j != i:
                        d = min_image(p - x[j], L)
                        if wp.dot(d, d) < rlist2:
                            if cnt < cap:
                                nbr[cnt, i] = j
                            cnt += 1
        ncount[i] = cnt
        wp.atomic_max(maxcount, 0, cnt)

    @kern
    def build_vertex_list(xv: wp.array(dtype=vec3), vrep: wp.array(dtype=wp.int32), x: wp.array(dtype=vec3),
                          box: wp.array(dtype=vec3), ncell: wp.array(dtype=wp.vec3i),
                          cell_offset: wp.array(dtype=wp.int32), start: wp.array(dtype=wp.int32),
                          end: wp.array(dtype=wp.int32), rlist2: dtype, vnbr: wp.array2d(dtype=wp.int32),
                          vcount: wp.array(dtype=wp.int32), xvref: wp.array(dtype=vec3),
                          maxcount: wp.array(dtype=wp.int32)):
        i = wp.tid()
        r = vrep[i]
        L = box[r]
        n = ncell[r]
        p = xv[i]
        xvref[i] = p
        cap = vnbr.shape[0]
        cnt = wp.int32(0)
        if finite3(p):
            home = cell_of(p, L, n)
            off = cell_offset[r]
            for q in range(27):
                c = stencil_cell(home, n, off, q)
                for j in range(start[c], end[c]):
                    d = min_image(p - x[j], L)
                    if wp.dot(d, d) < rlist2:
                        if cnt < cap:
                            vnbr[cnt, i] = j
                        cnt += 1
        vcount[i] = cnt
        wp.atomic_max(maxcount, 1, cnt)

    @kern
    def triangle_candidates(xv: wp.array(dtype=vec3), faces: wp.array(dtype=wp.vec3i),
                            frep: wp.array(dtype=wp.int32), x: wp.array(dtype=vec3), box: wp.array(dtype=vec3),
                            ncell: wp.array(dtype=wp.vec3i), cell_offset: wp.array(dtype=wp.int32),
                            start: wp.array(dtype=wp.int32), end: wp.array(dtype=wp.int32), margin: dtype,
                            fill: wp.int32, count: wp.array(dtype=wp.int32), row: wp.array(dtype=wp.int32),
                            cols: wp.array(dtype=wp.int32)):
        """Pass ``fill == 0``: count candidates per particle; ``fill == 1``: write the CSR columns."""
        t = wp.tid()
        r = frep[t]
        L = box[r]
        n = ncell[r]
        f = faces[t]
        a = xv[f[0]]
        b = a + min_image(xv[f[1]] - a, L)
        c3 = a + min_image(xv[f[2]] - a, L)
        ctr = (a + b + c3) / dtype(3.0)
        if not finite3(ctr):
            return
        rad = wp.max(wp.length(a - ctr), wp.max(wp.length(b - ctr), wp.length(c3 - ctr))) + margin
        rad2 = rad * rad
        q = vec3(ctr[0] - L[0] * wp.floor(ctr[0] / L[0]), ctr[1] - L[1] * wp.floor(ctr[1] / L[1]),
                 ctr[2] - L[2] * wp.floor(ctr[2] / L[2]))
        off = cell_offset[r]
        lo0 = wp.int32(wp.floor((q[0] - rad) / L[0] * dtype(n[0])))
        hi0 = wp.int32(wp.floor((q[0] + rad) / L[0] * dtype(n[0])))
        lo1 = wp.int32(wp.floor((q[1] - rad) / L[1] * dtype(n[1])))
        hi1 = wp.int32(wp.floor((q[1] + rad) / L[1] * dtype(n[1])))
        lo2 = wp.int32(wp.floor((q[2] - rad) / L[2] * dtype(n[2])))
        hi2 = wp.int32(wp.floor((q[2] + rad) / L[2] * dtype(n[2])))
        hi0 = wp.min(hi0, lo0 + n[0] - 1)
        hi1 = wp.min(hi1, lo1 + n[1] - 1)
        hi2 = wp.min(hi2, lo2 + n[2] - 1)
        for cx in range(lo0, hi0 + 1):
            ix = wrap_int(cx, n[0])
            for cy in range(lo1, hi1 + 1):
                iy = wrap_int(cy, n[1])
                for cz in range(lo2, hi2 + 1):
                    iz = wrap_int(cz, n[2])
                    c = off + (ix * n[1] + iy) * n[2] + iz
                    for j in range(start[c], end[c]):
                        d = min_image(x[j] - ctr, L)
                        if wp.dot(d, d) < rad2:
                            slot = wp.atomic_add(count, j, 1)
                            if fill == 1:
                                cols[row[j] + slot] = t

    @kern
    def csr_close(count: wp.array(dtype=wp.int32), row: wp.array(dtype=wp.int32), n: wp.int32,
                  total: wp.array(dtype=wp.int32)):
        row[n] = row[n - 1] + count[n - 1]
        total[0] = row[n]

    @kern
    def permute_vec(src: wp.array(dtype=vec3), perm: wp.array(dtype=wp.int32), dst: wp.array(dtype=vec3)):
        i = wp.tid()
        dst[i] = src[perm[i]]

    @kern
    def permute_int(src: wp.array(dtype=wp.int32), perm: wp.array(dtype=wp.int32), dst: wp.array(dtype=wp.int32)):
        i = wp.tid()
        dst[i] = src[perm[i]]

    return {"compute_cells": compute_cells, "cell_ranges": cell_ranges, "build_solvent_list": build_solvent_list,
            "build_vertex_list": build_vertex_list, "triangle_candidates": triangle_candidates,
            "permute_vec": permute_vec, "permute_int": permute_int, "csr_close": csr_close}


def grid_for_boxes(boxes: np.ndarray, rlist: float) -> tuple[np.ndarray, np.ndarray, int]:
    """Cells per axis of each replica's box and the replicas' first global cell index.

    Parameters
    ----------
    boxes : numpy.ndarray
        [R, 3] box edge lengths (DPD length).
    rlist : float
        Neighbour-list radius r_c + skin (DPD length); a cell is at least this wide.

    Returns
    -------
    n_cells : numpy.ndarray
        [R, 3] int32 cells per axis (>= 3).
    offsets : numpy.ndarray
        [R] int32 first global cell of each replica.
    total : int
        Number of cells over all replicas.

    Raises
    ------
    ValueError
        When a box edge is shorter than 3 rlist.
    """
    boxes = np.asarray(boxes, dtype=float).reshape(-1, 3)
    n = np.floor(boxes / rlist).astype(np.int32)
    if np.any(n < 3):
        raise ValueError(f"every box edge must be >= 3 (r_c + skin) = {3 * rlist:.3f}; got boxes {boxes.tolist()}")
    counts = n.prod(axis=1)
    offsets = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int32)
    return n, offsets, int(counts.sum())


class NeighbourLists:
    """Neighbour-list upkeep of :class:`~bubblecal.sim.engine.system.ParticleSystem` (a mixin of it).

    Works on the system's solvent, vertex and list arrays: :meth:`rebuild` runs the steps of the module
    docstring, :meth:`_schedule_rebuild` decides after each chunk whether the lists survive the next one.
    """

    def rebuild(self) -> None:
        """Sort the solvent by cell and rebuild every neighbour / candidate list (synchronises).

        Lists that overflow are grown and rebuilt; a grown list invalidates the captured CUDA graph.
        """
        t0 = time.perf_counter()
        kn, dev, N = self.kn, self.device, self.N
        wp.launch(kn["compute_cells"], dim=N, inputs=[self.x, self.rep, self.box, self.ncell, self.cell_offset,
                                                      self._keys, self._vals], device=dev)
        wp.utils.radix_sort_pairs(self._keys, self._vals, N)
        perm = self._vals
        # permute into scratch, copy back: array identities stay fixed (a captured graph stays valid)
        for src in (self.x, self.v):
            wp.launch(kn["permute_vec"], dim=N, inputs=[src, perm, self._x2], device=dev)
            wp.copy(src, self._x2)
        for src in (self.typ, self.rep, self.pid):
            wp.launch(kn["permute_int"], dim=N, inputs=[src, perm, self._i2], device=dev)
            wp.copy(src, self._i2)
        self.cell_start.zero_()
        self.cell_end.zero_()
        wp.launch(kn["cell_ranges"], dim=N, inputs=[self._keys, N, self.cell_start, self.cell_end], device=dev)
        rl2 = self.rlist**2
        while True:
            self._maxcount.zero_()
            wp.launch(kn["build_solvent_list"], dim=N,
                      inputs=[self.x, self.rep, self.box, self.ncell, self.cell_offset, self.cell_start,
                              self.cell_end, rl2, self.nbr, self.ncount, self.xref, self._maxcount], device=dev)
            if self.Nv:
                wp.launch(kn["build_vertex_list"], dim=self.Nv,
                          inputs=[self.xv, self.vrep, self.x, self.box, self.ncell, self.cell_offset,
                                  self.cell_start, self.cell_end, rl2, self.vnbr, self.vcount, self.xvref,
                                  self._maxcount], device=dev)
            mx, mxv = (int(c) for c in self._maxcount.numpy()[:2])
            grown = False
            if mx > self.nbr.shape[0]:
                self.nbr = wp.zeros((int(mx * 1.25) + 4, N), dtype=wp.int32, device=dev)
                grown = True
            if self.Nv and mxv > self.vnbr.shape[0]:
                self.vnbr = wp.zeros((int(mxv * 1.25) + 4, self.Nv), dtype=wp.int32, device=dev)
                grown = True
            if not grown:
                break
            self._chunks.invalidate()
        if self.Nv:
            self.tri_count.zero_()
            margin = self.skin + 1e-3
            common = [self.xv, self.faces, self.frep, self.x, self.box, self.ncell, self.cell_offset,
                      self.cell_start, self.cell_end, margin]
            wp.launch(kn["triangle_candidates"], dim=self.Nf,
                      inputs=[*common, 0, self.tri_count, self.tri_row, self.tri_cols], device=dev)
            wp.utils.array_scan(self.tri_count, self.tri_row[0:N], inclusive=False)
            wp.launch(kn["csr_close"], dim=1, inputs=[self.tri_count, self.tri_row, N, self._maxcount[2:3]],
                      device=dev)
            total = int(self._maxcount.numpy()[2])
            if total > self.tri_cols.shape[0]:
                self.tri_cols = wp.zeros(int(total * 1.5) + 16, dtype=wp.int32, device=dev)
                self._chunks.invalidate()
            self.tri_count.zero_()
            wp.launch(kn["triangle_candidates"], dim=self.Nf,
                      inputs=[*common, 1, self.tri_count, self.tri_row, self.tri_cols], device=dev)
        self._need_rebuild = False
        self.n_rebuilds += 1
        self._timed("rebuild", t0)

    def _schedule_rebuild(self) -> None:
        """Decide from the max displacement / speed whether the lists survive another chunk."""
        ki, dev = self.ki, self.device
        self._disp2.zero_()
        self._speed2.zero_()
        wp.launch(ki["motion_stats"], dim=self.N, inputs=[self.x, self.v, self.xref, self.rep, self.status,
                                                          self._disp2, self._speed2], device=dev)
        if self.Nv:
            wp.launch(ki["motion_stats"], dim=self.Nv, inputs=[self.xv, self.vv, self.xvref, self.vrep, self.status,
                                                               self._disp2, self._speed2], device=dev)
        disp = math.sqrt(float(self._disp2.numpy()[0]))
        vmax = math.sqrt(float(self._speed2.numpy()[0]))
        self._vmax = vmax
        ov = self.overrun.numpy()
        if ov.any():
            self.n_overruns += 1
            self.overrun.zero_()
            self._need_rebuild = True
        if disp + self.safety * vmax * self.dt * self.chunk > 0.5 * self.skin:
            self._need_rebuild = True

    def _next_chunk(self, remaining: int) -> int:
        """Steps until the next check: the full chunk unless particles are fast enough to cross ``skin / 2``
        sooner (large dt on CPU checks); then fewer, without the graph."""
        vmax = getattr(self, "_vmax", None)
        k = self.chunk
        if vmax is not None and vmax > 0:
            k_safe = int(0.5 * self.skin / (self.safety * vmax * self.dt))
            k = max(1, min(k, k_safe))
        return min(k, remaining)
