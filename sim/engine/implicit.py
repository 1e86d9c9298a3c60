"""Implicit-solvent shell system: R bubble shells without solvent particles, batched in the same launches.

Each replica is a shell (the :class:`~bubblecal.sim.engine.kernels.shell.ShellForceField` of the explicit
engine) whose enclosed gas and surrounding water are replaced by pressures on the enclosed volume V
(docs/physics.md section 7, "implicit" tier): an ideal gas p_gas = N_g k_BT / V inside, a constant back
pressure ``p_back`` outward and a constant ambient pressure ``p_water`` inward, by default ``p_back + p_gas(V0)``
so that the stress-free reference is force-free at T = 0.  The net outward force on vertex v is
(p_gas - p_water + p_back) dV/dx_v; only the gas bulk modulus (p0) adds stiffness (the comparison with the
explicit water: benchmarks/RESULTS.md).

Thermostat: Langevin on every vertex, integrated with BAOAB (one force evaluation per step; the O step is the
exact Ornstein-Uhlenbeck update v <- c1 v + sqrt((1 - c1^2) k_BT/m) xi, c1 = exp(-gamma dt / m)); why
Langevin: docs/decisions.md.  With ``pin_com`` the mean vertex force is removed every step and the mean
velocity after the thermostat kick, so the centre of mass does not move (to round-off).

All replicas' vertices live in one packed array ``x`` [sum N_v] (replica r at rows
``offsets[r]:offsets[r] + n_vertices[r]``); one step is ~8 launches for all R replicas, and on CUDA ``chunk``
steps are captured once as a CUDA graph.  Kernels: :mod:`bubblecal.sim.engine.kernels.implicit`; settings:
:mod:`bubblecal.sim.engine.implicit_settings`; measurements and health checks:
:mod:`bubblecal.sim.engine.implicit_observables`.  Units: DPD (length r_c = 250 nm, energy k_BT).
"""

import dataclasses
import math
from collections.abc import Callable, Sequence

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.engine.graphs import ChunkGraph
from bubblecal.sim.engine.implicit_observables import ImplicitObservables
from bubblecal.sim.engine.implicit_settings import GAS_P0_DEFAULT, implicit_settings
from bubblecal.sim.engine.kernels.implicit import (
    N_TAB,
    T_GAMMA,
    T_KBT,
    T_MASS,
    T_NKT,
    T_NV,
    T_PEXT,
    implicit_kernels,
)
from bubblecal.sim.engine.kernels.shell import ShellForceField, ShellParams
from bubblecal.sim.engine.mesh import ShellMesh
from bubblecal.sim.engine.particles import P_BACK_DEFAULT
from bubblecal.sim.engine.system import resolve_dtype

wp = require("warp", "sim")

__all__ = ["ImplicitShellSystem"]


class ImplicitShellSystem(ImplicitObservables):
    """R implicit-solvent bubble shells advanced together (see the module docstring).

    Parameters
    ----------
    meshes : ShellMesh or sequence of ShellMesh
        One mesh for every replica or a list of R meshes (stress-free references, DPD length, centred
        anywhere; coordinates are used as given).
    params : ShellParams or sequence of ShellParams
        R parameter sets (or one for all; DPD units).  Their ``p_back`` is ignored (the system's ``p_back``
        applies) so the back pressure is never counted twice.
    gas_number : float or array_like, optional
        Ideal-gas particle number N_g per replica (scalar or [R]); None -> ``p0 V0 / kbt``.
    p0 : float or array_like, optional
        Gas pressure at the reference volume (DPD pressure), used when ``gas_number`` is None.
    p_back : float or array_like, optional
        Outward back pressure (DPD pressure, scalar or [R]).
    p_water : float or array_like, optional
        Inward ambient pressure (DPD pressure, scalar or [R]); None -> p_back + p_gas(V0).
    kbt : float or array_like, optional
        Thermal energy (k_BT units, scalar or [R]); 0 gives damped athermal dynamics.
    gamma : float or array_like, optional
        Langevin friction per vertex (DPD mass / time, scalar or [R]); None ->
        :func:`~bubblecal.sim.engine.implicit_settings.default_vertex_friction` of the first mesh.
    vertex_mass : float or array_like, optional
        DPD mass per vertex (scalar or [R]); None -> rho_shell h A / N_v (1100 kg/m^3).
    dt : float, optional
        Time step (DPD time).
    device : str, optional
        Warp device.
    dtype : str, optional
        ``"float32"`` (default) or ``"float64"``.
    seed : int or array_like, optional
        Base seed, or one seed per replica.
    pin_com : bool, optional
        Remove the mean force and the mean thermostat kick (centre of mass fixed).
    chunk : int, optional
        Steps per captured CUDA graph.
    use_graph : bool, optional
        Capture on CUDA (default True there).
    init_velocities : bool, optional
        Draw Maxwellian velocities at kbt (mean removed) at set-up.

    Raises
    ------
    ValueError
        On empty or mismatched meshes / parameters, a non-positive ``dt``, or negative or non-finite
        per-replica values.
    TypeError
        When ``meshes`` or ``params`` hold other types.
    """

    def __init__(self, meshes: ShellMesh | Sequence[ShellMesh], params: ShellParams | Sequence[ShellParams], *,
                 gas_number=None, p0=GAS_P0_DEFAULT, p_back=P_BACK_DEFAULT, p_water=None, kbt=1.0, gamma=None,
                 vertex_mass=None, dt: float = 1e-4, device: str = "cpu", dtype="float32", seed=0,
                 pin_com: bool = True, chunk: int = 50, use_graph: bool | None = None,
                 init_velocities: bool = True):
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
        graphs = self.device.is_cuda if use_graph is None else bool(use_graph)
        self._chunks = ChunkGraph(self._one_step, self.device, graphs and self.device.is_cuda)
        self._k = implicit_kernels(self.dtype)

        nv = np.array([m.n_vertices for m in meshes], dtype=np.int64)
        self.n_vertices = nv
        self.offsets = np.concatenate([[0], np.cumsum(nv)[:-1]]).astype(np.int64)
        self.N = int(nv.sum())
        self.uniform = bool(np.all(nv == nv[0]))
        self.volume0 = np.array([m.volume() for m in meshes])
        self.area0 = np.array([m.area() for m in meshes])
        self.radius0 = np.sqrt(self.area0 / (4 * math.pi))

        st = implicit_settings(meshes, self.volume0, gas_number=gas_number, p0=p0, p_back=p_back, p_water=p_water,
                               kbt=kbt, gamma=gamma, vertex_mass=vertex_mass, seed=seed)
        self.gas_number = st.gas_number
        self.p_back, self.p_water, self.kbt, self.nkt = st.p_back, st.p_water, st.kbt, st.nkt
        self.gamma = st.gamma
        self.vertex_mass = st.vertex_mass
        self.seed_values = st.seeds
        kbt_a, nkt, pb, pw, g, mv, seeds = st.kbt, st.nkt, st.p_back, st.p_water, st.gamma, st.vertex_mass, st.seeds

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
        self.seeds = wp.array(st.hashed_seeds, dtype=wp.int32, device=dev)
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
    # ------------------------------------------------------------------------------------------
    # configuration
    # ------------------------------------------------------------------------------------------
    def set_external_forces(self, forces) -> None:
        """Set constant external forces on the vertices.

        Parameters
        ----------
        forces : array_like or None
            [R, Nv, 3] or [sum Nv, 3] (DPD force); None = 0.

        Raises
        ------
        ValueError
            On a wrong shape.
        """
        if forces is None:
            self.fext.zero_()
        else:
            self.fext.assign(self._to_packed(forces, "forces").astype(self.np_dtype))
        self._need_forces = True

    def add_force_callback(self, cb: Callable[["ImplicitShellSystem"], None]) -> None:
        """Register ``cb(system)``, which adds forces into ``system.f`` after the internal forces every step.

        Parameters
        ----------
        cb : callable
            Adds DPD forces into ``system.f`` (a wp.array of vec3, packed rows); it must only launch kernels,
            so that CUDA-graph capture keeps working.
        """
        self.force_callbacks.append(cb)
        self._chunks.invalidate()
        self._need_forces = True

    def set_anchor_z(self, mask) -> None:
        """Hold the z velocity (and force) of the masked vertices at 0.

        Parameters
        ----------
        mask : array_like of bool
            [R, Nv], [sum Nv], or [Nv] (the same for every replica).

        Raises
        ------
        ValueError
            On a wrong shape.
        """
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
        """Replace the vertex positions.

        Parameters
        ----------
        x : array_like
            [R, Nv, 3] or packed [sum Nv, 3] (DPD length).

        Raises
        ------
        ValueError
            On a wrong shape.
        """
        self.x.assign(self._to_packed(x, "x").astype(self.np_dtype))
        self._need_forces = True

    def set_velocities(self, v) -> None:
        """Replace the vertex velocities (the replica means are removed when the centre of mass is pinned).

        Parameters
        ----------
        v : array_like
            [R, Nv, 3] or packed [sum Nv, 3] (DPD velocity).

        Raises
        ------
        ValueError
            On a wrong shape.
        """
        vv = self._to_packed(v, "v")
        if self.pin_com:
            vv = self._remove_means(vv)
        self.v.assign(vv.astype(self.np_dtype))

    # ------------------------------------------------------------------------------------------
    # dynamics
    # ------------------------------------------------------------------------------------------
    def compute_forces(self) -> None:
        """Shell, pressure and callback forces into ``self.f`` (DPD force; launches only, no integration)."""
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
        """Second half kick with the current forces (mean force removed when pinned)."""
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
        """One BAOAB step (the unit a chunk repeats)."""
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
        """Advance every live replica by ``n`` BAOAB steps of ``dt``.

        Parameters
        ----------
        n : int, optional
            Number of steps (>= 0).

        Raises
        ------
        ValueError
            When ``n`` < 0.
        """
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
