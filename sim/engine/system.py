"""Particle system: R independent replicas of solvent (+ optional shell) advanced by the same launches.

Each replica has its own periodic box ``[0, L)^3``, DPD pair table (a, gamma, s per type pair),
masses, k_BT, random seed, shell mesh and :class:`~bubblecal.sim.engine.kernels.shell.ShellParams`.
Replicas never interact: the neighbour search (:mod:`bubblecal.sim.engine.neighbors`) only looks into a
replica's own cells, every force kernel reads its replica's parameters.

Storage (all on one Warp device, ``float32`` by default, ``float64`` selectable for CPU checks):

* solvent arrays (water, gas, wall particles of every replica): ``x, v, f, typ, rep, pid``; kept
  sorted by (replica, cell) at each neighbour-list rebuild; ``pid`` is the persistent particle id
  (random-number hashing, :meth:`solvent_numpy` returns particles in pid order);
* shell vertex arrays ``xv, vv, fv`` (replica blocks at ``vertex_offset[r]``, never reordered, coordinates
  unwrapped) and the triangles ``faces`` (global vertex indices).

One step (:meth:`step`): solvent-solvent DPD forces, vertex-solvent DPD forces (reaction atomically
onto the solvent), shell forces (:class:`ShellForceField`), optional user force callbacks; then
kick-drift (``v += F/m dt; x += v dt``) for solvent and vertices (optional pinning of the shell's
centre-of-mass velocity); then bounce-back of solvent on the moving triangles; step counter + 1.
The neighbour lists are rebuilt when any particle may have moved more than ``skin / 2`` since the
last rebuild (checked every ``chunk`` steps from the maximum displacement and speed; a per-step
overrun flag in the integrator catches the rest). On CUDA a chunk of steps is captured once as a
CUDA graph and replayed.

Set-up: :mod:`bubblecal.sim.engine.replicas` (:class:`ReplicaSpec`, :func:`bubble_spec`); measurements:
:mod:`bubblecal.sim.engine.system_observables`.  Units: DPD (length r_c = 250 nm, energy k_BT, time
r_c sqrt(m / k_BT) with the water bead mass m = 1).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.engine.graphs import ChunkGraph
from bubblecal.sim.engine.kernels.bounce import bounce_kernels
from bubblecal.sim.engine.kernels.integrate import integrate_kernels
from bubblecal.sim.engine.kernels.pairs import pair_kernels
from bubblecal.sim.engine.neighbors import NeighbourLists, grid_for_boxes, neighbor_kernels
from bubblecal.sim.engine.particles import N_TYPES, VERTEX, WALL
from bubblecal.sim.engine.replicas import ReplicaSpec
from bubblecal.sim.engine.system_observables import ParticleObservables

wp = require("warp", "sim")

__all__ = ["ParticleSystem", "resolve_dtype"]


def resolve_dtype(dtype) -> type:
    """The Warp scalar type of ``dtype``.

    Parameters
    ----------
    dtype : str, numpy or warp type
        ``wp.float32``, ``"float32"``, ``np.float32``, ``"f32"`` or the float64 equivalents.

    Returns
    -------
    type
        ``wp.float32`` or ``wp.float64``.

    Raises
    ------
    ValueError
        For any other value.
    """
    if dtype in (wp.float32, "float32", np.float32, "f32"):
        return wp.float32
    if dtype in (wp.float64, "float64", np.float64, "f64"):
        return wp.float64
    raise ValueError(f"dtype must be float32 or float64, got {dtype!r}")


class ParticleSystem(NeighbourLists, ParticleObservables):
    """R replicas advanced together (see the module docstring); DPD units throughout.

    Parameters
    ----------
    replicas : sequence of ReplicaSpec
        One description per replica.
    dt : float, optional
        Time step shared by the replicas (DPD time; 1e-4 with a stiff shell).
    device : str, optional
        Warp device, ``"cpu"`` or ``"cuda"`` (``"cuda:0"``, ...).
    dtype : str or warp type, optional
        ``"float32"`` (default, GPU) or ``"float64"`` (CPU checks); see :func:`resolve_dtype`.
    skin : float, optional
        Verlet skin (DPD length): the neighbour lists hold pairs within ``1 + skin``.
    chunk : int, optional
        Steps between rebuild checks (and the length of the captured CUDA graph).
    use_graph : bool, optional
        Capture chunks as CUDA graphs (default: on CUDA).
    bounce_eps : float, optional
        Distance off the triangle a bounced particle is put at (DPD length; default 1e-4, 2e-5 in float64).
    nbr_capacity, vnbr_capacity : int, optional
        Initial neighbour slots per solvent particle and per vertex (grown when needed).
    safety : float, optional
        Factor on (max speed x dt x chunk) when predicting whether the lists survive a chunk.

    Raises
    ------
    ValueError
        On no replicas, no solvent particles, a mesh without :class:`ShellParams`, an invalid pair table or
        a box too small for the cell lists.
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
        graphs = self.device.is_cuda if use_graph is None else bool(use_graph)
        self._chunks = ChunkGraph(self._one_step, self.device, graphs and self.device.is_cuda)
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
        """Set up every replica's particles and pack them, the tables and the shells into device arrays."""
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

    def _timed(self, name: str, t0: float) -> None:
        """Add the wall time since ``t0`` to ``timers[name]`` (s)."""
        self.timers[name] = self.timers.get(name, 0.0) + time.perf_counter() - t0

    # ------------------------------------------------------------------------------------------
    # one step
    # ------------------------------------------------------------------------------------------
    def compute_forces(self) -> None:
        """Forces of the current state: solvent-solvent and vertex-solvent DPD, shell, then the user callbacks.

        Writes ``f`` (solvent) and ``fv`` (vertices), DPD force; launches only (no synchronisation).
        """
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
        """Kick-drift of solvent and vertices, bounce-back on the moving triangles, step counter + 1."""
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
        """One time step (the unit a chunk repeats)."""
        self.compute_forces()
        self._integrate()

    def _advance(self, n: int) -> None:
        """Run ``n`` steps; a full chunk replays the CUDA graph."""
        self._chunks.run(n, capture=n == self.chunk)

    @property
    def use_graph(self) -> bool:
        """Whether full chunks replay as CUDA graphs (False on the CPU or after a failed capture)."""
        return self._chunks.enabled

    def step(self, n: int = 1, health=None, health_every: int = 0) -> None:
        """Advance every live replica by ``n`` steps of ``dt``, rebuilding the neighbour lists as needed.

        Parameters
        ----------
        n : int, optional
            Number of steps.
        health : HealthMonitor, optional
            Checked every ``health_every`` steps (at chunk boundaries); failed replicas are frozen.
        health_every : int, optional
            Steps between health checks (0 = never).
        """
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
