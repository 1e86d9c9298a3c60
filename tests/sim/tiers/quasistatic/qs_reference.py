"""The NumPy reference of the quasi-static tier: host FIRE with NumPy shell and gas forces (tests only).

The package's only backend is the device chain (:mod:`bubblecal.sim.tiers.quasistatic.backends`, which runs on
the CPU too).  This reference follows the same FIRE rules with :func:`bubblecal.sim.engine.minimize.fire_minimize`
and one host round trip per force evaluation, on the package's own plans, lock-step schedule and results, so
float64 curves on the CPU agree with the device chain to round-off.  Loaded by path (tests run with
``--import-mode=importlib``): the ``qs_reference`` fixture of ``tests/sim/tiers/quasistatic/conftest.py``, or
``load_script("tests/sim/tiers/quasistatic/qs_reference.py")``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

from bubblecal.sim.engine.kernels.shell import ShellParams
from bubblecal.sim.engine.mesh import ShellMesh
from bubblecal.sim.protocols import PlateContact, plate_force_energy
from bubblecal.sim.tiers.quasistatic import (
    FireSettings,
    IdealGas,
    ThermalContact,
    hard_wall_distance,
    shell_fluctuation_sigma,
    thermal_plate_force,
)
from bubblecal.sim.tiers.quasistatic.compression import (
    _compression_plan,
    _compression_result,
    _compression_settings,
)
from bubblecal.sim.tiers.quasistatic.indentation import _indentation_plan, _indentation_result
from bubblecal.sim.tiers.quasistatic.schedule import _run_chain
from bubblecal.sim.tiers.quasistatic.settings import _check_params

_ASYNC_REFUSED = "schedule='async' needs minimizer='device' (the NumPy FIRE runs lock-step only)"


class _Batch:
    """R replicas of one mesh packed row-wise; shell + gas forces as NumPy arrays."""

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


def _mean_free(f: np.ndarray, R: int, nv: int, comps: slice) -> np.ndarray:
    """Forces with each replica's mean removed in the ``comps`` components (centre of mass pinned)."""
    fr = f.reshape(R, nv, 3)
    fr[:, :, comps] -= fr[:, :, comps].mean(axis=1, keepdims=True)
    return fr.reshape(-1, 3)


def _lockstep(schedule: str | None) -> str:
    """The NumPy FIRE runs lock-step only (None = lock-step)."""
    if schedule == "async":
        raise ValueError(_ASYNC_REFUSED)
    return "lockstep" if schedule is None else schedule


def reference_indentation(params: Sequence[ShellParams] | ShellParams, mesh: ShellMesh,
                          forces_dpd: Sequence[float] | np.ndarray, *, gas: IdealGas | None = IdealGas(),
                          device: str = "cpu", dtype=None, fire: FireSettings = FireSettings(),
                          rupture_strain: float = 1.0, fraction_loaded: float | None = None,
                          pole_patch: dict | None = None, schedule: str | None = None, first_load_ramp: int = 0,
                          progress: Callable[[int, int, float], None] | None = None):
    """:func:`bubblecal.sim.tiers.quasistatic.quasistatic_indentation` with the host FIRE (lock-step, each point
    from the previous minimum); ``settings["minimizer"]`` is ``"numpy"``."""
    t0 = time.perf_counter()
    plan = _indentation_plan(params, mesh, forces_dpd, gas=gas, fire=fire, rupture_strain=rupture_strain,
                             fraction_loaded=fraction_loaded, pole_patch=pole_patch, dtype=dtype, extrapolate=False,
                             schedule=_lockstep(schedule), max_replicas=None, first_load_ramp=first_load_ramp)
    plan.static_settings["minimizer"] = "numpy"
    R, nv, chain_forces = len(plan.params), mesh.n_vertices, plan.chain_forces
    top, bottom = plan.top, plan.bottom
    b = _Batch(plan.params, mesh, gas, device, dtype)
    unit_all = np.tile(plan.unit, (R, 1))

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

    hc = _HostChain(b, make, np.tile(plan.free_v, (R, 1)), fire, measure)
    out = _run_chain(hc, len(chain_forces), rupture_strain, progress=progress, stop_unstable=fire.stop_at_max_steps)
    return _indentation_result(plan, out, t0)


def reference_compression(params: Sequence[ShellParams] | ShellParams, mesh: ShellMesh,
                          displacements_dpd: Sequence[float] | np.ndarray, *,
                          gas: IdealGas | None = IdealGas(), contact: PlateContact = PlateContact(),
                          thermal: ThermalContact | None = None, device: str = "cpu", dtype=None,
                          fire: FireSettings = FireSettings(), rupture_strain: float = 1.0,
                          max_plate_step: float = 0.06, schedule: str | None = None,
                          progress: Callable[[int, int, float], None] | None = None):
    """:func:`bubblecal.sim.tiers.quasistatic.quasistatic_compression` with the host FIRE (lock-step, each point
    from the previous minimum) and NumPy plate forces; ``settings["minimizer"]`` is ``"numpy"``."""
    t0 = time.perf_counter()
    plan = _compression_plan(params, mesh, displacements_dpd, gas=gas, contact=contact, thermal=thermal, fire=fire,
                             rupture_strain=rupture_strain, max_plate_step=max_plate_step,
                             schedule=_lockstep(schedule), max_replicas=None)
    R, nv, zc, plate, radius = len(plan.params), mesh.n_vertices, plan.zc, plan.plate, plan.radius
    b = _Batch(plan.params, mesh, gas, device, dtype)
    if thermal is not None:
        sig = (np.full(R, thermal.sigma) if thermal.sigma is not None
               else shell_fluctuation_sigma(plan.params, radius, thermal.kT))
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
    out = _run_chain(hc, len(plan.disp), rupture_strain, progress=progress, stop_unstable=fire.stop_at_max_steps)
    settings = _compression_settings(plan, gas=gas, contact=contact, thermal=thermal, fire=fire,
                                     rupture_strain=rupture_strain, n_vertices=nv, dtype=dtype, extrapolate=False,
                                     max_replicas=None)
    res = _compression_result(plan, out, t0, settings)
    res.settings["minimizer"] = "numpy"
    return res
