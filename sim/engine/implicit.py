"""Implicit-solvent shell system: R bubble shells without solvent particles, batched in the same launches.

Each replica is a shell (Lim in-plane + bending + optional constraints + self-avoidance, exactly the
:class:`~bubblecal.sim.engine.kernels.shell.ShellForceField` of the explicit engine) whose enclosed ideal gas
and surrounding water are replaced by pressures acting on the enclosed volume V (physics.md section 7,
"implicit" tier):

* ideal gas inside: p_gas = N_g k_BT / V (``gas_number`` N_g per replica, or ``p0`` = p_gas at the
  reference volume V0, then N_g = p0 V0 / k_BT);
* constant back pressure ``p_back`` (default 91, physics.md section 3) pushing outward;
* constant ambient (water) pressure ``p_water`` pushing inward.  *Choice*: ``None`` (default) =
  ``p_back + p_gas(V0)``, so the stress-free reference is balanced (force-free at T = 0).  With the
  defaults (p0 = 3: gas number density 3 as in :func:`bubblecal.sim.engine.system.bubble_spec`) p_water = 94.
  The explicit model's water (a = 100: 89.05 in bulk, plus the vertex-water repulsion at the membrane)
  leaves its bubbles at V/V0 ~ 0.99 (benchmarks/RESULTS.md); a constant pressure adds no stiffness, only
  the gas bulk modulus (p0) does.

  The net outward force on vertex v is (p_gas - p_water + p_back) dV/dx_v.

* Thermostat: Langevin on every vertex (friction ``gamma`` [DPD mass/time], noise at k_BT), integrated
  with BAOAB (one force evaluation per step; the O step is the exact Ornstein-Uhlenbeck update
  v <- c1 v + sqrt((1 - c1^2) k_BT/m) xi, c1 = exp(-gamma dt / m)).  *Why Langevin and not DPD-style
  pairs with a virtual solvent*: with no solvent particles there is no partner for pairwise forces; a
  per-vertex bath samples the canonical ensemble exactly, is trivially batched (one thread per vertex)
  and its only defect, non-conservation of momentum, is irrelevant here because the bubble's
  centre-of-mass velocity is pinned anyway.  Default ``gamma`` = the friction one vertex feels from a
  half-space of published DPD water, gamma_fsi rho_w pi/18 (~2.2 for a 3 um s4 bubble): the same local
  damping, not the hydrodynamic one.

* ``pin_com`` (default on): the mean (replica) vertex force is removed every step and the mean velocity
  after the thermostat kick, so the centre of mass does not move (to round-off).
* Anchors: :meth:`set_anchor_z` marks vertices whose z velocity (and force) is held at zero (the
  equator of the indentation protocol).
* External forces: :meth:`set_external_forces` (constant per-vertex forces [R, Nv, 3], device array) and
  :meth:`add_force_callback` (``cb(system)`` adds into ``system.f`` after the internal forces; must only
  launch kernels so that CUDA-graph capture keeps working -- e.g. the analytic plates of
  :mod:`bubblecal.sim.protocols.md_loading`).

Storage: all replicas' vertices in one packed array ``x`` [sum N_v] (replica r at rows
``offsets[r]:offsets[r] + n_vertices[r]``), ``float32`` by default; per-replica tables on the device.
One step = ~8 launches for all R replicas (shell forces, volume, pressure, force sum, two
half-kick/drift kernels, step counter), independent of R; on CUDA ``chunk`` steps are captured once
as a CUDA graph and replayed.  Memory (float32, measured with :meth:`memory_bytes`, shell field's
topology tables included): ~350 B per vertex, so R = 1,000 s4 bubbles (2.56 M vertices) need ~0.9 GB.

Health: :meth:`check_health` marks replicas with non-finite coordinates (NAN), an over-stretched
triangle (RUPTURE, max |A_t/A0_t - 1| > ``rupture_strain``), a collapsed or folded triangle (INVERSION)
or a vertex far from the centroid (ESCAPE), using :class:`bubblecal.sim.engine.health.Status` codes; a marked
replica is frozen (no longer integrated) while the others go on.

Units: DPD throughout (length 0.25 um, energy k_BT, see :mod:`bubblecal.data.units`).
"""

# (no "from __future__ import annotations": Warp must see the closure types of the kernel signatures)

import dataclasses
import functools
import math
from collections.abc import Callable, Sequence

import numpy as np
import warp as wp

from bubblecal.sim.engine.graphs import ChunkGraph
from bubblecal.sim.engine.health import Status
from bubblecal.sim.engine.kernels.common import kernel_decorator
from bubblecal.sim.engine.kernels.shell import ShellForceField, ShellParams
from bubblecal.sim.engine.mesh import ShellMesh

__all__ = ["ImplicitShellSystem", "HealthThresholds", "default_vertex_friction", "P_BACK_DEFAULT",
           "GAS_P0_DEFAULT"]

#: Published back pressure (DPD pressure, physics.md section 3).
P_BACK_DEFAULT = 91.0
#: Gas pressure at the reference volume (= number density 3 at k_BT = 1, the explicit tier's choice).
GAS_P0_DEFAULT = 3.0

# per-replica table columns
T_NKT, T_PEXT, T_KBT, T_GAMMA, T_MASS, T_NV, T_NFREE = range(7)
N_TAB = 7


@dataclasses.dataclass(frozen=True)
class HealthThresholds:
    """Limits of :meth:`ImplicitShellSystem.check_health` (dimensionless).

    ``rupture_strain``: max triangle |A/A0 - 1|; ``min_area_ratio``: smallest A/A0 before a triangle
    counts as collapsed; ``max_dihedral_change``: radians (a fold gives ~pi); ``max_radius_factor``:
    largest vertex distance from the centroid in units of the reference radius.
    """

    rupture_strain: float = 1.0
    min_area_ratio: float = 0.02
    max_dihedral_change: float = 2.5
    max_radius_factor: float = 3.0


def default_vertex_friction(mesh: ShellMesh, protocol: str = "compression") -> float:
    """Langevin friction [DPD mass / DPD time] of one vertex: gamma_fsi rho_w pi / 18.

    gamma_fsi is the published vertex-water DPD friction for this mesh's vertex density
    (:func:`bubblecal.sim.engine.particles.published_pair_table`); pi/18 rho_w = the integral of the s = 1/2
    dissipative weight w^2 = 1 - r over a half-space of water at number density rho_w = 3, projected
    on one direction (1/3).
    """
    from bubblecal.sim.engine.particles import VERTEX, WATER, published_pair_table

    tab = published_pair_table(mesh.n_vertices / mesh.area(), protocol)
    return float(tab.gamma[VERTEX, WATER] * 3.0 * math.pi / 18.0)


@functools.cache
def _kernels(dtype):
    T = dtype
    V = wp.types.vector(3, T)
    kern = kernel_decorator(dtype, "implicit")

    @kern
    def volume_kernel(x: wp.array(dtype=V), tri: wp.array(dtype=wp.vec3i), tri_rep: wp.array(dtype=wp.int32),
                      goff: wp.array(dtype=wp.int32), vol: wp.array(dtype=T)):
        t = wp.tid()
        r = tri_rep[t]
        idx = tri[t]
        c = x[goff[r]]
        wp.atomic_add(vol, r, wp.dot(x[idx[0]] - c, wp.cross(x[idx[1]] - c, x[idx[2]] - c)) / T(6.0))

    @kern
    def pressure_kernel(x: wp.array(dtype=V), f: wp.array(dtype=V), tri: wp.array(dtype=wp.vec3i),
                        tri_rep: wp.array(dtype=wp.int32), tab: wp.array2d(dtype=T), vol: wp.array(dtype=T),
                        status: wp.array(dtype=wp.int32)):
        t = wp.tid()
        r = tri_rep[t]
        if status[r] != 0:
            return
        idx = tri[t]
        x0 = x[idx[0]]
        n = wp.cross(x[idx[1]] - x0, x[idx[2]] - x0)
        v = wp.max(vol[r], T(1.0e-12))
        p = tab[r, T_NKT] / v - tab[r, T_PEXT]
        fc = (p / T(6.0)) * n  # p dV/dx per corner (translation-invariant form, exact for closed meshes)
        wp.atomic_add(f, idx[0], fc)
        wp.atomic_add(f, idx[1], fc)
        wp.atomic_add(f, idx[2], fc)

    @kern
    def force_sum_kernel(f: wp.array(dtype=V), fext: wp.array(dtype=V), vrep: wp.array(dtype=wp.int32),
                         fsum: wp.array(dtype=V)):
        i = wp.tid()
        wp.atomic_add(fsum, vrep[i], f[i] + fext[i])

    @kern
    def finish_kick(v: wp.array(dtype=V), f: wp.array(dtype=V), fext: wp.array(dtype=V),
                    fstore: wp.array(dtype=V), vrep: wp.array(dtype=wp.int32), anchor: wp.array(dtype=wp.int32),
                    tab: wp.array2d(dtype=T), fsum: wp.array(dtype=V), pin: wp.int32,
                    status: wp.array(dtype=wp.int32), dt: T):
        # second half of B: v += F dt / (2 m), F with the replica's mean removed (pinned COM)
        i = wp.tid()
        r = vrep[i]
        if status[r] != 0:
            return
        ft = f[i] + fext[i]
        if pin != 0:
            ft = ft - fsum[r] / tab[r, T_NV]
        if anchor[i] != 0:
            ft = V(ft[0], ft[1], T(0.0))
        fstore[i] = ft
        v[i] = v[i] + ft * (T(0.5) * dt / tab[r, T_MASS])

    @kern
    def kick_drift_thermo(x: wp.array(dtype=V), v: wp.array(dtype=V), fstore: wp.array(dtype=V),
                          vrep: wp.array(dtype=wp.int32), anchor: wp.array(dtype=wp.int32),
                          tab: wp.array2d(dtype=T), seeds: wp.array(dtype=wp.int32),
                          step: wp.array(dtype=wp.int32), mom: wp.array(dtype=V), pin: wp.int32,
                          status: wp.array(dtype=wp.int32), dt: T, local: wp.array(dtype=wp.int32)):
        # B (first half) A (half drift) O (exact OU)
        i = wp.tid()
        r = vrep[i]
        if status[r] != 0:
            return
        m = tab[r, T_MASS]
        half = T(0.5) * dt
        vi = v[i] + fstore[i] * (half / m)
        xi = x[i] + vi * half
        g = tab[r, T_GAMMA]
        kt = tab[r, T_KBT]
        if g > T(0.0):
            c1 = wp.exp(-g * dt / m)
            amp = wp.sqrt(wp.max(T(1.0) - c1 * c1, T(0.0)) * kt / m)
            st = wp.rand_init(seeds[r], step[0])
            st = wp.rand_init(wp.int32(st), local[i])
            xi_n = V(T(wp.randn(st)), T(wp.randn(st)), T(wp.randn(st)))
            vi = c1 * vi + amp * xi_n
        if anchor[i] != 0:
            vi = V(vi[0], vi[1], T(0.0))
        v[i] = vi
        x[i] = xi
        if pin != 0:
            wp.atomic_add(mom, r, vi)

    @kern
    def drift_half(x: wp.array(dtype=V), v: wp.array(dtype=V), vrep: wp.array(dtype=wp.int32),
                   anchor: wp.array(dtype=wp.int32), tab: wp.array2d(dtype=T), mom: wp.array(dtype=V),
                   pin: wp.int32, status: wp.array(dtype=wp.int32), dt: T):
        # (pinned: remove the replica's mean velocity) A (second half drift)
        i = wp.tid()
        r = vrep[i]
        if status[r] != 0:
            return
        vi = v[i]
        if pin != 0:
            vm = mom[r] / tab[r, T_NV]
            if anchor[i] != 0:
                vm = V(vm[0], vm[1], T(0.0))
            vi = vi - vm
            v[i] = vi
        x[i] = x[i] + vi * (T(0.5) * dt)

    @kern
    def increment(step: wp.array(dtype=wp.int32)):
        step[0] = step[0] + 1

    @kern
    def kinetic_kernel(v: wp.array(dtype=V), vrep: wp.array(dtype=wp.int32), tab: wp.array2d(dtype=T),
                       out: wp.array(dtype=wp.float64)):
        i = wp.tid()
        r = vrep[i]
        vi = v[i]
        wp.atomic_add(out, r, wp.float64(tab[r, T_MASS] * wp.dot(vi, vi)))

    return {k: v for k, v in locals().items() if isinstance(v, wp.Kernel)}


def _per_replica(value, R: int, name: str, allow_none: bool = False) -> np.ndarray | None:
    if value is None:
        if allow_none:
            return None
        raise ValueError(f"{name} must be given")
    a = np.atleast_1d(np.asarray(value, dtype=np.float64))
    if a.size == 1:
        a = np.full(R, float(a[0]))
    if a.shape != (R,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be a finite scalar or one value per replica ({R}), got shape {a.shape}")
    return a


class ImplicitShellSystem:
    """R implicit-solvent bubble shells advanced together (see the module docstring).

    Args:
        meshes: one :class:`ShellMesh` for every replica or a list of R meshes (stress-free references,
            DPD length, centred anywhere; coordinates are used as given).
        params: list of R :class:`ShellParams` (or one for all; DPD units).  Their ``p_back`` is ignored
            (the system's ``p_back`` applies) so the back pressure is never counted twice.
        gas_number: ideal-gas particle number N_g per replica (scalar or [R]); None -> ``p0 V0 / kbt``.
        p0: gas pressure at the reference volume (DPD pressure), used when ``gas_number`` is None.
        p_back: outward back pressure (DPD pressure, scalar or [R]).
        p_water: inward ambient pressure (DPD pressure, scalar or [R]); None -> p_back + p_gas(V0).
        kbt: thermal energy (DPD energy, scalar or [R]); 0 gives damped athermal dynamics.
        gamma: Langevin friction per vertex (DPD mass/time, scalar or [R]); None ->
            :func:`default_vertex_friction` of the first mesh.
        vertex_mass: DPD mass per vertex (scalar or [R]); None -> rho_shell h A / N_v (1100 kg/m^3).
        dt: time step (DPD time).  device: Warp device.  dtype: "float32" (default) or "float64".
        seed: base seed (int) or one seed per replica.
        pin_com: remove the mean force and the mean thermostat kick (centre of mass fixed).
        chunk: steps per captured CUDA graph.  use_graph: capture on CUDA (default True there).
        init_velocities: draw Maxwellian velocities at kbt (mean removed) at set-up.
    """

    def __init__(self, meshes: ShellMesh | Sequence[ShellMesh], params: ShellParams | Sequence[ShellParams], *,
                 gas_number=None, p0=GAS_P0_DEFAULT, p_back=P_BACK_DEFAULT, p_water=None, kbt=1.0, gamma=None,
                 vertex_mass=None, dt: float = 1e-4, device: str = "cpu", dtype="float32", seed=0,
                 pin_com: bool = True, chunk: int = 50, use_graph: bool | None = None,
                 init_velocities: bool = True):
        from bubblecal.sim.engine.system import resolve_dtype

        wp.init()
        if isinstance(params, ShellParams):
            params = [params] * (len(meshes) if isinstance(meshes, (list, tuple)) else 1)
        params = list(params)
        if not params:
            raise ValueError("params must hold at least one ShellParams")
        for p in params:
            if not isinstance(p, ShellParams):
                raise TypeError(f"params must hold ShellParams, got {type(p).__name__}")
        R = len(params)
        meshes = list(meshes) if isinstance(meshes, (list, tuple)) else [meshes] * R
        if len(meshes) != R:
            raise ValueError(f"{len(meshes)} meshes but {R} parameter sets")
        for m in meshes:
            if not isinstance(m, ShellMesh):
                raise TypeError(f"meshes must be ShellMesh, got {type(m).__name__}")
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive DPD time, got {dt!r}")
        self.R = R
        self.meshes = meshes
        self.params = [dataclasses.replace(p, p_back=0.0) for p in params]
        self.device = wp.get_device(device)
        self.dtype = resolve_dtype(dtype)
        self.np_dtype = np.float32 if self.dtype is wp.float32 else np.float64
        self.vec3 = wp.types.vector(3, self.dtype)
        self.dt = float(dt)
        self.pin_com = bool(pin_com)
        self.chunk = int(chunk)
        self._chunks = ChunkGraph(self._one_step, self.device,
                                  (self.device.is_cuda if use_graph is None else bool(use_graph)) and self.device.is_cuda)
        self._k = _kernels(self.dtype)

        nv = np.array([m.n_vertices for m in meshes], dtype=np.int64)
        self.n_vertices = nv
        self.offsets = np.concatenate([[0], np.cumsum(nv)[:-1]]).astype(np.int64)
        self.N = int(nv.sum())
        self.uniform = bool(np.all(nv == nv[0]))
        self.volume0 = np.array([m.volume() for m in meshes])
        self.area0 = np.array([m.area() for m in meshes])
        self.radius0 = np.sqrt(self.area0 / (4 * math.pi))

        kbt_a = _per_replica(kbt, R, "kbt")
        if np.any(kbt_a < 0):
            raise ValueError("kbt must be >= 0")
        if gas_number is None:
            p0_a = _per_replica(p0, R, "p0")
            if np.any(p0_a < 0):
                raise ValueError("p0 must be >= 0 (DPD pressure)")
            nkt = p0_a * self.volume0
            self.gas_number = np.where(kbt_a > 0, nkt / np.where(kbt_a > 0, kbt_a, 1.0), np.nan)
        else:
            self.gas_number = _per_replica(gas_number, R, "gas_number")
            if np.any(self.gas_number < 0):
                raise ValueError("gas_number must be >= 0")
            nkt = self.gas_number * kbt_a
        pb = _per_replica(p_back, R, "p_back")
        pw = pb + nkt / self.volume0 if p_water is None else _per_replica(p_water, R, "p_water")
        self.p_back, self.p_water, self.kbt, self.nkt = pb, pw, kbt_a, nkt
        g = (_per_replica(default_vertex_friction(meshes[0]), R, "gamma") if gamma is None
             else _per_replica(gamma, R, "gamma"))
        if np.any(g < 0):
            raise ValueError("gamma must be >= 0 (DPD mass / time)")
        self.gamma = g
        mv = (np.array([m.vertex_mass() for m in meshes]) if vertex_mass is None
              else _per_replica(vertex_mass, R, "vertex_mass"))
        if np.any(mv <= 0):
            raise ValueError("vertex_mass must be > 0")
        self.vertex_mass = mv
        seeds = (np.asarray(seed, dtype=np.int64).reshape(-1) if np.ndim(seed) else
                 np.asarray([int(seed) * 7919 + r for r in range(R)], dtype=np.int64))
        if seeds.shape != (R,):
            raise ValueError(f"seed must be an int or one int per replica ({R})")
        self.seed_values = seeds
        hashed = np.array([np.random.SeedSequence([int(s) % (2**63), r]).generate_state(1)[0] % (2**30)
                           for r, s in enumerate(seeds)], dtype=np.int32)

        dev, npf = self.device, self.np_dtype
        self.field = ShellForceField(meshes, self.params, device=dev, dtype=self.dtype)
        tab = np.zeros((R, N_TAB))
        tab[:, T_NKT] = nkt
        tab[:, T_PEXT] = pw - pb
        tab[:, T_KBT] = kbt_a
        tab[:, T_GAMMA] = g
        tab[:, T_MASS] = mv
        tab[:, T_NV] = nv
        self._tab_np = tab
        self.tab = wp.array(tab.astype(npf), dtype=self.dtype, device=dev)
        self.seeds = wp.array(hashed, dtype=wp.int32, device=dev)
        self.step_counter = wp.zeros(1, dtype=wp.int32, device=dev)
        self.status = wp.zeros(R, dtype=wp.int32, device=dev)
        x0 = np.concatenate([m.vertices for m in meshes]).astype(npf)
        self.x_ref = np.concatenate([m.vertices for m in meshes]).astype(np.float64)
        self.x = wp.array(x0, dtype=self.vec3, device=dev)
        self.vrep_np = np.repeat(np.arange(R), nv).astype(np.int32)
        self.vrep = wp.array(self.vrep_np, dtype=wp.int32, device=dev)
        self.local = wp.array(np.concatenate([np.arange(n) for n in nv]).astype(np.int32), dtype=wp.int32,
                              device=dev)
        self.tri = wp.array(np.concatenate([m.faces + o for m, o in zip(meshes, self.offsets, strict=True)])
                            .astype(np.int32), dtype=wp.vec3i, device=dev)
        self.tri_rep = wp.array(np.repeat(np.arange(R), [m.n_faces for m in meshes]).astype(np.int32),
                                dtype=wp.int32, device=dev)
        self.n_tri = int(self.tri.shape[0])
        self.goff = wp.array(self.offsets.astype(np.int32), dtype=wp.int32, device=dev)
        self.f = wp.zeros(self.N, dtype=self.vec3, device=dev)
        self.fext = wp.zeros(self.N, dtype=self.vec3, device=dev)
        self.fstore = wp.zeros(self.N, dtype=self.vec3, device=dev)
        self.vol = wp.zeros(R, dtype=self.dtype, device=dev)
        self.fsum = wp.zeros(R, dtype=self.vec3, device=dev)
        self.mom = wp.zeros(R, dtype=self.vec3, device=dev)
        self.anchor_np = np.zeros(self.N, dtype=np.int32)
        self.anchor = wp.zeros(self.N, dtype=wp.int32, device=dev)
        rng = np.random.default_rng(np.random.SeedSequence([int(s) % (2**63) for s in seeds]))
        v0 = np.zeros((self.N, 3))
        if init_velocities:
            v0 = rng.normal(size=(self.N, 3)) * np.sqrt(np.repeat(kbt_a / mv, nv))[:, None]
        if self.pin_com:
            v0 = self._remove_means(v0)
        self.v = wp.array(v0.astype(npf), dtype=self.vec3, device=dev)
        self.force_callbacks: list[Callable[[ImplicitShellSystem], None]] = []
        self.steps_done = 0
        self._need_forces = True

    # ------------------------------------------------------------------------------------------
    def _remove_means(self, v: np.ndarray) -> np.ndarray:
        out = v.copy()
        for r in range(self.R):
            o, n = int(self.offsets[r]), int(self.n_vertices[r])
            out[o:o + n] -= out[o:o + n].mean(axis=0)
        return out

    def _rows(self, r: int) -> slice:
        o = int(self.offsets[r])
        return slice(o, o + int(self.n_vertices[r]))

    def _to_packed(self, a, name: str) -> np.ndarray:
        a = np.asarray(a, dtype=np.float64)
        if a.shape == (self.N, 3):
            return a
        if self.uniform and a.shape == (self.R, int(self.n_vertices[0]), 3):
            return a.reshape(-1, 3)
        raise ValueError(f"{name} must have shape [R, Nv, 3] or [sum Nv, 3], got {a.shape}")

    def _unpack(self, a: np.ndarray):
        if self.uniform:
            return a.reshape(self.R, int(self.n_vertices[0]), -1) if a.ndim == 2 else a.reshape(self.R, -1)
        return [a[self._rows(r)] for r in range(self.R)]

    # ------------------------------------------------------------------------------------------
    # configuration
    # ------------------------------------------------------------------------------------------
    def set_external_forces(self, forces) -> None:
        """Constant external forces on the vertices, [R, Nv, 3] or [sum Nv, 3] (DPD force); None = 0."""
        if forces is None:
            self.fext.zero_()
        else:
            self.fext.assign(self._to_packed(forces, "forces").astype(self.np_dtype))
        self._need_forces = True

    def add_force_callback(self, cb: Callable[["ImplicitShellSystem"], None]) -> None:
        """``cb(system)`` adds forces into ``system.f`` (a wp.array of vec3, packed rows) after the
        internal forces every step; it must only launch kernels (CUDA-graph capture)."""
        self.force_callbacks.append(cb)
        self._chunks.invalidate()
        self._need_forces = True

    def set_anchor_z(self, mask) -> None:
        """Hold the z velocity (and force) of the masked vertices at 0: mask [R, Nv] / [sum Nv] / [Nv]
        (the same for every replica) of bool."""
        m = np.asarray(mask, dtype=bool)
        if m.shape == (self.N,):
            flat = m
        elif self.uniform and m.shape == (int(self.n_vertices[0]),):
            flat = np.tile(m, self.R)
        elif self.uniform and m.shape == (self.R, int(self.n_vertices[0])):
            flat = m.reshape(-1)
        else:
            raise ValueError(f"anchor mask must have shape [Nv], [R, Nv] or [sum Nv], got {m.shape}")
        self.anchor_np = flat.astype(np.int32)
        self.anchor.assign(self.anchor_np)
        v = self.v.numpy().astype(np.float64)
        v[flat, 2] = 0.0
        self.v.assign(v.astype(self.np_dtype))
        self._need_forces = True

    def set_vertices(self, x) -> None:
        """Replace the vertex positions ([R, Nv, 3] or packed; DPD length)."""
        self.x.assign(self._to_packed(x, "x").astype(self.np_dtype))
        self._need_forces = True

    def set_velocities(self, v) -> None:
        """Replace the vertex velocities ([R, Nv, 3] or packed; DPD velocity; means removed if pinned)."""
        vv = self._to_packed(v, "v")
        if self.pin_com:
            vv = self._remove_means(vv)
        self.v.assign(vv.astype(self.np_dtype))

    def freeze(self, replicas, code: int = int(Status.NAN)) -> None:
        """Mark replicas as failed with a :class:`Status` code (they stop moving)."""
        st = self.status.numpy().copy()
        for r in np.atleast_1d(replicas):
            if st[int(r)] == 0:
                st[int(r)] = int(code)
        self.status.assign(st)

    # ------------------------------------------------------------------------------------------
    # dynamics
    # ------------------------------------------------------------------------------------------
    def compute_forces(self) -> None:
        """Internal + external forces into ``self.f`` (no integration)."""
        k, dev = self._k, self.device
        self.f.zero_()
        self.field.accumulate_forces(self.x, self.f)
        self.vol.zero_()
        wp.launch(k["volume_kernel"], dim=self.n_tri, inputs=[self.x, self.tri, self.tri_rep, self.goff, self.vol],
                  device=dev)
        wp.launch(k["pressure_kernel"], dim=self.n_tri,
                  inputs=[self.x, self.f, self.tri, self.tri_rep, self.tab, self.vol, self.status], device=dev)
        for cb in self.force_callbacks:
            cb(self)

    def _finish(self) -> None:
        k, dev = self._k, self.device
        pin = int(self.pin_com)
        if pin:
            self.fsum.zero_()
            wp.launch(k["force_sum_kernel"], dim=self.N, inputs=[self.f, self.fext, self.vrep, self.fsum], device=dev)
        wp.launch(k["finish_kick"], dim=self.N,
                  inputs=[self.v, self.f, self.fext, self.fstore, self.vrep, self.anchor, self.tab, self.fsum, pin,
                          self.status, self.dtype(self.dt)], device=dev)

    @property
    def use_graph(self) -> bool:
        """Whether full chunks replay as CUDA graphs (False on the CPU or after a failed capture)."""
        return self._chunks.enabled

    def _one_step(self) -> None:
        k, dev = self._k, self.device
        pin = int(self.pin_com)
        dt = self.dtype(self.dt)
        self.mom.zero_()
        wp.launch(k["kick_drift_thermo"], dim=self.N,
                  inputs=[self.x, self.v, self.fstore, self.vrep, self.anchor, self.tab, self.seeds,
                          self.step_counter, self.mom, pin, self.status, dt, self.local], device=dev)
        wp.launch(k["drift_half"], dim=self.N,
                  inputs=[self.x, self.v, self.vrep, self.anchor, self.tab, self.mom, pin, self.status, dt],
                  device=dev)
        self.compute_forces()
        self._finish()
        wp.launch(k["increment"], dim=1, inputs=[self.step_counter], device=dev)

    def _prime(self) -> None:
        """Forces at the current positions into ``fstore`` (the first half kick of the next step uses
        them); the velocities are not changed."""
        self.compute_forces()
        v = wp.clone(self.v)
        self._finish()
        wp.copy(self.v, v)
        self._need_forces = False

    def step(self, n: int = 1) -> None:
        """Advance every live replica by ``n`` BAOAB steps of ``dt``."""
        n = int(n)
        if n < 0:
            raise ValueError("n must be >= 0")
        if self._need_forces:
            self._prime()
            self._chunks.invalidate()
        done = 0
        while done < n:
            k = min(self.chunk, n - done)
            self._chunks.run(k, capture=k == self.chunk)
            done += k
        self.steps_done += n

    @property
    def time(self) -> float:
        """Simulated time (DPD time units)."""
        return self.steps_done * self.dt

    # ------------------------------------------------------------------------------------------
    # measurements (synchronise; float64 on the host)
    # ------------------------------------------------------------------------------------------
    def vertices(self):
        """Vertex positions [R, Nv, 3] (a list of [Nv_r, 3] if the meshes differ), DPD length."""
        return self._unpack(self.x.numpy().astype(np.float64))

    def velocities(self):
        """Vertex velocities [R, Nv, 3] (or a list), DPD velocity."""
        return self._unpack(self.v.numpy().astype(np.float64))

    def volumes(self) -> np.ndarray:
        """Enclosed volume per replica [R] (DPD length^3)."""
        self.vol.zero_()
        wp.launch(self._k["volume_kernel"], dim=self.n_tri, inputs=[self.x, self.tri, self.tri_rep, self.goff,
                                                                       self.vol], device=self.device)
        return self.vol.numpy().astype(np.float64)

    def areas(self) -> np.ndarray:
        """Total shell area per replica [R] (DPD length^2)."""
        return self.field.areas_volumes(self.x)[0]

    def gas_pressure(self) -> np.ndarray:
        """Ideal-gas pressure N_g k_BT / V per replica [R] (DPD pressure)."""
        return self.nkt / self.volumes()

    def centers(self) -> np.ndarray:
        """Vertex centroid per replica [R, 3]."""
        x = self.x.numpy().astype(np.float64)
        return np.stack([x[self._rows(r)].mean(axis=0) for r in range(self.R)])

    def kinetic_temperature(self) -> np.ndarray:
        """sum m v^2 / n_dof per replica [R]; n_dof = 3 N_v - (3 if pinned) - (anchored vertices)."""
        out = wp.zeros(self.R, dtype=wp.float64, device=self.device)
        wp.launch(self._k["kinetic_kernel"], dim=self.N, inputs=[self.v, self.vrep, self.tab, out], device=self.device)
        nanch = np.bincount(self.vrep_np, weights=self.anchor_np, minlength=self.R)
        dof = 3 * self.n_vertices - (3 if self.pin_com else 0) - nanch
        return out.numpy() / dof

    def energies(self) -> np.ndarray:
        """Shell energy per replica and term [R, 6] (columns of :data:`bubblecal.sim.engine.kernels.shell.ENERGY_TERMS`;
        the back-pressure column is 0 here: pressures are the system's)."""
        return self.field.energies(self.x)

    def status_names(self) -> list[str]:
        """Per-replica :class:`Status` names ('OK', 'NAN', 'RUPTURE', ...)."""
        return [Status(int(s)).name for s in self.status.numpy()]

    def check_health(self, thresholds: HealthThresholds | None = None) -> dict:
        """Check every live replica, freeze failures; returns per-replica indicators and status names."""
        th = thresholds or HealthThresholds()
        x = self.x.numpy().astype(np.float64)
        st = self.status.numpy().copy()
        finite = np.array([np.all(np.isfinite(x[self._rows(r)])) for r in range(self.R)])
        h = self.field.health(self.x)
        radius = np.full(self.R, np.nan)
        for r in range(self.R):
            if finite[r]:
                xr = x[self._rows(r)]
                radius[r] = np.max(np.linalg.norm(xr - xr.mean(axis=0), axis=1)) / self.radius0[r]
        for r in range(self.R):
            if st[r] != 0:
                continue
            if not finite[r] or not np.isfinite(h["max_area_strain"][r]):
                st[r] = Status.NAN
            elif h["max_area_strain"][r] > th.rupture_strain:
                st[r] = Status.RUPTURE
            elif h["min_area_ratio"][r] < th.min_area_ratio or h["max_dihedral_change"][r] > th.max_dihedral_change:
                st[r] = Status.INVERSION
            elif radius[r] > th.max_radius_factor:
                st[r] = Status.ESCAPE
        self.status.assign(st.astype(np.int32))
        return {"status": [Status(int(s)).name for s in st], "max_area_strain": h["max_area_strain"],
                "min_area_ratio": h["min_area_ratio"], "max_dihedral_change": h["max_dihedral_change"],
                "max_radius_ratio": radius}

    def memory_bytes(self) -> int:
        """Device bytes held by the system and its shell field."""
        total = 0
        for obj in (self, self.field):
            for val in vars(obj).values():
                if isinstance(val, wp.array):
                    total += val.capacity
        return int(total)

    def settings(self) -> dict:
        """The physical choices of this system (per replica where they vary), JSON-friendly."""
        return {"gas_number": self.gas_number.tolist(), "p_back": self.p_back.tolist(),
                "p_water": self.p_water.tolist(), "kbt": self.kbt.tolist(), "gamma": self.gamma.tolist(),
                "vertex_mass": self.vertex_mass.tolist(), "dt": self.dt, "pin_com": self.pin_com,
                "thermostat": "Langevin (BAOAB) on vertices", "n_vertices": self.n_vertices.tolist()}
