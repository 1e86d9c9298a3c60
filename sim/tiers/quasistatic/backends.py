"""The quasi-static tier's backend: a chain of load points relaxed by a device-resident minimiser.

Positions, forces and the minimiser's state stay on the Warp device (FIRE,
:class:`bubblecal.sim.engine.minimize_device.DeviceFire`, or the nonlinear CG,
:class:`bubblecal.sim.engine.minimize_device_cg.DeviceCG`, after ``FireSettings.minimizer``;
the attribute ``fire`` holds either); shell (ShellForceField kernels), gas, pole loads or
plates, centre-of-mass removal and the observables are kernels (:mod:`bubblecal.sim.engine.kernels.qs_loading`);
the host reads R status flags every ``sync_every`` iterations (CUDA: those iterations replay as one CUDA graph).
This backend runs on every Warp device, the CPU included.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.protocols.plates import PlateContact, plate_cap_distance
from bubblecal.sim.tiers.quasistatic.settings import FireSettings, IdealGas, _check_params
from bubblecal.sim.tiers.quasistatic.thermal_contact import (
    ThermalContact,
    hard_wall_distance,
    psi_continuation,
    shell_fluctuation_sigma,
)

if TYPE_CHECKING:
    from bubblecal.sim.engine.kernels.shell import ShellParams
    from bubblecal.sim.engine.mesh import ShellMesh

__all__: list[str] = []


class _DeviceChain:
    """Load-point backend with the device-resident FIRE (:class:`bubblecal.sim.engine.minimize_device.DeviceFire`).

    Shell (ShellForceField kernels), gas, pole loads / plates, COM removal and the observables all run
    as Warp kernels on ``device``; per load point only R-sized arrays come back to the host.
    ``free_v [Nv, 3]`` (per mesh vertex), ``remove_mean`` (components), ``unit [Nv, 3]`` (pole-load
    direction per unit load, or None), ``tag [Nv]`` (1 top patch, -1 bottom patch, or None),
    ``contact`` (plates, or None).  Several bubble sizes in one batch: ``mesh`` a list of per-replica
    references of one topology, ``replica_loads [R, n]`` each replica's chain loads (the predictor's, instead
    of the shared ``loads``), ``radii [R]`` (thermal contact), ``plate_heights [R, n]`` (top-plate height at each
    chain point) and ``centers [R]`` (the plates are symmetric about them); :meth:`load_samples` swaps them with a
    slot's sample and :meth:`assign_plates` sets each slot's plates.
    """

    def __init__(self, params, mesh: ShellMesh, gas: IdealGas | None, device: str, dtype, fire: FireSettings, *,
                 free_v: np.ndarray, remove_mean: tuple[bool, bool, bool], unit: np.ndarray | None = None,
                 tag: np.ndarray | None = None, contact: PlateContact | None = None,
                 thermal: ThermalContact | None = None, radius_dpd: float | None = None,
                 sync_every: int | None = None, use_graph: bool | None = None,
                 loads: np.ndarray | None = None, replica_loads: np.ndarray | None = None,
                 radii: Sequence[float] | None = None, plate_heights: np.ndarray | None = None,
                 centers: Sequence[float] | None = None):
        wp = require("warp", "sim")

        from bubblecal.sim.engine.kernels.qs_loading import qs_kernels
        from bubblecal.sim.engine.kernels.shell import ShellForceField
        from bubblecal.sim.engine.minimize_device import DeviceFire
        from bubblecal.sim.engine.minimize_device_cg import DeviceCG

        meshes = list(mesh) if isinstance(mesh, (list, tuple)) else None  # one reference per replica
        mesh = meshes[0] if meshes else mesh
        if meshes is not None and len(meshes) != len(params):
            raise ValueError(f"{len(meshes)} meshes for {len(params)} parameter sets")
        params = _check_params(params, mesh, gas)
        wp.config.quiet = True
        wp.init()
        self.wp = wp
        T = wp.float64 if dtype is None else dtype
        self.R, self.nv = R, nv = len(params), mesh.n_vertices
        self.ff = ShellForceField(meshes or mesh, params, device=device, dtype=T, force_mode=fire.force_mode)
        self.dtype, self.vec3, dev = T, self.ff.vec3, self.ff.device
        self.device = dev
        npf = np.float64 if T is wp.float64 else np.float32
        self._npf = npf
        self.k = qs_kernels(T)
        self.fire_settings = fire
        minimizer = DeviceCG if fire.minimizer == "cg" else DeviceFire
        self.fire = minimizer(np.arange(R + 1) * nv, self._forces, device=dev, dtype=T,
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
        self._gas_model = gas
        g = np.zeros((R, 2))
        if gas is not None:
            g[:, 0] = gas.p0 * (np.array([m.volume() for m in meshes]) if meshes else mesh.volume())
            g[:, 1] = gas.ambient
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
        h_cap = plate_cap_distance(c.epsilon, c.sigma, c.force_cap)
        self.pc = [T(c.epsilon), T(c.sigma), T(c.cutoff), T(h_cap), T(c.force_cap)]
        # thermal contact: per-replica rms normal fluctuation, hard wall at the WCA's Barker-Henderson distance
        self.thermal = thermal if self.plate_on else None
        self._radius = float(mesh.radius_dpd) if radius_dpd is None else float(radius_dpd)
        self.slot_radius = np.full(R, self._radius) if radii is None else np.asarray(radii, dtype=np.float64)
        self.slot_plates = None if plate_heights is None else np.array(plate_heights, dtype=np.float64).reshape(R, -1)
        self.slot_center = None if centers is None else np.array(centers, dtype=np.float64).reshape(R)
        self.tsig = wp.array(self._sigmas(params, self.slot_radius).astype(npf), dtype=T, device=dev)
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
        if replica_loads is not None:
            self.slot_loads = np.array(replica_loads, dtype=np.float64).reshape(R, -1)
        else:
            self.slot_loads = None if self.loads is None else np.tile(self.loads, (R, 1))
        self.x_prev = wp.clone(self.fire.x) if self.slot_loads is not None else None

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

    def _sigmas(self, params, radii: np.ndarray) -> np.ndarray:
        """rms normal fluctuation of each shell (radius ``radii[i]``) for the thermal contact (ones when
        athermal: unused)."""
        if self.thermal is None:
            return np.ones(len(params))
        if self.thermal.sigma is not None:
            return np.full(len(params), float(self.thermal.sigma))
        out = np.empty(len(params))
        for r in np.unique(radii):  # one call per size, as a batch of that size alone computes it
            idx = np.flatnonzero(radii == r)
            out[idx] = shell_fluctuation_sigma([params[int(i)] for i in idx], float(r), self.thermal.kT)
        return out

    def set_load(self, value: float) -> None:
        """Pole load (total force per pole, DPD force) for every replica."""
        self.load.fill_(float(value))

    def set_plates(self, z_top: float, z_bottom: float) -> None:
        """Plate heights (DPD length) for every replica."""
        self.plates.assign(np.tile([z_top, z_bottom], (self.R, 1)).astype(self._npf))

    def assign_plates(self, j: np.ndarray) -> None:
        """Plates of each slot at its chain point ``j[r]`` from its own ``plate_heights`` and centre."""
        top = self.slot_plates[np.arange(self.R), np.asarray(j, dtype=np.int64)]
        self.set_plate_rows(top, 2 * self.slot_center - top)

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
        L = self.slot_loads  # [R, n]: each slot's own chain (one row per slot, equal rows for one size)
        jj = np.asarray(j, dtype=np.int64)
        c = np.zeros(jj.shape)
        ok = (jj >= 2) & (jj < L.shape[1])
        rows, jo = np.flatnonzero(ok), jj[ok]
        den = L[rows, jo - 1] - L[rows, jo - 2]
        c[ok] = np.where(den > 0, (L[rows, jo] - L[rows, jo - 1]) / np.where(den > 0, den, 1.0), 0.0)
        return c

    def start_rows(self, j: np.ndarray, flags: np.ndarray) -> None:
        """(Re)start FIRE on the flagged replicas at their points ``j`` (loads already assigned), from the
        linear prediction of their last two minima when the chain extrapolates."""
        flags = np.asarray(flags, dtype=bool)
        if not flags.any():
            return
        if self.slot_loads is not None:
            self.flag.assign(flags.astype(np.int32))
            coef = self.wp.array(self.predictor_coefficients(j).astype(self._npf), dtype=self.dtype,
                                 device=self.device)
            self.wp.launch(self.k["extrapolate_rows_kernel"], dim=self.R * self.nv,
                           inputs=[self.fire.x, self.x_prev, self.row_rep, self.flag, coef], device=self.device)
        self.fire.restart(flags)

    def load_samples(self, rows: np.ndarray, params: Sequence[ShellParams],
                     meshes: Sequence[ShellMesh] | None = None, loads: np.ndarray | None = None,
                     radii: Sequence[float] | None = None, plate_heights: np.ndarray | None = None,
                     centers: Sequence[float] | None = None) -> None:
        """Reuse replica slots ``rows`` for new samples: their shells get ``params`` (and, for samples of other
        sizes, the stress-free references ``meshes`` of the same topology, chain ``loads [k, n]``, ``radii``,
        ``plate_heights [k, n]`` and ``centers``) and return to the reference (the caller then restarts them at
        load point 0 with :meth:`start_rows`)."""
        rows = np.asarray(rows, dtype=np.int64)
        if len(rows) == 0:
            return
        if loads is not None:
            self.slot_loads[rows] = np.asarray(loads, dtype=np.float64)
        if plate_heights is not None:
            self.slot_plates[rows] = np.asarray(plate_heights, dtype=np.float64)
            self.slot_center[rows] = np.asarray(centers, dtype=np.float64)
        if radii is not None:
            self.slot_radius[rows] = np.asarray(radii, dtype=np.float64)
        if meshes is None:
            self.ff.set_params_rows(rows, list(params))
        else:
            self.ff.set_reference_rows(rows, list(meshes), list(params))
            wp = self.wp
            for r, m in zip(rows, meshes, strict=True):  # only the slots' rows travel to the device
                src = wp.array(m.vertices.astype(self._npf), dtype=self.vec3, device=self.device)
                wp.copy(self.x_ref, src, dest_offset=int(r) * self.nv, count=self.nv)
            if self._gas_model is not None:
                g = self.gas.numpy()
                g[rows, 0] = [self._gas_model.p0 * m.volume() for m in meshes]
                self.gas.assign(g)
        if self.thermal is not None:
            sig = self.tsig.numpy()
            sig[rows] = self._sigmas(list(params), self.slot_radius[rows])
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
        self.gas.assign(old.gas.numpy()[slots])
        self.slot_radius = old.slot_radius[slots].copy()
        if old.slot_loads is not None:
            self.slot_loads = old.slot_loads[slots].copy()
        if old.slot_plates is not None:
            self.slot_plates, self.slot_center = old.slot_plates[slots].copy(), old.slot_center[slots].copy()
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
