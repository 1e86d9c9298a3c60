"""Athermal quasi-static fidelity tier for the two mechanical loading protocols (physics.md sections 5, 7).

At every load point the shell (+ enclosed ideal gas) is relaxed to a force-balanced state with FIRE;
load points are chained (each starts from the previous minimum).  R replicas (one :class:`ShellParams`
each, same mesh) are batched into one :class:`ShellForceField` and minimised together, each with its
own FIRE state.  No solvent, no temperature: this is the cheap tier that must be validated against
the explicit one.

Minimiser (``minimizer=``): ``"device"`` (default, every device incl. the CPU) runs
:class:`bubblecal.sim.engine.minimize_device.DeviceFire` -- positions, velocities, forces and the FIRE state
stay on the Warp device; shell (ShellForceField kernels), gas, pole loads / plates, COM removal and
the observables are kernels (:mod:`bubblecal.sim.engine.kernels.qs_loading`); the host reads R status flags
every ``sync_every`` iterations (CUDA: those iterations replay as one CUDA graph).  ``"numpy"`` is the
reference implementation (:func:`bubblecal.sim.engine.minimize.fire_minimize`, one host round trip per
force evaluation); both follow the same FIRE rules and give the same curves (float64: equal to
round-off on the CPU; tests/sim/test_minimize_device.py).  ``dtype=wp.float32`` is offered for GPU
throughput (curves within ~1e-3 relative of float64, see benchmarks/RESULTS.md).

Choices (stated once; also returned in ``result.settings``):

* **Gas** (:class:`IdealGas`): isothermal ideal gas p V = p0 V0 inside; default p0 = 3 DPD pressure
  (ideal gas at number density 3, k_BT = 1 -- as in the Reissner check of :mod:`bubblecal.sim.validation.checks`),
  balanced at the reference by a constant ambient pressure p_ambient (default = p0), so the
  stress-free sphere is force-free.  In the explicit model the water pressure (~89) is balanced by
  gas + back pressure p_b = 91; a *constant* pressure adds no stiffness, so only p0 (the gas bulk
  modulus) matters here.  ``gas=None`` removes the gas (shell only).
* **Indentation**: k = max(1, floor(0.01 N_v)) top-most and bottom-most reference vertices (by z)
  carry -F/k and +F/k along z.  Centre of mass pinned: the mean force over each replica's vertices
  is subtracted (all three components).  Equator anchored in z: vertices with
  |z - z_c| < 0.25 l_min of the reference are not allowed to move in z.  Observable
  d(F) = H0 - H(F) with H = max z - min z of the shell (axial extent, "pole-to-pole distance");
  the distance between the loaded patches' mean z is returned as well (``d_patch``).
* **Compression**: analytic plates z = z_c +- (h0 + gap - d/2), h0 = max_v |z_v - z_c| of the
  reference, ``gap`` default 1 = the LJ range, so the plates just touch at d = 0 (zero force in this
  athermal tier; the published thermal curves have F(0) ~ 40-60).  Plate-vertex force: repulsive
  LJ (WCA) eps = 1000, sigma = 2^(-1/6), r_c = 2^(1/6) sigma = 1, on the distance h of a vertex to
  the plate; the force magnitude is capped at ``force_cap`` (default 1e4 DPD per vertex, reached at
  h ~ 0.91) and the energy continued linearly below (also behind the plate), so FIRE can recover a
  vertex that crossed.  Centre of mass pinned in x, y (mean x, y force removed).  Observable
  F(d) = force on ONE plate: the sum of plate-vertex forces on the top plate (positive = compressive);
  the bottom plate's is returned too (``force_bottom``; equal at equilibrium).  "Both plates"
  (sum) would be twice this -- keep it consistent with the data's convention.
* **Status per replica**: ``'ok'``; ``'not_converged'`` (FIRE hit ``max_steps`` at some point; the
  chain goes on, or ends there with ``FireSettings.stop_at_max_steps``); ``'nonfinite'``; ``'ruptured'`` (max triangle area strain |A/A0 - 1| above
  ``rupture_strain``, default 1.0).  After ``nonfinite`` / ``ruptured`` the replica is frozen and its
  later observables are NaN.  ``point_status[r][j]`` holds the per-point verdict.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from bubblecal.sim.engine import FORCE_MODES, ShellMesh, ShellParams, pole_patches
from bubblecal.sim.protocols.loading import validate_grid
from bubblecal.sim.tiers.thermal_contact import (
    ThermalContact,
    hard_wall_distance,
    psi_continuation,
    shell_fluctuation_sigma,
    thermal_plate_force,
)

__all__ = [
    "IdealGas",
    "PlateContact",
    "ThermalContact",
    "FireSettings",
    "IndentationResult",
    "CompressionResult",
    "quasistatic_indentation",
    "quasistatic_compression",
    "plate_force_energy",
    "STATUS_OK",
    "STATUS_NOT_CONVERGED",
    "STATUS_NONFINITE",
    "STATUS_RUPTURED",
]

STATUS_OK = "ok"
STATUS_NOT_CONVERGED = "not_converged"
STATUS_NONFINITE = "nonfinite"
STATUS_RUPTURED = "ruptured"
_FAILED = (STATUS_NONFINITE, STATUS_RUPTURED)


@dataclass(frozen=True)
class IdealGas:
    """Isothermal ideal gas inside the shell: p = p0 V0 / V (DPD pressure), ambient ``p_ambient`` outside.

    ``p_ambient`` None -> p0 (reference force-free).  Net outward pressure p - p_ambient acts on the
    shell as (p - p_ambient) dV/dx_v.
    """

    p0: float = 3.0
    p_ambient: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.p0) and self.p0 >= 0):
            raise ValueError(f"IdealGas.p0 must be a finite number >= 0, got {self.p0!r}")
        if self.p_ambient is not None and not math.isfinite(self.p_ambient):
            raise ValueError(f"IdealGas.p_ambient must be finite, got {self.p_ambient!r}")

    @property
    def ambient(self) -> float:
        return self.p0 if self.p_ambient is None else float(self.p_ambient)


@dataclass(frozen=True)
class PlateContact:
    """Capped repulsive LJ between an analytic plate and shell vertices (DPD units).

    ``epsilon`` (energy), ``sigma`` (length; cut-off 2^(1/6) sigma), ``force_cap`` (largest force
    magnitude per vertex), ``gap`` (plate offset beyond the reference extent at d = 0, length).
    """

    epsilon: float = 1000.0
    sigma: float = 2.0 ** (-1.0 / 6.0)
    force_cap: float = 1.0e4
    gap: float = 1.0

    def __post_init__(self) -> None:
        for name in ("epsilon", "sigma", "force_cap"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"PlateContact.{name} must be a positive finite number, got {v!r}")
        if not (math.isfinite(self.gap) and self.gap >= 0):
            raise ValueError(f"PlateContact.gap must be a finite number >= 0, got {self.gap!r}")

    @property
    def cutoff(self) -> float:
        return 2.0 ** (1.0 / 6.0) * self.sigma


@dataclass(frozen=True)
class FireSettings:
    """FIRE controls for every load point: ``ftol`` (absolute per-vertex force norm, DPD force),
    ``max_steps`` per point, ``dt`` / ``dt_max`` (DPD time, unit FIRE mass), ``max_move`` (length/step);
    ``n_delay``, ``f_inc``, ``f_dec``, ``alpha0``, ``f_alpha``: the FIRE 2.0 constants of
    :func:`bubblecal.sim.engine.minimize.fire_minimize` (dimensionless).
    ``stop_at_max_steps``: a replica whose FIRE reaches ``max_steps`` at a point ends its curve there
    ('not_converged', that point and the later ones NaN, the converged prefix kept) instead of going on to the
    last point; such curves are not trained on past their prefix, and they make most of a pool's tail.
    ``force_mode``: how the device backend evaluates the shell forces (:class:`ShellForceField` ``force_mode``:
    ``"auto"`` = per-vertex gather on a GPU, per-element scatter with atomics on the CPU); the same forces up to
    the summation order."""

    ftol: float = 0.05
    max_steps: int = 20_000
    dt: float = 5e-3
    dt_max: float = 5e-2
    max_move: float = 0.01
    stop_at_max_steps: bool = False
    n_delay: int = 5
    f_inc: float = 1.1
    f_dec: float = 0.5
    alpha0: float = 0.1
    f_alpha: float = 0.99
    force_mode: str = "auto"

    def __post_init__(self) -> None:
        if self.force_mode not in FORCE_MODES:
            raise ValueError(f"FireSettings.force_mode must be one of {FORCE_MODES}, got {self.force_mode!r}")

    def constants(self) -> dict:
        """Keyword arguments of the FIRE minimisers (time step, move cap and the FIRE 2.0 constants)."""
        return {"dt": self.dt, "dt_max": self.dt_max, "max_move": self.max_move, "n_delay": self.n_delay,
                "f_inc": self.f_inc, "f_dec": self.f_dec, "alpha0": self.alpha0, "f_alpha": self.f_alpha}


def plate_force_energy(h: np.ndarray, contact: PlateContact) -> tuple[np.ndarray, np.ndarray]:
    """Repulsive force magnitude (>= 0, pushing the vertex away from the plate) and energy for
    vertex-plate distances ``h`` (DPD length; h <= 0 = behind the plate).  Capped at
    ``contact.force_cap`` with the energy continued linearly."""
    h = np.asarray(h, dtype=np.float64)
    eps, sig, rc, cap = contact.epsilon, contact.sigma, contact.cutoff, contact.force_cap
    # distance where the LJ force reaches the cap (bisection on the monotone branch h < rc)
    h_cap = _cap_distance(eps, sig, cap)
    e_cap = _lj_energy(np.array([h_cap]), eps, sig)[0]
    f = np.zeros_like(h)
    e = np.zeros_like(h)
    near = (h < rc) & (h > h_cap)
    f[near] = _lj_force(h[near], eps, sig)
    e[near] = _lj_energy(h[near], eps, sig)
    capped = h <= h_cap
    f[capped] = cap
    e[capped] = e_cap + cap * (h_cap - h[capped])
    return f, e


def _lj_force(h, eps, sig):
    s6 = (sig / h) ** 6
    return 24.0 * eps * (2.0 * s6 * s6 - s6) / h


def _lj_energy(h, eps, sig):
    s6 = (sig / h) ** 6
    return 4.0 * eps * (s6 * s6 - s6) + eps


def _cap_distance(eps, sig, cap) -> float:
    lo, hi = 1e-3 * sig, 2.0 ** (1.0 / 6.0) * sig
    if _lj_force(lo, eps, sig) <= cap:
        return lo
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if _lj_force(mid, eps, sig) > cap:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


# ------------------------------------------------------------------------------------------------
# shared machinery
# ------------------------------------------------------------------------------------------------
MINIMIZERS = ("device", "numpy")


def _check_params(params, mesh: ShellMesh, gas: IdealGas | None) -> list[ShellParams]:
    if isinstance(params, ShellParams):
        params = [params]
    params = list(params)
    if not params:
        raise ValueError("params must hold at least one ShellParams")
    for p in params:
        if not isinstance(p, ShellParams):
            raise ValueError(f"params must hold ShellParams, got {type(p).__name__}")
    if not isinstance(mesh, ShellMesh):
        raise ValueError(f"mesh must be a ShellMesh, got {type(mesh).__name__}")
    if gas is not None and not isinstance(gas, IdealGas):
        raise ValueError(f"gas must be an IdealGas or None, got {type(gas).__name__}")
    return params


class _Batch:
    """R replicas of one mesh packed row-wise; shell + gas forces as NumPy (``minimizer='numpy'``)."""

    def __init__(self, params: Sequence[ShellParams], mesh: ShellMesh, gas: IdealGas | None, device: str,
                 dtype):
        import warp as wp

        from bubblecal.sim.engine.kernels.shell import ShellForceField

        params = _check_params(params, mesh, gas)
        wp.config.quiet = True
        wp.init()
        self.R = len(params)
        self.nv = mesh.n_vertices
        self.mesh = mesh
        self.gas = gas
        self.ff = ShellForceField(mesh, params, device=device, dtype=wp.float64 if dtype is None else dtype)
        self.x_ref = self.ff.reference_positions()
        self.groups = np.repeat(np.arange(self.R), self.nv)
        self.v0 = mesh.volume()
        f = mesh.faces
        self._faces = f

    def view(self, x: np.ndarray) -> np.ndarray:
        return x.reshape(self.R, self.nv, 3)

    def volumes(self, x: np.ndarray) -> np.ndarray:
        xr = self.view(x)
        f = self._faces
        return np.einsum("rij,rij->r", xr[:, f[:, 0]], np.cross(xr[:, f[:, 1]], xr[:, f[:, 2]])) / 6.0

    def volume_gradient(self, x: np.ndarray) -> np.ndarray:
        xr = self.view(x)
        f = self._faces
        n = np.cross(xr[:, f[:, 1]] - xr[:, f[:, 0]], xr[:, f[:, 2]] - xr[:, f[:, 0]]) / 6.0  # [R, Nt, 3]
        g = np.zeros_like(xr)
        for c in range(3):
            np.add.at(g, (slice(None), f[:, c]), n)
        return g.reshape(-1, 3)

    def shell_gas_forces(self, x: np.ndarray) -> np.ndarray:
        _, f = self.ff.energy_forces_numpy(x, with_energy=False)
        if self.gas is not None:
            vol = self.volumes(x)
            dp = self.gas.p0 * self.v0 / vol - self.gas.ambient  # [R]
            f = f + np.repeat(dp, self.nv)[:, None] * self.volume_gradient(x)
        return f

    def max_area_strain(self, x: np.ndarray) -> np.ndarray:
        import warp as wp

        xa = wp.array(np.ascontiguousarray(x), dtype=self.ff.vec3, device=self.ff.device)
        return self.ff.health(xa)["max_area_strain"]


class _HostChain:
    """Load-point backend with the NumPy FIRE (:func:`bubblecal.sim.engine.minimize.fire_minimize`): every force
    evaluation copies positions to the Warp device and forces back (the reference implementation)."""

    def __init__(self, batch: _Batch, make_energy_forces: Callable[[int, np.ndarray], Callable],
                 free: np.ndarray, fire: FireSettings, measure: Callable[[np.ndarray, int], dict]):
        self.b, self.make, self.free, self.fire, self.measure = batch, make_energy_forces, free, fire, measure
        self.R, self.nv = batch.R, batch.nv
        self.x = batch.x_ref.copy()
        self.xn = self.x
        self.n_evaluations = 0

    def minimize(self, j: int, alive: np.ndarray):
        from bubblecal.sim.engine.minimize import fire_minimize

        b, fire = self.b, self.fire
        groups = np.where(alive[b.groups], b.groups, -1)
        res = fire_minimize(self.make(j, alive), self.x, groups, n_groups=self.R, free=self.free, ftol=fire.ftol,
                            max_steps=fire.max_steps, **fire.constants())
        self.xn = res.x
        self.n_evaluations += res.n_evaluations
        return res.status, res.steps, res.fmax

    def point_state(self, j: int):
        b = self.b
        finite_rows = np.isfinite(b.view(self.xn)).all(axis=(1, 2))
        xs = np.where(np.repeat(finite_rows, b.nv)[:, None], self.xn, b.x_ref)
        return finite_rows, b.max_area_strain(xs), b.volumes(xs), self.measure(xs, j)

    def reset_failed(self, failed: np.ndarray) -> None:
        self.x = np.where(np.repeat(failed, self.nv)[:, None], self.b.x_ref, self.xn)

    def x_final(self) -> np.ndarray:
        return self.x


class _DeviceChain:
    """Load-point backend with the device-resident FIRE (:class:`bubblecal.sim.engine.minimize_device.DeviceFire`).

    Shell (ShellForceField kernels), gas, pole loads / plates, COM removal and the observables all run
    as Warp kernels on ``device``; per load point only R-sized arrays come back to the host.
    ``free_v [Nv, 3]`` (per mesh vertex), ``remove_mean`` (components), ``unit [Nv, 3]`` (pole-load
    direction per unit load, or None), ``tag [Nv]`` (1 top patch, -1 bottom patch, or None),
    ``contact`` (plates, or None).
    """

    def __init__(self, params, mesh: ShellMesh, gas: IdealGas | None, device: str, dtype, fire: FireSettings, *,
                 free_v: np.ndarray, remove_mean: tuple[bool, bool, bool], unit: np.ndarray | None = None,
                 tag: np.ndarray | None = None, contact: PlateContact | None = None,
                 thermal: ThermalContact | None = None, radius_dpd: float | None = None,
                 sync_every: int | None = None, use_graph: bool | None = None,
                 loads: np.ndarray | None = None):
        import warp as wp

        from bubblecal.sim.engine.kernels.qs_loading import qs_kernels
        from bubblecal.sim.engine.kernels.shell import ShellForceField
        from bubblecal.sim.engine.minimize_device import DeviceFire

        params = _check_params(params, mesh, gas)
        wp.config.quiet = True
        wp.init()
        self.wp = wp
        T = wp.float64 if dtype is None else dtype
        self.R, self.nv = R, nv = len(params), mesh.n_vertices
        self.ff = ShellForceField(mesh, params, device=device, dtype=T, force_mode=fire.force_mode)
        self.dtype, self.vec3, dev = T, self.ff.vec3, self.ff.device
        self.device = dev
        npf = np.float64 if T is wp.float64 else np.float32
        self._npf = npf
        self.k = qs_kernels(T)
        self.fire_settings = fire
        self.fire = DeviceFire(np.arange(R + 1) * nv, self._forces, device=dev, dtype=T,
                               free=np.tile(np.asarray(free_v, dtype=bool), (R, 1)), remove_mean=remove_mean,
                               **fire.constants(), sync_every=sync_every,
                               use_graph=use_graph)
        self.nthr = self.fire.nthr
        self.row_start = self.fire.row_start
        # finished replicas (FIRE status != ACTIVE) skip the shell kernels while the slowest ones relax
        self.ff.set_skip(self.fire.status)
        self.x_ref = wp.array(self.ff.reference_positions().astype(npf), dtype=self.vec3, device=dev)
        wp.copy(self.fire.x, self.x_ref)
        self.row_rep = wp.array(np.repeat(np.arange(R), nv).astype(np.int32), dtype=wp.int32, device=dev)
        faces = mesh.faces.astype(np.int64)
        self.tri = wp.array(faces.astype(np.int32), dtype=wp.vec3i, device=dev)
        self.gas_on = gas is not None
        v0 = mesh.volume()
        g = np.zeros((R, 2))
        if gas is not None:
            g[:] = (gas.p0 * v0, gas.ambient)
        self.gas = wp.array(g.astype(npf), dtype=T, device=dev)
        self.vol = wp.zeros(R, dtype=T, device=dev)
        self.vol_meas = wp.zeros(R, dtype=T, device=dev)
        if self.gas_on:  # the gas force rides on the shell's own triangle pass (ShellForceField.set_gas)
            self.ff.set_gas(self.gas, self.vol)
        self.load = wp.zeros(R, dtype=T, device=dev)
        u = np.zeros((nv, 3)) if unit is None else np.asarray(unit, dtype=np.float64)
        self.unit = wp.array(np.tile(u, (R, 1)).astype(npf), dtype=self.vec3, device=dev)
        loaded = np.nonzero(np.any(u != 0.0, axis=1))[0]  # the pole patches (none without a unit load)
        self.load_on = len(loaded) > 0
        self.loaded = wp.array(loaded.astype(np.int32) if len(loaded) else np.zeros(1, np.int32), dtype=wp.int32,
                               device=dev)
        tg = np.zeros(nv, dtype=np.int32) if tag is None else np.asarray(tag, dtype=np.int32)
        self.n_top = max(1, int(np.sum(tg == 1)))
        self.n_bottom = max(1, int(np.sum(tg == -1)))
        self.tag = wp.array(np.tile(tg, R), dtype=wp.int32, device=dev)
        self.plate_on = contact is not None
        self.plates = wp.zeros((R, 2), dtype=T, device=dev)
        c = contact if contact is not None else PlateContact()
        h_cap = _cap_distance(c.epsilon, c.sigma, c.force_cap)
        self.pc = [T(c.epsilon), T(c.sigma), T(c.cutoff), T(h_cap), T(c.force_cap)]
        # thermal contact: per-replica rms normal fluctuation, hard wall at the WCA's Barker-Henderson distance
        self.thermal = thermal if self.plate_on else None
        self._radius = float(mesh.radius_dpd) if radius_dpd is None else float(radius_dpd)
        self.tsig = wp.array(self._sigmas(params).astype(npf), dtype=T, device=dev)
        hw = hard_wall_distance(c, thermal.kT) if self.thermal is not None else 0.0
        p0, dp0 = psi_continuation()
        self.tc = [self.tsig, int(self.thermal is not None), T(hw),
                   T(thermal.kT if self.thermal is not None else 1.0), T(p0), T(dp0)]
        self.obs = wp.zeros((R, 4), dtype=T, device=dev)
        self.nonfin = wp.zeros(R, dtype=wp.int32, device=dev)
        self.flag = wp.zeros(R, dtype=wp.int32, device=dev)
        self.n_evaluations = 0
        # load values of the chain (plate displacement or pole force) for the linear start predictor
        self.loads = None if loads is None else np.asarray(loads, dtype=np.float64)
        self.x_prev = wp.clone(self.fire.x) if self.loads is not None else None

    # ----- forces (graph-capturable: all varying inputs live in device arrays) -----
    def _forces(self, x, f) -> None:
        wp, k, dev = self.wp, self.k, self.device
        if self.gas_on:  # the volume first: the shell pass adds the gas force (set_gas)
            self.vol.zero_()
            wp.launch(k["volume_kernel"], dim=self.R * self.nthr,
                      inputs=[x, self.tri, self.row_start, self.fire.status, 0, self.nthr, self.vol], device=dev)
        self.ff.accumulate_forces(x, f)
        if self.load_on:
            wp.launch(k["pole_load_kernel"], dim=self.R * self.loaded.shape[0],
                      inputs=[f, self.row_start, self.fire.status, self.loaded, self.load, self.unit], device=dev)
        if self.plate_on:
            wp.launch(k["plate_force_kernel"], dim=self.R * self.nthr,
                      inputs=[x, f, self.row_start, self.fire.status, self.nthr, self.plates, *self.pc, *self.tc],
                      device=dev)

    def _sigmas(self, params) -> np.ndarray:
        """rms normal fluctuation of each shell for the thermal contact (ones when athermal: unused)."""
        if self.thermal is None:
            return np.ones(len(params))
        if self.thermal.sigma is not None:
            return np.full(len(params), float(self.thermal.sigma))
        return shell_fluctuation_sigma(params, self._radius, self.thermal.kT)

    def set_load(self, value: float) -> None:
        """Pole load (total force per pole, DPD force) for every replica."""
        self.load.fill_(float(value))

    def set_plates(self, z_top: float, z_bottom: float) -> None:
        """Plate heights (DPD length) for every replica."""
        self.plates.assign(np.tile([z_top, z_bottom], (self.R, 1)).astype(self._npf))

    def set_load_rows(self, values: np.ndarray) -> None:
        """Pole load of each replica (``[R]``, total force per pole, DPD force)."""
        self.load.assign(np.asarray(values, dtype=np.float64).astype(self._npf))

    def set_plate_rows(self, z_top: np.ndarray, z_bottom: np.ndarray) -> None:
        """Plate heights of each replica (``[R]`` each, DPD length)."""
        self.plates.assign(np.stack([z_top, z_bottom], axis=1).astype(self._npf))

    # ----- chain backend -----
    def _predict_start(self, j: int, alive: np.ndarray) -> None:
        """Start point j from x_{j-1} + (x_{j-1} - x_{j-2}) (L_j - L_{j-1}) / (L_{j-1} - L_{j-2}): the loading
        path is smooth, so FIRE starts near the next minimum (fewer iterations, same minimum)."""
        L = self.loads
        c = 0.0
        if j >= 2 and L[j - 1] > L[j - 2]:
            c = (L[j] - L[j - 1]) / (L[j - 1] - L[j - 2])
        self.flag.assign(np.asarray(alive, dtype=np.int32) if c > 0 else np.zeros(self.R, dtype=np.int32))
        self.wp.launch(self.k["extrapolate_kernel"], dim=self.R * self.nv,
                       inputs=[self.fire.x, self.x_prev, self.row_rep, self.flag, self.dtype(c)], device=self.device)

    def minimize(self, j: int, alive: np.ndarray):
        fs = self.fire_settings
        if self.loads is not None:
            self._predict_start(j, alive)
        res = self.fire.minimize(ftol=fs.ftol, max_steps=fs.max_steps, active=alive)
        self.n_evaluations += res.n_evaluations
        return res.status, res.steps, res.fmax

    def point_state(self, j: int):
        wp, k, dev, x = self.wp, self.k, self.device, self.fire.x
        n = self.R * self.nv
        self.nonfin.zero_()
        wp.launch(k["nonfinite_kernel"], dim=n, inputs=[x, self.row_rep, self.nonfin], device=dev)
        finite_rows = self.nonfin.numpy() == 0
        eps = self.ff.health(x)["max_area_strain"]
        self.vol_meas.zero_()
        wp.launch(k["volume_kernel"], dim=self.R * self.nthr,
                  inputs=[x, self.tri, self.row_start, self.fire.status, 1, self.nthr, self.vol_meas], device=dev)
        vols = self.vol_meas.numpy().astype(np.float64)
        return finite_rows, eps, vols, self.measure(j)

    def measure(self, j: int) -> dict:
        wp, k, dev, x = self.wp, self.k, self.device, self.fire.x
        n = self.R * self.nv
        if self.plate_on:
            self.obs.zero_()
            wp.launch(k["plate_obs_kernel"], dim=n,
                      inputs=[x, self.row_rep, self.plates, *self.pc, *self.tc, self.obs], device=dev)
            o = self.obs.numpy().astype(np.float64)
            return {"top": o[:, 0].copy(), "bottom": o[:, 1].copy(), "contacts": o[:, 2].copy()}
        init = np.zeros((self.R, 4))
        init[:, 0], init[:, 1] = -1e30, 1e30
        self.obs.assign(init.astype(self._npf))
        wp.launch(k["axial_obs_kernel"], dim=n, inputs=[x, self.row_rep, self.tag, self.obs], device=dev)
        o = self.obs.numpy().astype(np.float64)
        return {"H": o[:, 0] - o[:, 1], "patch": o[:, 2] / self.n_top - o[:, 3] / self.n_bottom}

    # ----- replica-asynchronous chain backend -----
    def predictor_coefficients(self, j: np.ndarray) -> np.ndarray:
        """Linear-predictor coefficient of each replica's next point j[r] (0 = start from the last minimum)."""
        L = self.loads
        jj = np.asarray(j, dtype=np.int64)
        c = np.zeros(jj.shape)
        ok = (jj >= 2) & (jj < len(L))
        jo = jj[ok]
        den = L[jo - 1] - L[jo - 2]
        c[ok] = np.where(den > 0, (L[jo] - L[jo - 1]) / np.where(den > 0, den, 1.0), 0.0)
        return c

    def start_rows(self, j: np.ndarray, flags: np.ndarray) -> None:
        """(Re)start FIRE on the flagged replicas at their points ``j`` (loads already assigned), from the
        linear prediction of their last two minima when the chain extrapolates."""
        flags = np.asarray(flags, dtype=bool)
        if not flags.any():
            return
        if self.loads is not None:
            self.flag.assign(flags.astype(np.int32))
            coef = self.wp.array(self.predictor_coefficients(j).astype(self._npf), dtype=self.dtype,
                                 device=self.device)
            self.wp.launch(self.k["extrapolate_rows_kernel"], dim=self.R * self.nv,
                           inputs=[self.fire.x, self.x_prev, self.row_rep, self.flag, coef], device=self.device)
        self.fire.restart(flags)

    def load_samples(self, rows: np.ndarray, params: Sequence[ShellParams]) -> None:
        """Reuse replica slots ``rows`` for new samples: their shells get ``params`` and return to the
        stress-free reference (the caller then restarts them at load point 0 with :meth:`start_rows`)."""
        rows = np.asarray(rows, dtype=np.int64)
        if len(rows) == 0:
            return
        self.ff.set_params_rows(rows, list(params))
        if self.thermal is not None:
            sig = self.tsig.numpy()
            sig[rows] = self._sigmas(list(params))
            self.tsig.assign(sig)
        fl = np.zeros(self.R, dtype=bool)
        fl[rows] = True
        self.reset_failed(fl)

    def take_over(self, old: _DeviceChain, slots: np.ndarray) -> None:
        """Continue replicas ``slots`` of chain ``old`` here (this chain holds exactly their parameter sets,
        in that order): FIRE state, predictor history, loads and plates are copied, so their iterates go on
        unchanged."""
        slots = np.asarray(slots, dtype=np.int64)
        if len(slots) != self.R or old.nv != self.nv:
            raise ValueError(f"take_over: {len(slots)} slots of {old.nv}-vertex shells for {self.R} of {self.nv}")
        self.fire.import_rows(old.fire.export_rows(slots))
        rows = (slots[:, None] * old.nv + np.arange(old.nv)[None, :]).reshape(-1)
        if self.x_prev is not None and old.x_prev is not None:
            self.x_prev.assign(old.x_prev.numpy()[rows])
        self.load.assign(old.load.numpy()[slots])
        self.plates.assign(old.plates.numpy()[slots])
        self.tsig.assign(old.tsig.numpy()[slots])
        self.n_evaluations = old.n_evaluations

    def row_positions(self, r: int) -> np.ndarray:
        """Positions [Nv, 3] (float64, DPD length) of replica slot ``r``."""
        return self.fire.x[r * self.nv:(r + 1) * self.nv].numpy().astype(np.float64)

    def reset_failed(self, failed: np.ndarray) -> None:
        if not np.any(failed):
            return
        self.flag.assign(np.asarray(failed, dtype=np.int32))
        self.wp.launch(self.k["reset_rows_kernel"], dim=self.R * self.nv,
                       inputs=[self.fire.x, self.x_ref, self.row_rep, self.flag], device=self.device)

    def x_final(self) -> np.ndarray:
        return self.fire.positions()


def _result_tables(n: int, n_points: int):
    """Empty per-curve results of a chain of ``n`` curves: statuses, per-point statuses, FIRE steps, fmax, area
    strain, volume (NaN until measured) and the observables dict (filled per key as they come)."""
    return ([STATUS_OK] * n, [[STATUS_OK] * n_points for _ in range(n)], np.zeros((n, n_points), dtype=np.int64),
            np.full((n, n_points), np.nan), np.full((n, n_points), np.nan), np.full((n, n_points), np.nan),
            {})


def _run_chain(backend, n_points: int, rupture_strain: float, set_point: Callable[[int], None] | None = None,
               progress: Callable[[int, int, float], None] | None = None, stop_unstable: bool = False) -> dict:
    """Chain the load points on ``backend`` (:class:`_HostChain` / :class:`_DeviceChain`); returns
    per-replica/point arrays and statuses.  ``progress(j, n_points, seconds)`` after every point.
    ``stop_unstable``: a 'not_converged' point ends the replica's curve (:class:`FireSettings`)."""
    from bubblecal.sim.engine.minimize import STATUS_CONVERGED, STATUS_NONFINITE

    R = backend.R
    terminal = _terminal(stop_unstable)
    status, point_status, steps, fmax, strain, volume, obs = _result_tables(R, n_points)
    t0 = time.perf_counter()
    for j in range(n_points):
        alive = np.array([s not in terminal for s in status])
        if not alive.any():
            for r in range(R):
                point_status[r][j:] = [status[r]] * (n_points - j)
            break
        if set_point is not None:
            set_point(j)
        fstatus, fsteps, ffmax = backend.minimize(j, alive)
        finite_rows, eps, vols, m = backend.point_state(j)
        for r in range(R):
            if not alive[r]:
                point_status[r][j] = status[r]
                continue
            if fstatus[r] == STATUS_NONFINITE or not finite_rows[r]:
                ps = STATUS_NONFINITE
            elif eps[r] > rupture_strain:
                ps = STATUS_RUPTURED
            elif fstatus[r] != STATUS_CONVERGED:
                ps = STATUS_NOT_CONVERGED
            else:
                ps = STATUS_OK
            point_status[r][j] = ps
            if ps in terminal or status[r] == STATUS_OK:
                status[r] = ps if ps != STATUS_OK else status[r]
            steps[r, j] = fsteps[r]
            fmax[r, j] = ffmax[r]
            if ps in terminal:
                continue
            strain[r, j] = eps[r]
            volume[r, j] = vols[r]
            for k, v in m.items():
                obs.setdefault(k, np.full((R, n_points), np.nan))[r, j] = v[r]
        # failed replicas restart from (and stay frozen at) the reference so their rows stay finite
        backend.reset_failed(np.array([s in terminal for s in status]))
        if progress is not None:
            progress(j, n_points, time.perf_counter() - t0)
    return {"status": status, "point_status": point_status, "fire_steps": steps, "fmax": fmax,
            "max_area_strain": strain, "volume": volume, "obs": obs, "x": backend.x_final(),
            "fire_evaluations": int(backend.n_evaluations)}


def _terminal(stop_unstable: bool) -> tuple[str, ...]:
    """Point verdicts that end a replica's curve."""
    return _FAILED + ((STATUS_NOT_CONVERGED,) if stop_unstable else ())


def _classify(fire_code: int, finite: bool, eps: float, rupture_strain: float) -> str:
    """Point verdict of one replica from its FIRE status code, finiteness and max area strain."""
    from bubblecal.sim.engine.kernels.fire import CONVERGED, NONFINITE

    if fire_code == NONFINITE or not finite:
        return STATUS_NONFINITE
    if eps > rupture_strain:
        return STATUS_RUPTURED
    return STATUS_OK if fire_code == CONVERGED else STATUS_NOT_CONVERGED


def _run_chain_async(backend: _DeviceChain, n_points: int, rupture_strain: float,
                     assign: Callable[[np.ndarray], None],
                     progress: Callable[[int, int, float], None] | None = None,
                     batch_fraction: float = 0.05, samples: Sequence[ShellParams] | None = None,
                     compact: Callable[[_DeviceChain, np.ndarray, list], tuple] | None = None,
                     compact_below: float = 0.125, compact_min: int = 8,
                     on_finish: Callable[[int, dict], None] | None = None, stop_unstable: bool = False) -> dict:
    """Chain the load points with every replica at its own point (device FIRE only).

    A replica that stops (converged, ``max_steps`` or non-finite) is measured, then restarted at its next
    point while the others go on relaxing, so no replica waits for the batch's slowest one at every point
    (lock-step: the sum over points of the slowest replica's FIRE steps; here: the slowest replica's own
    sum).  Each replica follows exactly the FIRE iterates of the lock-step chain: same curves, same steps.
    Stopped replicas are measured in groups of at least ``batch_fraction`` of those still running (or
    when none is running) to keep host round trips rare.  ``assign(j)`` sets each slot's load (plate
    positions or pole force) of point ``j[r]``.

    ``samples`` (S >= R parameter sets, the first R already loaded in the backend's R slots): a slot whose
    sample has finished its curve takes the next pending sample (reference shape, point 0), so the batch
    runs at full occupancy until the pool is empty; the wall time then follows the pool's total FIRE
    work instead of its slowest sample.  Each sample's iterates are those it would have had in its own
    slot.  ``progress(k, S, seconds)`` then counts finished samples (k = samples finished - 1).
    ``compact(backend, slots, params) -> (new backend, new assign)``: once the pool is empty and at most
    ``compact_below`` of the slots (and more than ``compact_min`` slots in all) still relax, they move to a
    batch of their own size (an iteration of a big batch costs a fixed floor however few of its replicas
    relax; same iterates).  ``on_finish(s, row)``: called as soon as sample (or replica) ``s`` has
    finished its curve, with its ``status``, ``point_status``, ``fire_steps`` [P] and ``obs`` {name: [P]}
    (a campaign writes the record at once, so an interrupted batch keeps its finished curves).
    ``stop_unstable``: a 'not_converged' point ends the curve (its slot is free at once).
    Returns the dict of :func:`_run_chain`, rows = samples.
    """
    from bubblecal.sim.engine.kernels.fire import ACTIVE

    R = backend.R
    stream = samples is not None
    S = len(samples) if stream else R
    if S < R:
        raise ValueError(f"samples: {S} parameter sets for {R} slots")
    fs = backend.fire_settings
    terminal = _terminal(stop_unstable)
    status, point_status, steps, fmax, strain, volume, obs = _result_tables(S, n_points)
    x_out = np.zeros((S * backend.nv, 3)) if stream else None
    sample = np.arange(R)  # sample held by each slot
    next_sample = R
    n_finished = 0
    j = np.zeros(R, dtype=np.int64)
    done = np.zeros(R, dtype=bool)
    fire = backend.fire
    t0 = time.perf_counter()
    fire.begin(ftol=fs.ftol, max_steps=fs.max_steps)
    assign(j)
    backend.start_rows(j, ~done)
    reported = 0
    while not done.all():
        code = fire.advance()
        backend.n_evaluations += fire.sync_every
        waiting = (code != ACTIVE) & ~done
        n_wait, n_run = int(waiting.sum()), int((~done).sum())
        if n_wait == 0 or (n_wait < n_run and n_wait < max(1, math.ceil(batch_fraction * n_run))):
            continue
        fsteps, ffmax = fire.replica_report()
        finite_rows, eps, vols, m = backend.point_state(-1)
        failed = np.zeros(R, dtype=bool)
        for r in np.nonzero(waiting)[0]:
            jr, s_ = int(j[r]), int(sample[r])
            ps = _classify(int(code[r]), bool(finite_rows[r]), float(eps[r]), rupture_strain)
            point_status[s_][jr] = ps
            steps[s_, jr] = fsteps[r]
            fmax[s_, jr] = ffmax[r]
            if ps in terminal:
                status[s_] = ps
                point_status[s_][jr + 1:] = [ps] * (n_points - jr - 1)
                failed[r] = done[r] = True
                continue
            if ps != STATUS_OK and status[s_] == STATUS_OK:
                status[s_] = ps
            strain[s_, jr] = eps[r]
            volume[s_, jr] = vols[r]
            for key, v in m.items():
                obs.setdefault(key, np.full((S, n_points), np.nan))[s_, jr] = v[r]
            j[r] = jr + 1
            done[r] = j[r] >= n_points
        # failed replicas return to (and stay frozen at) the reference so their rows stay finite
        backend.reset_failed(failed)
        restart = waiting & ~done
        finished = np.nonzero(waiting & done)[0]
        if on_finish is not None:
            for r in finished:
                s_ = int(sample[r])
                on_finish(s_, {"status": status[s_], "point_status": list(point_status[s_]),
                               "fire_steps": steps[s_].copy(), "obs": {k: v[s_].copy() for k, v in obs.items()}})
        if stream:
            for r in finished:
                x_out[sample[r] * backend.nv:(sample[r] + 1) * backend.nv] = backend.row_positions(int(r))
            n_finished += len(finished)
            refill = finished[:max(0, S - next_sample)]
            if len(refill):
                new = np.arange(next_sample, next_sample + len(refill))
                next_sample += len(refill)
                backend.load_samples(refill, [samples[int(k)] for k in new])
                sample[refill], j[refill], done[refill] = new, 0, False
                restart[refill] = True
        assign(np.minimum(j, n_points - 1))
        backend.start_rows(j, restart)
        n_left = int((~done).sum())
        if (compact is not None and stream and next_sample >= S and 0 < n_left <= compact_below * R
                and R > compact_min):
            keep = np.nonzero(~done)[0]
            backend, assign = compact(backend, keep, [samples[int(k)] for k in sample[keep]])
            fire = backend.fire
            R = backend.R
            sample, j, done = sample[keep], j[keep], np.zeros(R, dtype=bool)
        if progress is not None and stream:
            for k in range(reported, n_finished):
                progress(k, S, time.perf_counter() - t0)
            reported = n_finished
        elif progress is not None:
            finished_pt = int(np.min(np.where(done, n_points, j)))
            for jj in range(reported, finished_pt):
                progress(jj, n_points, time.perf_counter() - t0)
            reported = max(reported, finished_pt)
    return {"status": status, "point_status": point_status, "fire_steps": steps, "fmax": fmax,
            "max_area_strain": strain, "volume": volume, "obs": obs,
            "x": x_out if stream else backend.x_final(), "fire_evaluations": int(backend.n_evaluations)}


def _refine_grid(grid: np.ndarray, max_step: float) -> tuple[np.ndarray, np.ndarray]:
    """Insert sub-steps so no load step exceeds ``max_step``; returns (refined grid, indices of ``grid``)."""
    pts, keep, prev = [], [], 0.0
    for g in grid:
        n = max(1, int(math.ceil((g - prev) / max_step - 1e-9)))
        pts.extend(prev + (g - prev) * (i + 1) / n for i in range(n))
        keep.append(len(pts) - 1)
        prev = g
    return np.asarray(pts), np.asarray(keep)


def _ramp_grid(grid: np.ndarray, n_ramp: int) -> tuple[np.ndarray, np.ndarray]:
    """Insert ``n_ramp`` geometric sub-points base + (F - base) / 2^k, k = n_ramp ... 1, before the first positive
    load F of ``grid`` (base = the load before it, or 0); returns (grid with sub-points, indices of ``grid``).
    Why: from the unloaded shape FIRE needs ~58 % of a curve's work for the first load point (3.2 um); reached
    through halvings, each start is the predictor's extrapolation (0.54x-0.75x of the FIRE work, 3.2-5.8 um)."""
    grid = np.asarray(grid, dtype=np.float64)
    pos = np.nonzero(grid > 0)[0]
    if n_ramp <= 0 or pos.size == 0:
        return grid, np.arange(grid.size)
    j1 = int(pos[0])
    base = float(grid[j1 - 1]) if j1 > 0 else 0.0
    sub = [base + (float(grid[j1]) - base) / 2.0 ** k for k in range(n_ramp, 0, -1)]
    full = np.r_[grid[:j1], sub, grid[j1:]]
    return full, np.r_[np.arange(j1), np.arange(j1 + n_ramp, full.size)]


def _sum_substeps(fire_steps: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """FIRE steps per reported point (last axis), each including those of the sub-points before it."""
    return np.add.reduceat(fire_steps, np.r_[0, keep[:-1] + 1], axis=-1) if len(keep) else fire_steps[..., :0]


def _select_points(out: dict, keep: np.ndarray) -> dict:
    """Restrict the per-point arrays of :func:`_run_chain` to the reported points (failures are kept)."""
    sel = dict(out)
    for k in ("fmax", "max_area_strain", "volume"):
        sel[k] = out[k][:, keep]
    sel["fire_steps"] = _sum_substeps(out["fire_steps"], keep)
    sel["point_status"] = [[ps[j] for j in keep] for ps in out["point_status"]]
    sel["obs"] = {k: v[:, keep] for k, v in out["obs"].items()}
    return sel


# the last relaxing curves of an emptied pool move to a batch of their own size when at most this fraction of the
# slots (and more than _COMPACT_MIN slots in all) still relax: an iteration of 500 slots costs >= 0.32 ms on an
# H100 however few relax, one of a batch of 8 slots 0.085 ms (benchmarks/qs_iteration_cost.py, session 12)
_COMPACT_BELOW = 0.125
_COMPACT_MIN = 8


def _run_device_async(dc_factory: Callable[[list], _DeviceChain], params: list, n_points: int,
                      rupture_strain: float, assign_factory: Callable[[_DeviceChain], Callable],
                      max_replicas: int | None, progress,
                      on_finish: Callable[[int, dict], None] | None = None, stop_unstable: bool = False) -> dict:
    """Async chain over ``params``; with ``max_replicas`` < len(params) at most that many slots run at once
    and finished slots take the next sample, softest (smallest k_a) first: FIRE work grows as k_a falls,
    so starting the longest chains first keeps the pool's tail short.  Rows come back in ``params`` order.
    ``on_finish(i, row)``: each finished curve at once (``i`` indexes ``params``)."""
    S = len(params)
    if max_replicas is None or max_replicas >= S:
        dc = dc_factory(params)
        return _run_chain_async(dc, n_points, rupture_strain, assign_factory(dc), progress=progress,
                                on_finish=on_finish, stop_unstable=stop_unstable)
    order = np.argsort([p.ka for p in params], kind="stable")
    pool = [params[int(i)] for i in order]
    dc = dc_factory(pool[:max_replicas])

    def compact(old: _DeviceChain, slots: np.ndarray, ps: list):
        new = dc_factory(ps)
        new.take_over(old, slots)
        return new, assign_factory(new)

    finish = None if on_finish is None else (lambda s, row: on_finish(int(order[s]), row))
    out = _run_chain_async(dc, n_points, rupture_strain, assign_factory(dc), progress=progress, samples=pool,
                           compact=compact, compact_below=_COMPACT_BELOW, compact_min=_COMPACT_MIN,
                           on_finish=finish, stop_unstable=stop_unstable)
    inv = np.empty(S, dtype=np.int64)
    inv[order] = np.arange(S)
    nv = dc.nv
    back = dict(out)
    for k in ("fire_steps", "fmax", "max_area_strain", "volume"):
        back[k] = out[k][inv]
    back["status"] = [out["status"][int(i)] for i in inv]
    back["point_status"] = [out["point_status"][int(i)] for i in inv]
    back["obs"] = {k: v[inv] for k, v in out["obs"].items()}
    back["x"] = out["x"].reshape(S, nv, 3)[inv].reshape(-1, 3)
    return back


def _check_max_replicas(max_replicas, schedule: str) -> None:
    if max_replicas is None:
        return
    if isinstance(max_replicas, bool) or not isinstance(max_replicas, (int, np.integer)) or max_replicas < 1:
        raise ValueError(f"max_replicas must be an integer >= 1 or None, got {max_replicas!r}")
    if schedule != "async":
        raise ValueError("max_replicas (slot refill) needs schedule='async' with the device minimiser")


SCHEDULES = ("async", "lockstep")


def _check_common(rupture_strain: float, fire: FireSettings, minimizer: str = "device",
                  schedule: str | None = None) -> str:
    """Validate the shared arguments; returns the load-point schedule (default: async on the device FIRE)."""
    if schedule is None:
        schedule = "async" if minimizer == "device" else "lockstep"
    if schedule not in SCHEDULES:
        raise ValueError(f"schedule must be one of {SCHEDULES}, got {schedule!r}")
    if schedule == "async" and minimizer != "device":
        raise ValueError("schedule='async' needs minimizer='device' (the NumPy FIRE runs lock-step only)")
    if not (math.isfinite(rupture_strain) and rupture_strain > 0):
        raise ValueError(f"rupture_strain must be a positive finite number, got {rupture_strain!r}")
    if not isinstance(fire, FireSettings):
        raise ValueError(f"fire must be a FireSettings, got {type(fire).__name__}")
    if minimizer not in MINIMIZERS:
        raise ValueError(f"minimizer must be one of {MINIMIZERS}, got {minimizer!r}")
    return schedule


def _dtype_name(dtype) -> str:
    return "float64" if dtype is None else str(getattr(dtype, "__name__", dtype))


def _mean_free(f: np.ndarray, R: int, nv: int, comps: slice) -> np.ndarray:
    fr = f.reshape(R, nv, 3)
    fr[:, :, comps] -= fr[:, :, comps].mean(axis=1, keepdims=True)
    return fr.reshape(-1, 3)

# ------------------------------------------------------------------------------------------------
# results
# ------------------------------------------------------------------------------------------------
@dataclass(kw_only=True)
class _ChainResult:
    """Fields every quasi-static result has: per load point ``volume``, ``max_area_strain``, ``fmax``
    (final per-vertex residual), ``fire_steps`` [R, P]; ``status [R]``, ``point_status [R][P]``;
    ``x_final`` [R*Nv, 3]; ``settings`` (choices); ``seconds`` (wall time)."""

    volume: np.ndarray
    max_area_strain: np.ndarray
    fmax: np.ndarray
    fire_steps: np.ndarray
    status: list[str]
    point_status: list[list[str]]
    x_final: np.ndarray
    settings: dict = field(default_factory=dict)
    seconds: float = 0.0


# ------------------------------------------------------------------------------------------------
# indentation
# ------------------------------------------------------------------------------------------------
@dataclass(kw_only=True)
class IndentationResult(_ChainResult):
    """Quasi-static indentation curves of R replicas at P forces (DPD units).

    ``forces [P]`` (total per pole), ``displacement [R, P]`` = d(F) = H0 - H (axial extent
    reduction), ``axial_diameter [R, P]`` = H, ``axial_diameter0 [R]`` = H0, ``d_patch [R, P]``
    (reduction of the distance between the loaded patches' mean z), ``volume``, ``max_area_strain``,
    ``fmax`` (final per-vertex residual), ``fire_steps`` [R, P]; ``status [R]``, ``point_status
    [R][P]``; ``x_final`` [R*Nv, 3]; ``settings`` (choices); ``seconds`` (wall time).
    """

    forces: np.ndarray
    displacement: np.ndarray
    axial_diameter: np.ndarray
    axial_diameter0: np.ndarray
    d_patch: np.ndarray


def quasistatic_indentation(params: Sequence[ShellParams] | ShellParams, mesh: ShellMesh,
                            forces_dpd: Sequence[float] | np.ndarray, *, gas: IdealGas | None = IdealGas(),
                            device: str = "cpu", dtype=None, fire: FireSettings = FireSettings(),
                            rupture_strain: float = 1.0, fraction_loaded: float | None = None,
                            pole_patch: dict | None = None, minimizer: str = "device",
                            sync_every: int | None = None, extrapolate: bool = True, schedule: str | None = None,
                            max_replicas: int | None = None, first_load_ramp: int = 0,
                            progress: Callable[[int, int, float], None] | None = None,
                            on_curve: Callable[[int, dict], None] | None = None) -> IndentationResult:
    """Athermal quasi-static indentation d(F) of R replicas (one per ``params``) of ``mesh``.

    Args:
        params: one :class:`ShellParams` per replica (moduli in DPD units).
        mesh: stress-free reference shell (DPD lengths), shared by all replicas.
        forces_dpd: total force per pole at each load point (DPD force, >= 0, strictly increasing).
        gas: enclosed ideal gas (:class:`IdealGas`, pressures in DPD units) or None.
        device, dtype: Warp device and float type (default ``wp.float64``).
        fire: :class:`FireSettings` (ftol in DPD force per vertex).
        rupture_strain: max |A_t/A0_t - 1| above which a replica is 'ruptured'.
        fraction_loaded: k = max(1, floor(fraction_loaded N_v)) loaded vertices per pole (the default
            0.01 when neither this nor ``pole_patch`` is given).
        pole_patch: keyword arguments of :func:`bubblecal.sim.engine.pole_patches` (``{"cap_deg": 4.6}``
            for a polar cap); excludes ``fraction_loaded``.
        minimizer: ``"device"`` (default: :class:`bubblecal.sim.engine.minimize_device.DeviceFire`, all state
            and forces on the Warp device) or ``"numpy"`` (host FIRE, the reference implementation).
        sync_every: device FIRE iterations between host status checks (default 25 CUDA / 4 CPU).
        extrapolate: (device minimiser) start each load point from the linear extrapolation of the last
            two minima instead of the last one: same minima (within ``fire.ftol``), fewer FIRE iterations.
        schedule: ``"async"`` (default with the device minimiser: each replica advances to its next load
            point as soon as it has relaxed, so the batch never waits for its slowest replica at every
            point; same FIRE iterates and curves as lock-step) or ``"lockstep"`` (every replica at the same
            point; the only schedule of the ``"numpy"`` minimiser).
        max_replicas: (async only) at most this many replicas relax at once; a slot whose curve is finished
            takes the next parameter set (softest k_a first), so a large batch runs at full occupancy and
            its wall time follows the total FIRE work, not the slowest curve.  Same curves as one slot per
            parameter set.  None (default): one slot per parameter set.
        first_load_ramp: relax through this many geometric sub-points F1/2^n ... F1/2 before the first positive
            force F1 (:func:`_ramp_grid`; the curve keeps the requested points, whose FIRE steps include their
            sub-points'): curves within 0.5 %, 0.54x / 0.57x / 0.75x of the FIRE iterations at 3.2 / 3.4 / 5.8 um
            (benchmarks/RESULTS.md, session 12).  0 (default): none.
        progress: optional ``progress(j, n_points, seconds)`` called after every load point
            (compression: every sub-step); with slot refill ``progress(k, n_params, seconds)`` after every
            finished curve.
        on_curve: optional ``on_curve(i, row)`` as soon as ``params[i]`` has finished its curve (the async
            device schedule), ``row`` = {"displacement" [P] (DPD length), "status", "point_status",
            "fire_steps" [P], "fire_steps_chain" (FIRE updates per chain point, the ramp's sub-points included),
            "settings" (the result's, less the batch total ``fire_evaluations``)}: the same numbers as the
            returned rows.

    Returns: :class:`IndentationResult`; displacement in DPD length.
    """
    t0 = time.perf_counter()
    forces = validate_grid(forces_dpd, "forces_dpd")
    if isinstance(first_load_ramp, bool) or not isinstance(first_load_ramp, (int, np.integer)) \
            or not 0 <= first_load_ramp <= 20:
        raise ValueError(f"first_load_ramp must be an integer in [0, 20], got {first_load_ramp!r}")
    # the chain runs on the grid with the ramp's sub-points; results keep the requested points only
    chain_forces, keep = _ramp_grid(forces, int(first_load_ramp))
    schedule = _check_common(rupture_strain, fire, minimizer, schedule)
    _check_max_replicas(max_replicas, schedule)
    if pole_patch is not None and fraction_loaded is not None:
        raise ValueError("give fraction_loaded or pole_patch, not both")
    patch_kw = dict(pole_patch) if pole_patch is not None else {"fraction": 0.01 if fraction_loaded is None
                                                                 else fraction_loaded}
    if patch_kw.get("fraction") is not None and not (0 < patch_kw["fraction"] < 0.5):
        raise ValueError(f"fraction_loaded must lie in (0, 0.5), got {patch_kw['fraction']!r}")
    params = _check_params(params, mesh, gas)
    R, nv = len(params), mesh.n_vertices
    z0 = mesh.vertices[:, 2]
    zc = float(mesh.vertices[:, 2].mean())
    top, bottom = pole_patches(mesh.vertices, **patch_kw)
    k = len(top)
    h0 = float(z0.max() - z0.min())
    equator = np.nonzero(np.abs(z0 - zc) < 0.25 * mesh.min_edge_length())[0]
    free_v = np.ones((nv, 3), dtype=bool)
    free_v[equator, 2] = False
    unit = np.zeros((nv, 3))
    unit[top, 2] = -1.0 / k
    unit[bottom, 2] = 1.0 / k
    static_settings = {"k_loaded_per_pole": k, "n_equator_anchored": int(equator.size),
                       "pole_patch": {key: v for key, v in patch_kw.items() if v is not None},
                       "gas": None if gas is None else {"p0": gas.p0, "p_ambient": gas.ambient},
                       "com": "mean force removed (x, y, z)", "equator": "|z - z_c| < 0.25 l_min anchored in z",
                       "observable": "d = H0 - H, H = max z - min z", "fire": fire.__dict__,
                       "rupture_strain": rupture_strain, "n_vertices": nv, "minimizer": minimizer,
                       "dtype": _dtype_name(dtype),
                       "start": "linear extrapolation" if extrapolate and minimizer == "device" else "previous minimum",
                       "schedule": schedule, "max_replicas": max_replicas, "first_load_ramp": int(first_load_ramp)}
    if minimizer == "device":
        tag = np.zeros(nv, dtype=np.int32)
        tag[top], tag[bottom] = 1, -1
        def make_chain(ps):
            return _DeviceChain(ps, mesh, gas, device, dtype, fire, free_v=free_v, remove_mean=(True, True, True),
                                unit=unit, tag=tag, sync_every=sync_every,
                                loads=chain_forces if extrapolate else None)

        if schedule == "async":
            finish = None
            if on_curve is not None:
                def finish(i, row):
                    h = row["obs"].get("H", np.full(len(chain_forces), np.nan))[keep]
                    on_curve(i, {"displacement": h0 - h, "status": row["status"],
                                 "point_status": [row["point_status"][j] for j in keep],
                                 "fire_steps": _sum_substeps(row["fire_steps"], keep),
                                 "fire_steps_chain": np.asarray(row["fire_steps"]).copy(), "settings": static_settings})

            out = _run_device_async(make_chain, params, len(chain_forces), rupture_strain,
                                    lambda dc: (lambda jj: dc.set_load_rows(chain_forces[jj])), max_replicas,
                                    progress, on_finish=finish, stop_unstable=fire.stop_at_max_steps)
        else:
            dc = make_chain(params)
            out = _run_chain(dc, len(chain_forces), rupture_strain, set_point=lambda j: dc.set_load(chain_forces[j]),
                             progress=progress, stop_unstable=fire.stop_at_max_steps)
    else:
        b = _Batch(params, mesh, gas, device, dtype)
        unit_all = np.tile(unit, (R, 1))

        def make(j, alive):
            fext = chain_forces[j] * unit_all

            def ef(x):
                f = b.shell_gas_forces(x) + fext
                return None, _mean_free(f, R, nv, slice(0, 3))

            return ef

        def measure(x, j):
            xr = b.view(x)
            h = xr[:, :, 2].max(axis=1) - xr[:, :, 2].min(axis=1)
            patch = xr[:, top, 2].mean(axis=1) - xr[:, bottom, 2].mean(axis=1)
            return {"H": h, "patch": patch}

        hc = _HostChain(b, make, np.tile(free_v, (R, 1)), fire, measure)
        out = _run_chain(hc, len(chain_forces), rupture_strain, progress=progress,
                         stop_unstable=fire.stop_at_max_steps)
    out = _select_points(out, keep)
    patch0 = float(z0[top].mean() - z0[bottom].mean())
    H = out["obs"].get("H", np.full((R, len(forces)), np.nan))
    P = out["obs"].get("patch", np.full((R, len(forces)), np.nan))
    settings = {**static_settings, "fire_evaluations": out["fire_evaluations"]}
    return IndentationResult(forces=forces, displacement=h0 - H, axial_diameter=H,
                             axial_diameter0=np.full(R, h0), d_patch=patch0 - P, volume=out["volume"],
                             max_area_strain=out["max_area_strain"], fmax=out["fmax"],
                             fire_steps=out["fire_steps"], status=out["status"],
                             point_status=out["point_status"], x_final=out["x"], settings=settings,
                             seconds=time.perf_counter() - t0)


# ------------------------------------------------------------------------------------------------
# compression
# ------------------------------------------------------------------------------------------------
@dataclass(kw_only=True)
class CompressionResult(_ChainResult):
    """Quasi-static compression curves of R replicas at P imposed total displacements (DPD units).

    ``displacements [P]``, ``force [R, P]`` = compressive force on the top plate (one plate),
    ``force_bottom [R, P]`` (same for the bottom plate), ``n_contacts [R, P]`` (vertices in range of
    the top plate), ``plate_z [P]`` (top plate height; bottom is mirrored about z_c), ``volume``,
    ``max_area_strain``, ``fmax``, ``fire_steps``, ``status``, ``point_status``, ``x_final``,
    ``settings``, ``seconds``.
    """

    displacements: np.ndarray
    force: np.ndarray
    force_bottom: np.ndarray
    n_contacts: np.ndarray
    plate_z: np.ndarray


def quasistatic_compression(params: Sequence[ShellParams] | ShellParams, mesh: ShellMesh,
                            displacements_dpd: Sequence[float] | np.ndarray, *,
                            gas: IdealGas | None = IdealGas(), contact: PlateContact = PlateContact(),
                            thermal: ThermalContact | None = None,
                            device: str = "cpu", dtype=None, fire: FireSettings = FireSettings(),
                            rupture_strain: float = 1.0, max_plate_step: float = 0.06, minimizer: str = "device",
                            sync_every: int | None = None, extrapolate: bool = True, schedule: str | None = None,
                            max_replicas: int | None = None,
                            progress: Callable[[int, int, float], None] | None = None) -> CompressionResult:
    """Athermal quasi-static parallel-plate compression F(d) of R replicas of ``mesh``.

    Args:
        params: one :class:`ShellParams` per replica (DPD units).
        mesh: stress-free reference shell (DPD lengths).
        displacements_dpd: imposed total plate displacement d at each point (DPD length, >= 0,
            strictly increasing); each plate moves d/2.
        gas: enclosed ideal gas or None.  contact: plate-vertex :class:`PlateContact`.
        thermal: None (athermal WCA plates) or a :class:`ThermalContact`: the plates act on each vertex
            through the mean force of its thermal normal fluctuation against the WCA's hard-wall distance
            (:mod:`bubblecal.sim.tiers.thermal_contact`), the entropic contact force the explicit tier has.
        device, dtype, fire, rupture_strain, minimizer, sync_every, extrapolate, schedule, max_replicas,
            progress: as in :func:`quasistatic_indentation`.
        max_plate_step: largest plate move between two minimisations (DPD length); longer load steps
            are split into relaxed sub-steps (a 0.12 jump into the stiff WCA wall makes FIRE diverge).
            0.06 = one minimisation per point of the published grid; 0.03 gives the same curves within
            2e-4 of their maximum (3.0 um training rows, s3) at twice the FIRE evaluations.

    Returns: :class:`CompressionResult`; ``force`` in DPD force (on one plate), at the requested
    displacements only (sub-steps are not reported).
    """
    t0 = time.perf_counter()
    requested = validate_grid(displacements_dpd, "displacements_dpd")
    schedule = _check_common(rupture_strain, fire, minimizer, schedule)
    _check_max_replicas(max_replicas, schedule)
    if not (math.isfinite(max_plate_step) and max_plate_step > 0):
        raise ValueError(f"max_plate_step must be a positive finite DPD length, got {max_plate_step!r}")
    disp, keep = _refine_grid(requested, 2.0 * max_plate_step)
    if not isinstance(contact, PlateContact):
        raise ValueError(f"contact must be a PlateContact, got {type(contact).__name__}")
    if thermal is not None and not isinstance(thermal, ThermalContact):
        raise ValueError(f"thermal must be None or a ThermalContact, got {type(thermal).__name__}")
    params = _check_params(params, mesh, gas)
    radius = float(np.linalg.norm(mesh.vertices - mesh.vertices.mean(axis=0), axis=1).mean())
    R, nv = len(params), mesh.n_vertices
    zc = float(mesh.vertices[:, 2].mean())
    h0 = float(np.max(np.abs(mesh.vertices[:, 2] - zc)))
    if np.any(disp / 2 >= h0 + contact.gap):
        raise ValueError(f"displacements_dpd must stay below 2 (h0 + gap) = {2 * (h0 + contact.gap):.3f}")
    plate = zc + h0 + contact.gap - disp / 2.0  # top plate z; bottom = 2 zc - plate
    if minimizer == "device":
        def make_chain(ps):
            return _DeviceChain(ps, mesh, gas, device, dtype, fire, free_v=np.ones((nv, 3), dtype=bool),
                                remove_mean=(True, True, False), contact=contact, thermal=thermal,
                                radius_dpd=radius, sync_every=sync_every, loads=disp if extrapolate else None)

        if schedule == "async":
            out = _run_device_async(make_chain, params, len(disp), rupture_strain,
                                    lambda dc: (lambda jj: dc.set_plate_rows(plate[jj], 2 * zc - plate[jj])),
                                    max_replicas, progress, stop_unstable=fire.stop_at_max_steps)
        else:
            dc = make_chain(params)
            out = _run_chain(dc, len(disp), rupture_strain,
                             set_point=lambda j: dc.set_plates(plate[j], 2 * zc - plate[j]), progress=progress,
                             stop_unstable=fire.stop_at_max_steps)
    else:
        b = _Batch(params, mesh, gas, device, dtype)
        if thermal is not None:
            sig = (np.full(R, thermal.sigma) if thermal.sigma is not None
                   else shell_fluctuation_sigma(params, radius, thermal.kT))
            sig_rows = np.repeat(sig, nv)
            h_wall = hard_wall_distance(contact, thermal.kT)

        def plate_forces(x, j):
            z = x[:, 2]
            if thermal is not None:
                ft = thermal_plate_force(plate[j] - z, sig_rows, h_wall, thermal.kT, contact.force_cap)
                fb = thermal_plate_force(z - (2 * zc - plate[j]), sig_rows, h_wall, thermal.kT, contact.force_cap)
                return ft, fb
            ft, et = plate_force_energy(plate[j] - z, contact)
            fb, eb = plate_force_energy(z - (2 * zc - plate[j]), contact)
            return ft, fb

        def make(j, alive):
            def ef(x):
                f = b.shell_gas_forces(x)
                ft, fb = plate_forces(x, j)
                f[:, 2] += fb - ft
                return None, _mean_free(f, R, nv, slice(0, 2))

            return ef

        def measure(x, j):
            ft, fb = plate_forces(x, j)
            z = x[:, 2]
            reach = contact.cutoff if thermal is None else np.maximum(contact.cutoff, h_wall + 3.0 * sig_rows)
            return {"top": ft.reshape(R, nv).sum(axis=1), "bottom": fb.reshape(R, nv).sum(axis=1),
                    "contacts": (plate[j] - z < reach).reshape(R, nv).sum(axis=1).astype(float)}

        hc = _HostChain(b, make, np.ones((R * nv, 3), dtype=bool), fire, measure)
        out = _run_chain(hc, len(disp), rupture_strain, progress=progress, stop_unstable=fire.stop_at_max_steps)
    fire_evaluations = out["fire_evaluations"]
    out = _select_points(out, keep)
    nan = np.full((R, len(keep)), np.nan)
    settings = {"gas": None if gas is None else {"p0": gas.p0, "p_ambient": gas.ambient},
                "contact": {**contact.__dict__, "cutoff": contact.cutoff},
                "thermal_contact": None if thermal is None else {
                    "kT": thermal.kT, "sigma": thermal.sigma if thermal.sigma is not None
                    else "kT R / (8 sqrt(kappa Y)), kappa = (sqrt 3 / 2) kb, Y = 4 ka mu / (ka + mu)",
                    "hard_wall": hard_wall_distance(contact, thermal.kT), "radius_dpd": radius},
                "plates": "z = z_c +- (h0 + gap - d/2)", "h0": h0, "com": "mean x, y force removed",
                "observable": "force on the top plate (one plate), positive compressive",
                "fire": fire.__dict__, "rupture_strain": rupture_strain, "n_vertices": nv, "minimizer": minimizer,
                "dtype": _dtype_name(dtype), "fire_evaluations": fire_evaluations,
                "start": "linear extrapolation" if extrapolate and minimizer == "device" else "previous minimum",
                "schedule": schedule, "max_replicas": max_replicas}
    return CompressionResult(displacements=requested, force=out["obs"].get("top", nan),
                             force_bottom=out["obs"].get("bottom", nan),
                             n_contacts=out["obs"].get("contacts", nan), plate_z=plate[keep], volume=out["volume"],
                             max_area_strain=out["max_area_strain"], fmax=out["fmax"],
                             fire_steps=out["fire_steps"], status=out["status"],
                             point_status=out["point_status"], x_final=out["x"], settings=settings,
                             seconds=time.perf_counter() - t0)
