"""Particle system: R independent replicas of solvent (+ optional shell) advanced by the same launches.

Each replica has its own periodic box ``[0, L)^3``, DPD pair table (a, gamma, s per type pair),
masses, kBT, random seed, shell mesh and :class:`~bubblecal.sim.engine.kernels.shell.ShellParams`.
Replicas never interact: the neighbour search (:mod:`bubblecal.sim.engine.neighbors`) only looks into a
replica's own cells, every force kernel reads its replica's parameters.

Storage (all on one Warp device, ``float32`` by default, ``float64`` selectable for CPU checks):

* solvent arrays (water, gas, wall particles of every replica): ``x, v, f, typ, rep, pid``; kept
  sorted by (replica, cell) at each neighbour-list rebuild; ``pid`` is the persistent particle id
  (random-number hashing, :meth:`solvent_numpy` returns particles in pid order);
* shell vertex arrays ``xv, vv, fv`` (replica blocks at ``vert_offset[r]``, never reordered, coordinates
  unwrapped) and the triangles ``faces`` (global vertex indices).

One step (:meth:`step`): solvent-solvent DPD forces, vertex-solvent DPD forces (reaction atomically
onto the solvent), shell forces (:class:`ShellForceField`), optional user force callbacks; then
kick-drift (``v += F/m dt; x += v dt``) for solvent and vertices (optional pinning of the shell's
centre-of-mass velocity); then bounce-back of solvent on the moving triangles; step counter + 1.
The neighbour lists are rebuilt when any particle may have moved more than ``skin / 2`` since the
last rebuild (checked every ``chunk`` steps from the maximum displacement and speed; a per-step
overrun flag in the integrator catches the rest). On CUDA a chunk of steps is captured once as a
CUDA graph and replayed.

Set-up (:meth:`ReplicaSpec`): water is placed uniformly at number density ``water_density`` in the
box outside the shell and ideal gas at ``gas_density`` inside it (particles on the wrong side of the
reference mesh are deleted -- the set-up mesh is the convex icosphere, so a half-space test is exact);
velocities are Maxwellian at the replica's kBT with zero total momentum per replica.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import warp as wp

from bubblecal.sim.engine.graphs import ChunkGraph
from bubblecal.sim.engine.kernels.bounce import bounce_kernels
from bubblecal.sim.engine.kernels.integrate import integrate_kernels
from bubblecal.sim.engine.kernels.pairs import pair_kernels
from bubblecal.sim.engine.neighbors import grid_for_boxes, neighbor_kernels
from bubblecal.sim.engine.particles import GAS, N_TYPES, VERTEX, WALL, WATER, PairTable

__all__ = ["ReplicaSpec", "ParticleSystem", "resolve_dtype", "inside_convex_mesh", "bubble_spec"]


def resolve_dtype(dtype) -> type:
    if dtype in (wp.float32, "float32", np.float32, "f32"):
        return wp.float32
    if dtype in (wp.float64, "float64", np.float64, "f64"):
        return wp.float64
    raise ValueError(f"dtype must be float32 or float64, got {dtype!r}")


def inside_convex_mesh(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray, chunk: int = 4096) -> np.ndarray:
    """Boolean mask of points strictly inside a convex, outward-oriented triangulation.

    Points outside the vertices' bounding sphere are outside and points inside the inscribed sphere
    (distance to the nearest face plane) are inside; only the band between is tested face by face.
    """
    pts = np.asarray(points, dtype=np.float64)
    a = vertices[faces[:, 0]]
    n = np.cross(vertices[faces[:, 1]] - a, vertices[faces[:, 2]] - a)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    off = np.einsum("ij,ij->i", n, a)
    c = vertices.mean(axis=0)
    r_out = np.linalg.norm(vertices - c, axis=1).max()
    r_in = float(np.min(off - n @ c))  # > 0 when c is inside the convex mesh
    d = np.linalg.norm(pts - c, axis=1)
    out = d < r_in
    band = np.nonzero((d >= r_in) & (d <= r_out))[0]
    for s in range(0, len(band), chunk):
        idx = band[s:s + chunk]
        out[idx] = np.all(pts[idx] @ n.T - off[None, :] < 0.0, axis=1)
    return out


@dataclass
class ReplicaSpec:
    """Description of one replica.

    ``box``: edge lengths (DPD); ``pairs``: :class:`PairTable` (a, gamma, s per type pair and the
    per-type masses; the vertex mass is ``pairs.mass[VERTEX]`` unless ``vertex_mass`` is given);
    ``kbt``; ``seed``; ``water_density`` (number density of water outside the shell, 0 = none);
    ``gas_density`` (ideal gas inside the shell); ``mesh`` (:class:`~bubblecal.sim.engine.mesh.ShellMesh`
    centred at the origin, placed at ``center`` -- default the box centre -- or ``None``);
    ``shell`` (:class:`ShellParams`); ``frozen_shell`` (vertex inverse mass 0: a fixed wall);
    ``pin_com`` (remove the shell's mean velocity every step); ``extra_positions/extra_types/
    extra_velocities`` (additional particles, e.g. wall slabs); ``temperature_init`` (initial kBT of
    the velocities, default ``kbt``); ``water_gap``: no water is placed within this distance outside
    the shell's circumsphere at set-up (the vertex-water repulsion a = 400 would otherwise crush the
    shell in the first steps; the water closes the gap within a few hundred steps).
    """

    box: Sequence[float]
    pairs: PairTable
    kbt: float = 1.0
    seed: int = 0
    water_density: float = 3.0
    gas_density: float = 0.0
    mesh: object | None = None
    center: Sequence[float] | None = None
    shell: object | None = None
    vertex_mass: float | None = None
    frozen_shell: bool = False
    pin_com: bool = False
    extra_positions: np.ndarray | None = None
    extra_types: np.ndarray | None = None
    extra_velocities: np.ndarray | None = None
    temperature_init: float | None = None
    water_gap: float = 0.5
    label: str = ""

    def build_particles(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """(solvent positions, types, velocities, vertex positions or None) in float64."""
        rng = np.random.default_rng(self.seed)
        box = np.asarray(self.box, dtype=np.float64)
        vol = float(np.prod(box))
        pos, typ = [], []
        verts = None
        center = box / 2 if self.center is None else np.asarray(self.center, dtype=np.float64)
        if self.mesh is not None:
            verts = np.asarray(self.mesh.vertices, dtype=np.float64) + center
        if self.water_density > 0:
            n = int(round(self.water_density * vol))
            p = rng.uniform(0, 1, (n, 3)) * box
            if verts is not None:
                keep = ~inside_convex_mesh(p, verts, self.mesh.faces)
                if self.water_gap > 0:
                    rad = np.linalg.norm(verts - center, axis=1).max()
                    keep &= np.linalg.norm(p - center, axis=1) > rad + self.water_gap
                p = p[keep]
            pos.append(p)
            typ.append(np.full(len(p), WATER))
        if self.gas_density > 0:
            if verts is None:
                n = int(round(self.gas_density * vol))
                p = rng.uniform(0, 1, (n, 3)) * box
            else:
                lo, hi = verts.min(axis=0), verts.max(axis=0)
                n = int(round(self.gas_density * float(np.prod(hi - lo))))
                p = lo + rng.uniform(0, 1, (n, 3)) * (hi - lo)
                p = p[inside_convex_mesh(p, verts, self.mesh.faces)]
            pos.append(p)
            typ.append(np.full(len(p), GAS))
        if self.extra_positions is not None:
            ep = np.asarray(self.extra_positions, dtype=np.float64).reshape(-1, 3)
            et = (np.full(len(ep), WALL) if self.extra_types is None
                  else np.asarray(self.extra_types, dtype=np.int64).reshape(-1))
            pos.append(ep)
            typ.append(et)
        x = np.concatenate(pos) if pos else np.zeros((0, 3))
        t = np.concatenate(typ).astype(np.int32) if typ else np.zeros(0, dtype=np.int32)
        kt = self.kbt if self.temperature_init is None else self.temperature_init
        m = np.asarray(self.pairs.mass, dtype=np.float64)[t]
        v = rng.normal(0.0, 1.0, (len(x), 3)) * np.sqrt(kt / m)[:, None]
        if self.extra_positions is not None:
            ne = len(np.asarray(self.extra_positions).reshape(-1, 3))
            v[len(x) - ne:] = (0.0 if self.extra_velocities is None
                               else np.asarray(self.extra_velocities, dtype=np.float64).reshape(-1, 3))
        mobile = t != WALL
        if mobile.sum() > 1:  # zero total momentum of the mobile solvent
            p_tot = (m[mobile, None] * v[mobile]).sum(axis=0)
            v[mobile] -= p_tot / m[mobile].sum()
        return x, t, v, verts


class ParticleSystem:
    """R replicas advanced together; see the module docstring.

    Args:
        replicas: list of :class:`ReplicaSpec`.
        dt: time step (shared by the replicas; 1e-4 with a stiff shell).
        device: ``"cpu"`` or ``"cuda"`` (``"cuda:0"``...).
        dtype: ``"float32"`` (default, GPU) or ``"float64"`` (CPU checks).
        skin: Verlet skin (neighbour lists hold pairs within ``1 + skin``).
        chunk: steps between rebuild checks (and the length of the captured CUDA graph).
        use_graph: capture chunks as CUDA graphs (default: on CUDA).
        bounce_eps: distance off the triangle a bounced particle is put at.
    """

    def __init__(self, replicas: Sequence[ReplicaSpec], dt: float = 1e-4, device: str = "cpu",
                 dtype="float32", skin: float = 0.3, chunk: int = 20, use_graph: bool | None = None,
                 bounce_eps: float | None = None, nbr_capacity: int = 48, vnbr_capacity: int = 64,
                 safety: float = 1.5):
        wp.init()
        self.specs = list(replicas)
        if not self.specs:
            raise ValueError("no replicas")
        self.R = len(self.specs)
        self.device = wp.get_device(device)
        self.dtype = resolve_dtype(dtype)
        self.np_dtype = np.float32 if self.dtype is wp.float32 else np.float64
        self.vec3 = wp.types.vector(3, self.dtype)
        self.dt = float(dt)
        self.skin = float(skin)
        self.rlist = 1.0 + self.skin
        self.chunk = int(chunk)
        #: factor on (max speed x dt x chunk) when predicting whether the lists survive a chunk; a
        #: particle that still moves more than skin/2 sets the overrun flag (counted, forces a rebuild)
        self.safety = float(safety)
        self._chunks = ChunkGraph(self._one_step, self.device,
                                  (self.device.is_cuda if use_graph is None else bool(use_graph)) and self.device.is_cuda)
        self.bounce_eps = (2e-5 if self.dtype is wp.float64 else 1e-4) if bounce_eps is None else float(bounce_eps)
        self.kp = pair_kernels(self.dtype)
        self.kn = neighbor_kernels(self.dtype)
        self.ki = integrate_kernels(self.dtype)
        self.kb = bounce_kernels(self.dtype)
        self.force_callbacks: list[Callable[[ParticleSystem], None]] = []
        self.steps_done = 0
        self.n_rebuilds = 0
        self.n_overruns = 0
        self.timers: dict[str, float] = {}
        self._nbr_capacity = int(nbr_capacity)
        self._vnbr_capacity = int(vnbr_capacity)
        self._build()

    # ------------------------------------------------------------------------------------------
    # construction
    # ------------------------------------------------------------------------------------------
    def _build(self) -> None:
        dev, npf = self.device, self.np_dtype
        R = self.R
        xs, ts, vs, reps = [], [], [], []
        vx, vrep, faces, frep, meshes, shell_params, vert_off, face_off = [], [], [], [], [], [], [], []
        self.shell_replicas: list[int] = []
        self.vertex_count = np.zeros(R, dtype=np.int64)
        self.face_count = np.zeros(R, dtype=np.int64)
        self.vertex_offset = np.zeros(R, dtype=np.int64)
        self.face_offset = np.zeros(R, dtype=np.int64)
        nv_total = 0
        nf_total = 0
        for r, spec in enumerate(self.specs):
            spec.pairs.validate()
            x, t, v, verts = spec.build_particles()
            xs.append(x)
            ts.append(t)
            vs.append(v)
            reps.append(np.full(len(x), r, dtype=np.int32))
            self.vertex_offset[r] = nv_total
            self.face_offset[r] = nf_total
            if verts is not None:
                if spec.shell is None:
                    raise ValueError(f"replica {r} has a mesh but no ShellParams (shell=...)")
                vx.append(verts)
                vrep.append(np.full(len(verts), r, dtype=np.int32))
                faces.append(np.asarray(spec.mesh.faces, dtype=np.int64) + nv_total)
                frep.append(np.full(len(spec.mesh.faces), r, dtype=np.int32))
                meshes.append(spec.mesh)
                shell_params.append(spec.shell)
                vert_off.append(nv_total)
                face_off.append(nf_total)
                self.shell_replicas.append(r)
                self.vertex_count[r] = len(verts)
                self.face_count[r] = len(spec.mesh.faces)
                nv_total += len(verts)
                nf_total += len(spec.mesh.faces)
        x = np.concatenate(xs)
        self.N = len(x)
        self.Nv = nv_total
        self.Nf = nf_total
        if self.N == 0:
            raise ValueError("no solvent particles")
        self.boxes = np.array([np.asarray(s.box, dtype=np.float64) for s in self.specs])
        ncell, cell_off, ncells = grid_for_boxes(self.boxes, self.rlist)
        self.ncell_np, self.cell_off_np, self.ncells = ncell, cell_off, ncells

        # per-replica tables
        a = np.zeros((R, N_TYPES, N_TYPES))
        g = np.zeros_like(a)
        s = np.ones_like(a)
        mass = np.ones((R, N_TYPES))
        inv_mass = np.ones((R, N_TYPES))
        kbt = np.array([float(sp.kbt) for sp in self.specs])
        for r, sp in enumerate(self.specs):
            a[r], g[r], s[r] = sp.pairs.a, sp.pairs.gamma, sp.pairs.s
            mass[r] = sp.pairs.mass
            if sp.vertex_mass is not None:
                mass[r, VERTEX] = sp.vertex_mass
            inv_mass[r] = 1.0 / mass[r]
            inv_mass[r, WALL] = 0.0
            if sp.frozen_shell:
                inv_mass[r, VERTEX] = 0.0
        sig = np.sqrt(2.0 * g * kbt[:, None, None])
        self.mass_np, self.inv_mass_np, self.kbt_np = mass, inv_mass, kbt

        def arr(a_, dtype):
            return wp.array(np.ascontiguousarray(a_), dtype=dtype, device=dev)

        V = self.vec3
        self.box = arr(self.boxes.astype(npf), V)
        self.ncell = arr(ncell.astype(np.int32), wp.vec3i)
        self.cell_offset = arr(cell_off.astype(np.int32), wp.int32)
        self.tab_a = arr(a.reshape(-1).astype(npf), self.dtype)
        self.tab_g = arr(g.reshape(-1).astype(npf), self.dtype)
        self.tab_s = arr(s.reshape(-1).astype(npf), self.dtype)
        self.tab_sig = arr(sig.reshape(-1).astype(npf), self.dtype)
        self.mass = arr(mass.reshape(-1).astype(npf), self.dtype)
        self.inv_mass = arr(inv_mass.reshape(-1).astype(npf), self.dtype)
        self.kbt = arr(kbt.astype(npf), self.dtype)
        self.seeds = arr(np.array([int(sp.seed) % (2**31 - 1) for sp in self.specs], dtype=np.int32), wp.int32)
        self.status = wp.zeros(R, dtype=wp.int32, device=dev)
        self.pin = arr(np.array([int(sp.pin_com) for sp in self.specs], dtype=np.int32), wp.int32)
        self.nvert = arr(np.maximum(self.vertex_count, 1).astype(np.int32), wp.int32)
        self.mom = wp.zeros(R, dtype=V, device=dev)
        self.overrun = wp.zeros(R, dtype=wp.int32, device=dev)
        self.impulse = wp.zeros(R, dtype=wp.float64, device=dev)
        self.nbounce = wp.zeros(R, dtype=wp.int32, device=dev)
        self.step_counter = wp.zeros(1, dtype=wp.int32, device=dev)
        self._disp2 = wp.zeros(1, dtype=self.dtype, device=dev)
        self._speed2 = wp.zeros(1, dtype=self.dtype, device=dev)

        # solvent
        N = self.N
        self.x = arr(x.astype(npf), V)
        self.v = arr(np.concatenate(vs).astype(npf), V)
        self.f = wp.zeros(N, dtype=V, device=dev)
        self.typ = arr(np.concatenate(ts).astype(np.int32), wp.int32)
        self.rep = arr(np.concatenate(reps), wp.int32)
        self.pid = arr(np.arange(N, dtype=np.int32), wp.int32)
        self.xref = wp.zeros(N, dtype=V, device=dev)
        self._x2 = wp.zeros(N, dtype=V, device=dev)
        self._i2 = wp.zeros(N, dtype=wp.int32, device=dev)
        self._keys = wp.zeros(2 * N, dtype=wp.int32, device=dev)
        self._vals = wp.zeros(2 * N, dtype=wp.int32, device=dev)
        self.cell_start = wp.zeros(ncells, dtype=wp.int32, device=dev)
        self.cell_end = wp.zeros(ncells, dtype=wp.int32, device=dev)
        self.nbr = wp.zeros((self._nbr_capacity, N), dtype=wp.int32, device=dev)
        self.ncount = wp.zeros(N, dtype=wp.int32, device=dev)
        self._maxcount = wp.zeros(3, dtype=wp.int32, device=dev)

        # shell
        self.shell_field = None
        Nv = max(self.Nv, 1)
        self.xv = arr((np.concatenate(vx) if vx else np.zeros((1, 3))).astype(npf), V)
        self.vv = wp.zeros(Nv, dtype=V, device=dev)
        self.fv = wp.zeros(Nv, dtype=V, device=dev)
        self.xv_old = wp.zeros(Nv, dtype=V, device=dev)
        self.xvref = wp.zeros(Nv, dtype=V, device=dev)
        self.vrep = arr((np.concatenate(vrep) if vrep else np.zeros(1, dtype=np.int32)), wp.int32)
        self.vnbr = wp.zeros((self._vnbr_capacity, Nv), dtype=wp.int32, device=dev)
        self.vcount = wp.zeros(Nv, dtype=wp.int32, device=dev)
        self.faces_np = np.concatenate(faces).astype(np.int32) if faces else np.zeros((0, 3), dtype=np.int32)
        self.faces = arr(self.faces_np if faces else np.zeros((1, 3), dtype=np.int32), wp.vec3i)
        self.frep = arr((np.concatenate(frep) if frep else np.zeros(1, dtype=np.int32)), wp.int32)
        self.tri_count = wp.zeros(N, dtype=wp.int32, device=dev)
        self.tri_row = wp.zeros(N + 1, dtype=wp.int32, device=dev)
        self.tri_cols = wp.zeros(max(16, 4 * N // 10 if self.Nf else 16), dtype=wp.int32, device=dev)
        self.meshes = meshes
        if self.Nv:
            from bubblecal.sim.engine.kernels.shell import ShellForceField

            self.shell_field = ShellForceField(meshes, shell_params, device=str(dev), dtype=self.dtype,
                                               offsets=vert_off)
            self.ref_area_tri = np.concatenate([np.asarray(m.A0, dtype=np.float64) for m in meshes])
        # shell forces are skipped when every shell is frozen (vertex inverse mass 0)
        self.shell_active = bool(any(inv_mass[r, VERTEX] > 0 for r in self.shell_replicas))
        self._need_rebuild = True

    # ------------------------------------------------------------------------------------------
    # neighbour lists
    # ------------------------------------------------------------------------------------------
    def _timed(self, name: str, t0: float) -> None:
        self.timers[name] = self.timers.get(name, 0.0) + time.perf_counter() - t0

    def rebuild(self) -> None:
        """Sort the solvent by cell and rebuild every neighbour / candidate list."""
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

    # ------------------------------------------------------------------------------------------
    # one step
    # ------------------------------------------------------------------------------------------
    def compute_forces(self) -> None:
        kp, dev = self.kp, self.device
        inv_sqrt_dt = 1.0 / math.sqrt(self.dt)
        wp.launch(kp["solvent_forces"], dim=self.N,
                  inputs=[self.x, self.v, self.typ, self.rep, self.pid, self.nbr, self.ncount, self.box,
                          self.tab_a, self.tab_g, self.tab_s, self.tab_sig, self.seeds, self.step_counter,
                          inv_sqrt_dt, self.f], device=dev)
        if self.Nv:
            self.fv.zero_()
            wp.launch(kp["vertex_solvent_forces"], dim=self.Nv,
                      inputs=[self.xv, self.vv, self.vrep, self.x, self.v, self.typ, self.pid, self.vnbr,
                              self.vcount, self.box, self.tab_a, self.tab_g, self.tab_s, self.tab_sig, self.seeds,
                              self.step_counter, inv_sqrt_dt, self.fv, self.f], device=dev)
            if self.shell_active:
                self.shell_field.accumulate_forces(self.xv, self.fv, self.vv)
        for cb in self.force_callbacks:
            cb(self)

    def _integrate(self) -> None:
        ki, dev = self.ki, self.device
        hs2 = (0.5 * self.skin) ** 2
        wp.launch(ki["kick_drift_solvent"], dim=self.N,
                  inputs=[self.x, self.v, self.f, self.typ, self.rep, self.inv_mass, self.status, self.dt,
                          self.xref, hs2, self.overrun], device=dev)
        if self.Nv:
            self.mom.zero_()
            wp.launch(ki["kick_vertices"], dim=self.Nv,
                      inputs=[self.vv, self.fv, self.vrep, self.inv_mass, self.status, self.dt, self.pin, self.mom],
                      device=dev)
            wp.launch(ki["drift_vertices"], dim=self.Nv,
                      inputs=[self.xv, self.vv, self.xv_old, self.vrep, self.status, self.dt, self.pin, self.mom,
                              self.nvert, self.xvref, hs2, self.overrun], device=dev)
            wp.launch(self.kb["bounce"], dim=self.N,
                      inputs=[self.x, self.v, self.typ, self.rep, self.pid, self.tri_row, self.tri_cols,
                              self.xv_old, self.xv, self.vv, self.faces, self.box, self.mass, self.inv_mass,
                              self.kbt, self.seeds, self.step_counter, self.status, self.dt, self.bounce_eps,
                              self.impulse, self.nbounce], device=dev)
        wp.launch(ki["increment"], dim=1, inputs=[self.step_counter], device=dev)

    def _one_step(self) -> None:
        self.compute_forces()
        self._integrate()

    def _advance(self, n: int) -> None:
        self._chunks.run(n, capture=n == self.chunk)

    @property
    def use_graph(self) -> bool:
        """Whether full chunks replay as CUDA graphs (False on the CPU or after a failed capture)."""
        return self._chunks.enabled

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
        """Steps until the next check: the full chunk unless particles are fast enough to cross
        ``skin / 2`` sooner (large dt on CPU checks); then fewer, without the graph."""
        vmax = getattr(self, "_vmax", None)
        k = self.chunk
        if vmax is not None and vmax > 0:
            k_safe = int(0.5 * self.skin / (self.safety * vmax * self.dt))
            k = max(1, min(k, k_safe))
        return min(k, remaining)

    def step(self, n: int = 1, health=None, health_every: int = 0) -> None:
        """Advance every live replica by ``n`` steps (``health``: a HealthMonitor checked every
        ``health_every`` steps)."""
        done = 0
        since_health = 0
        while done < n:
            if self._need_rebuild:
                self.rebuild()
            k = self._next_chunk(n - done)
            t0 = time.perf_counter()
            self._advance(k)
            if self.device.is_cuda:
                wp.synchronize_device(self.device)
            self._timed("advance", t0)
            done += k
            self.steps_done += k
            since_health += k
            self._schedule_rebuild()
            if health is not None and health_every and since_health >= health_every:
                health.check(self)
                since_health = 0

    # ------------------------------------------------------------------------------------------
    # measurements (synchronise; float64 on the host)
    # ------------------------------------------------------------------------------------------
    def solvent_counts(self) -> np.ndarray:
        """[R, N_TYPES] number of solvent particles of each type per replica."""
        rep, typ = self.rep.numpy(), self.typ.numpy()
        out = np.zeros((self.R, N_TYPES), dtype=np.int64)
        np.add.at(out, (rep, typ), 1)
        return out

    def virial_pressure(self) -> tuple[np.ndarray, np.ndarray]:
        """(pressure [R], kinetic temperature [R]) of the solvent: P = (sum m v^2 + sum r.F^C)/(3V).

        Only valid for replicas without a shell; requires current neighbour lists (call after
        :meth:`step`).
        """
        if self._need_rebuild:
            self.rebuild()
        vir = wp.zeros(self.R, dtype=wp.float64, device=self.device)
        kin = wp.zeros(self.R, dtype=wp.float64, device=self.device)
        wp.launch(self.kp["solvent_virial"], dim=self.N,
                  inputs=[self.x, self.v, self.typ, self.rep, self.nbr, self.ncount, self.box, self.tab_a,
                          self.mass, vir, kin], device=self.device)
        vol = self.boxes.prod(axis=1)
        nmob = self.solvent_counts()[:, [WATER, GAS]].sum(axis=1)
        k = kin.numpy()
        return (k + vir.numpy()) / (3.0 * vol), k / (3.0 * np.maximum(nmob, 1))

    def kinetic_temperature(self) -> np.ndarray:
        """<m v^2>/3 per replica over mobile solvent particles."""
        v = self.v.numpy().astype(np.float64)
        m = self.mass_np[self.rep.numpy(), self.typ.numpy()]
        mob = self.typ.numpy() != WALL
        e = np.zeros(self.R)
        c = np.zeros(self.R)
        rep = self.rep.numpy()
        np.add.at(e, rep[mob], (m[mob, None] * v[mob] ** 2).sum(axis=1))
        np.add.at(c, rep[mob], 1)
        return e / (3.0 * np.maximum(c, 1))

    def total_momentum(self) -> np.ndarray:
        """[R, 3] total momentum (solvent + shell vertices) per replica, float64."""
        p = np.zeros((self.R, 3))
        v = self.v.numpy().astype(np.float64)
        rep, typ = self.rep.numpy(), self.typ.numpy()
        m = self.mass_np[rep, typ] * (typ != WALL)
        np.add.at(p, rep, m[:, None] * v)
        if self.Nv:
            vv = self.vv.numpy().astype(np.float64)
            vr = self.vrep.numpy()
            mv = self.mass_np[vr, VERTEX] * (self.inv_mass_np[vr, VERTEX] > 0)
            np.add.at(p, vr, mv[:, None] * vv)
        return p

    def solvent_numpy(self) -> dict[str, np.ndarray]:
        """Solvent arrays in persistent-id order (float64 positions/velocities)."""
        order = np.argsort(self.pid.numpy())
        return {"x": self.x.numpy().astype(np.float64)[order], "v": self.v.numpy().astype(np.float64)[order],
                "type": self.typ.numpy()[order], "replica": self.rep.numpy()[order]}

    def vertices_numpy(self, r: int) -> np.ndarray:
        o, n = int(self.vertex_offset[r]), int(self.vertex_count[r])
        return self.xv.numpy().astype(np.float64)[o:o + n]

    def shell_area_volume(self) -> tuple[np.ndarray, np.ndarray]:
        """Areas and volumes of every replica's shell (NaN for replicas without one)."""
        a = np.full(self.R, np.nan)
        vol = np.full(self.R, np.nan)
        if self.Nv:
            aa, vv = self.shell_field.areas_volumes(self.xv)
            a[self.shell_replicas] = aa
            vol[self.shell_replicas] = vv
        return a, vol

    def status_numpy(self) -> np.ndarray:
        return self.status.numpy().copy()

    def memory_bytes(self) -> int:
        """Bytes of the device arrays held by the system (neighbour lists included)."""
        total = 0
        for val in vars(self).values():
            if isinstance(val, wp.array):
                total += val.capacity
        if self.shell_field is not None:
            for val in vars(self.shell_field).values():
                if isinstance(val, wp.array):
                    total += val.capacity
        return int(total)


def bubble_spec(diameter_um: float = 3.0, subdivisions: int | None = None, box=None, seed: int = 0,
                ka: float = 5584.0, kb: float = 389.23, p_back: float = 91.0, gas_density: float = 3.0,
                protocol: str = "compression", rho_shell_kg_m3: float | None = None, mass_factor: float = 1.0,
                a_vertex_water: float | None = None, kbt: float = 1.0, **shell_kwargs) -> ReplicaSpec:
    """A bubble at the published parameters (physics.md sections 2-3) in explicit water and gas.

    Icosphere for the diameter (subdivision 4, 5 above 5 um), box ``(2R+5, 2R+5, 2R+10)`` by default
    (17 x 17 x 22 for 3 um), published pair table with gamma_fsi from the mesh's vertex density,
    vertex mass rho_shell h A / N_v x ``mass_factor`` (rho_shell 1100 kg/m^3 for compression, x5 for
    indentation), k_a = 5,584 (E = 10 MPa), mu = k_a/3, k_b = 389.23, back pressure p_b = 91 and
    an ideal gas of number density ``gas_density`` (*choice*, default 3) inside.
    """
    from bubblecal.sim.engine.kernels.shell import ShellParams
    from bubblecal.sim.engine.mesh import mesh_for_diameter
    from bubblecal.sim.engine.particles import RHO_SHELL_KG_M3, published_pair_table

    mesh = mesh_for_diameter(diameter_um, subdivisions)
    R = mesh.radius_dpd
    if box is None:
        box = (2 * R + 5.0, 2 * R + 5.0, 2 * R + 10.0)
    if rho_shell_kg_m3 is None:
        rho_shell_kg_m3 = RHO_SHELL_KG_M3 * (5.0 if protocol == "indentation" else 1.0)
    m_v = mesh.vertex_mass(rho_shell_kg_m3, mass_factor=mass_factor)
    tab = published_pair_table(mesh.n_vertices / mesh.area(), protocol, m_vertex=m_v,
                               rho_gas_number=gas_density, a_vertex_water=a_vertex_water)
    return ReplicaSpec(box=box, pairs=tab, kbt=kbt, seed=seed, water_density=3.0, gas_density=gas_density,
                       mesh=mesh, shell=ShellParams(ka=ka, kb=kb, p_back=p_back, **shell_kwargs))
