"""Batched FIRE minimiser whose whole state lives on a Warp device (CPU or CUDA).

Same rules as the NumPy reference :func:`bubblecal.sim.engine.minimize.fire_minimize` (FIRE 2.0: per-replica
time step, mixing, ``n_pos`` counter, half-step correction on an uphill step, ``max_move`` cap per
row, per-replica convergence test ``max_i |F_i| <= ftol`` over the free components, frozen replicas,
``nonfinite`` status), but positions ``x``, velocities ``v``, forces ``F`` and the per-replica state
(``dt``, ``alpha``, ``n_pos``, P = sum F.v, |F|^2, |v|^2, fmax, flags) are Warp arrays, updated by
the kernels of :mod:`bubblecal.sim.engine.kernels.fire`.  The host only reads the per-replica status
every ``sync_every`` iterations; on CUDA those iterations are captured once as a CUDA graph and
replayed.

Replica r owns the contiguous rows ``[row_start[r], row_start[r+1])``.  Forces come from a
``force_fn(x, f)`` that *adds* -dE/dx into ``f`` (zeroed before every call) with Warp launches only;
with graph capture on, every input that changes between minimisations (loads, plate positions)
must live in device arrays read by those kernels.  The optional mean-force removal (``remove_mean``, per
component) pins the centre of mass: the replica's mean force is subtracted before the fixed components (``free``)
are zeroed, as in the NumPy reference.  Layout, status loop and replica-asynchronous use (restart, export / import
of replicas) are the base's (:class:`bubblecal.sim.engine.minimize_device_base.DeviceMinimizer`).

Iteration i of a replica = force evaluation, convergence test, FIRE update; ``steps`` counts the
updates exactly as the NumPy version does (a replica converged at its first test reports 0).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.fire import fire_kernels
from bubblecal.sim.engine.minimize_device_base import DeviceMinimizer

wp = require("warp", "sim")

__all__ = ["DeviceFire", "numpy_force_fn"]


def numpy_force_fn(callback: Callable[[np.ndarray], np.ndarray]):
    """Adapter for a host callback: copies every evaluation (slow; tests and prototypes only, never graph-captured).

    Parameters
    ----------
    callback : callable
        ``x [N, 3] (float64) -> F [N, 3]`` forces (-dE/dx, caller's units).

    Returns
    -------
    callable
        ``fn(x, f)`` adding the callback's forces into the device array ``f``; ``fn.capturable`` is False.
    """

    def fn(x: wp.array, f: wp.array) -> None:
        xf = x.numpy().astype(np.float64)
        fh = np.asarray(callback(xf), dtype=np.float64)
        f.assign((f.numpy() + fh).astype(f.numpy().dtype))

    fn.capturable = False
    return fn


class DeviceFire(DeviceMinimizer):
    """Batched FIRE with device-resident state (see the module docstring).

    Parameters
    ----------
    row_start, force_fn : optional
        Replica layout and forces, as for :class:`~bubblecal.sim.engine.minimize_device_base.DeviceMinimizer`.
    device, dtype, n_rows, free, remove_mean, sync_every, threads_per_replica, use_graph : optional
        As for :class:`~bubblecal.sim.engine.minimize_device_base.DeviceMinimizer`.
    mass : float or numpy.ndarray, optional
        Scalar or per-row FIRE mass.
    dt, dt_max, dt_min, max_move, n_delay, f_inc, f_dec, alpha0, f_alpha : optional
        FIRE constants as in :func:`bubblecal.sim.engine.minimize.fire_minimize` (dt_max default 10 dt, dt_min
        dt / 50, ``max_move`` None: no cap), in the caller's time / length units.

    Raises
    ------
    ValueError
        On a bad ``dtype``, ``row_start``, ``n_rows``, ``dt``, ``sync_every`` or ``free`` shape.
    """

    def __init__(self, row_start: Sequence[int] | np.ndarray, force_fn: Callable, *, device: str = "cpu",
                 dtype=wp.float64, n_rows: int | None = None, free: np.ndarray | None = None,
                 mass: float | np.ndarray = 1.0, remove_mean: Sequence[bool] = (False, False, False),
                 dt: float = 1e-2, dt_max: float | None = None, dt_min: float | None = None,
                 max_move: float | None = 0.05, n_delay: int = 5, f_inc: float = 1.1, f_dec: float = 0.5,
                 alpha0: float = 0.1, f_alpha: float = 0.99, sync_every: int | None = None,
                 threads_per_replica: int | None = None, use_graph: bool | None = None):
        if not (dt > 0 and math.isfinite(dt)):
            raise ValueError(f"dt must be a positive finite time, got {dt!r}")
        super().__init__(row_start, force_fn, device=device, dtype=dtype, n_rows=n_rows, free=free,
                         remove_mean=remove_mean, sync_every=sync_every, threads_per_replica=threads_per_replica,
                         use_graph=use_graph)
        self._k = fire_kernels(dtype)
        self.consts = dict(dt=float(dt), dt_max=10.0 * dt if dt_max is None else float(dt_max),
                           dt_min=dt / 50.0 if dt_min is None else float(dt_min),
                           max_move=-1.0 if max_move is None else float(max_move), n_delay=int(n_delay),
                           f_inc=float(f_inc), f_dec=float(f_dec), alpha0=float(alpha0), f_alpha=float(f_alpha))
        n, R, dev, T, V = self.n_rows, self.R, self.device, dtype, self.vec3
        inv_m = 1.0 / np.broadcast_to(np.asarray(mass, dtype=np.float64), (n,))
        self.v = wp.zeros(n, dtype=V, device=dev)
        self.inv_mass = wp.array(inv_m.astype(self._np), dtype=T, device=dev)
        z = lambda dt_=T: wp.zeros(R, dtype=dt_, device=dev)  # noqa: E731
        self.npos = z(wp.int32)
        self.down = z(wp.int32)
        self.dt_r, self.alpha_r, self.fnorm = z(), z(), z()
        self.fmax_acc, self.fsq_acc, self.pow_acc, self.vsq_acc = z(), z(), z(), z()

    _ROW_STATE = ("x", "v", "f")
    _REPLICA_STATE = ("active", "status", "iters", "steps", "npos", "down", "nonfin", "dt_r", "alpha_r", "fnorm",
                      "fmax_out", "fmax_acc", "fsq_acc", "pow_acc", "vsq_acc", "mean_acc", "tol")

    # ------------------------------------------------------------------------------------------
    def _iteration(self) -> None:
        """One FIRE iteration of every replica: forces, projection, replica update, Euler step, mixing."""
        k, dev, c = self._k, self.device, self.consts
        T = self.dtype
        dimv = self.R * self.nthr
        self.force_fn(self.x, self.f)
        if self.remove_mean:
            wp.launch(k["mean_accum_kernel"], dim=dimv,
                      inputs=[self.f, self.row_start, self.status, self.nthr, self.mean_acc], device=dev)
        wp.launch(k["project_reduce_kernel"], dim=dimv,
                  inputs=[self.f, self.v, self.free, self.row_start, self.status, self.nthr, self.mean_comps,
                          self.mean_acc, self.fmax_acc, self.fsq_acc, self.pow_acc, self.nonfin], device=dev)
        wp.launch(k["replica_kernel"], dim=self.R,
                  inputs=[self.status, self.iters, self.max_steps, self.tol, self.fmax_acc, self.fsq_acc,
                          self.pow_acc, self.nonfin, self.vsq_acc, self.mean_acc, self.fmax_out, self.steps,
                          self.dt_r, self.alpha_r, self.npos, self.down, self.fnorm, T(c["dt_max"]),
                          T(c["dt_min"]), T(c["f_inc"]), T(c["f_dec"]), T(c["alpha0"]), T(c["f_alpha"]),
                          c["n_delay"]], device=dev)
        wp.launch(k["euler_kernel"], dim=dimv,
                  inputs=[self.x, self.v, self.f, self.free, self.inv_mass, self.row_start, self.status, self.nthr,
                          self.dt_r, self.down, self.vsq_acc], device=dev)
        wp.launch(k["mix_move_kernel"], dim=dimv,
                  inputs=[self.x, self.v, self.f, self.free, self.row_start, self.status, self.nthr, self.dt_r,
                          self.alpha_r, self.fnorm, self.vsq_acc, T(c["max_move"])], device=dev)

    def _reset_all(self) -> None:
        """FIRE at rest: ``active`` replicas ACTIVE with the initial time step and mixing, the others FROZEN."""
        c, T = self.consts, self.dtype
        self.v.zero_()
        self.f.zero_()
        wp.launch(self._k["reset_kernel"], dim=self.R,
                  inputs=[self.active, self.status, self.iters, self.steps, self.dt_r, self.alpha_r, self.npos,
                          self.down, self.fmax_out, self.fmax_acc, self.fsq_acc, self.pow_acc, self.nonfin,
                          self.vsq_acc, self.mean_acc, T(c["dt"]), T(c["alpha0"])], device=self.device)

    def _restart_flagged(self) -> None:
        """The replicas flagged in ``active`` at rest with a fresh FIRE state; the others untouched."""
        c, T, dev = self.consts, self.dtype, self.device
        wp.launch(self._k["zero_rows_kernel"], dim=self.R * self.nthr,
                  inputs=[self.v, self.row_start, self.active, self.nthr], device=dev)
        wp.launch(self._k["restart_kernel"], dim=self.R,
                  inputs=[self.active, self.status, self.iters, self.steps, self.dt_r, self.alpha_r, self.npos,
                          self.down, self.fmax_out, T(c["dt"]), T(c["alpha0"])], device=dev)
