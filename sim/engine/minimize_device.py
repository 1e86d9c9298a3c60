"""Batched FIRE minimiser whose whole state lives on a Warp device (CPU or CUDA).

Same rules as the NumPy reference :func:`bubblecal.sim.engine.minimize.fire_minimize` (FIRE 2.0: per-replica
time step, mixing, ``n_pos`` counter, half-step correction on an uphill step, ``max_move`` cap per
row, per-replica convergence test ``max_i |F_i| <= ftol`` over the free components, frozen replicas,
``nonfinite`` status), but positions ``x``, velocities ``v``, forces ``F`` and the per-replica state
(``dt``, ``alpha``, ``n_pos``, P = sum F.v, |F|^2, |v|^2, fmax, flags) are Warp arrays, updated by
the kernels of :mod:`bubblecal.sim.engine.kernels.fire`.  The host only reads the per-replica status
every ``sync_every`` iterations; on CUDA those iterations are captured once as a CUDA graph and
replayed.  Replica-asynchronous use (restart, export / import of replicas):
:mod:`bubblecal.sim.engine.minimize_device_async`.

Replica r owns the contiguous rows ``[row_start[r], row_start[r+1])``.  Forces come from a
``force_fn(x, f)`` that *adds* -dE/dx into ``f`` (zeroed before every call) with Warp launches only;
with graph capture on, every input that changes between minimisations (loads, plate positions)
must live in device arrays read by those kernels.  The optional mean-force removal
(``remove_mean``, per component) pins the centre of mass: the replica's mean force is subtracted
before the fixed components (``free``) are zeroed, as in the NumPy reference.

Iteration i of a replica = force evaluation, convergence test, FIRE update; ``steps`` counts the
updates exactly as the NumPy version does (a replica converged at its first test reports 0).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.engine.graphs import ChunkGraph
from bubblecal.sim.engine.kernels.fire import ACTIVE, CONVERGED, FROZEN, MAX_STEPS, NONFINITE, fire_kernels
from bubblecal.sim.engine.minimize_device_async import ReplicaAsyncFire

wp = require("warp", "sim")

__all__ = ["DeviceFire", "DeviceFireResult", "numpy_force_fn", "STATUS_NAMES", "cuda_threads_per_replica"]

#: status code -> name (names shared with :mod:`bubblecal.sim.engine.minimize`, plus ``"frozen"``)
STATUS_NAMES = {ACTIVE: "max_steps", CONVERGED: "converged", MAX_STEPS: "max_steps", NONFINITE: "nonfinite",
                FROZEN: "frozen"}


@dataclass
class DeviceFireResult:
    """Outcome of :meth:`DeviceFire.minimize`; per-replica arrays have length R.

    Attributes
    ----------
    status : list of str
        ``'converged'``, ``'max_steps'``, ``'nonfinite'`` or ``'frozen'`` per replica.
    converged : numpy.ndarray
        [R] bool.
    steps : numpy.ndarray
        [R] FIRE updates.
    fmax : numpy.ndarray
        [R] largest per-row force norm over the free components at the last test (force unit; inf if
        non-finite, NaN if frozen).
    n_evaluations : int
        Force evaluations launched, including no-op iterations of a finished chunk.
    n_syncs : int
        Host reads of the status.
    seconds : float
        Wall time (s).
    """

    status: list[str]
    converged: np.ndarray
    steps: np.ndarray
    fmax: np.ndarray
    n_evaluations: int
    n_syncs: int
    seconds: float

    @property
    def all_converged(self) -> bool:
        """Whether every replica converged."""
        return bool(np.all(self.converged))


def cuda_threads_per_replica(n_replicas: int, max_rows: int, min_threads: int = 64, max_threads: int = 1024,
                             target_threads: int = 16384) -> int:
    """Threads per replica of the FIRE row passes on a GPU.

    64 for big batches, doubled (up to ``max_threads``) while the launch holds fewer than ``target_threads``
    threads, never more than a replica's rows: each thread walks its replica's rows with stride T, so with few
    replicas the loop's memory latency sets the iteration time (benchmarks/RESULTS.md).

    Parameters
    ----------
    n_replicas : int
        Replicas R.
    max_rows : int
        Rows of the largest replica.
    min_threads, max_threads : int, optional
        Bounds on the threads per replica.
    target_threads : int, optional
        Threads per launch worth reaching.

    Returns
    -------
    int
    """
    t = int(min_threads)
    while t < max_threads and n_replicas * t < target_threads:
        t *= 2
    return max(1, min(t, int(max_rows)))


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


class DeviceFire(ReplicaAsyncFire):
    """Batched FIRE with device-resident state (see the module docstring).

    Parameters
    ----------
    row_start : sequence of int
        [R + 1] first row of each replica (contiguous blocks; rows past ``row_start[-1]`` never move).
    force_fn : callable
        ``force_fn(x, f)`` adds forces (-dE/dx) into ``f`` with Warp launches only.
    device : str, optional
        Warp device.
    dtype : warp scalar type, optional
        ``wp.float64`` (default) or ``wp.float32``.
    n_rows : int, optional
        Rows of the position arrays (default ``row_start[-1]``).
    free : numpy.ndarray, optional
        [N, 3] bool mask of the components that may move (default all).
    mass : float or numpy.ndarray, optional
        Scalar or per-row FIRE mass.
    remove_mean : sequence of bool, optional
        Per component, subtract the replica's mean force.
    dt, dt_max, dt_min, max_move, n_delay, f_inc, f_dec, alpha0, f_alpha : optional
        FIRE constants as in :func:`bubblecal.sim.engine.minimize.fire_minimize` (dt_max default 10 dt, dt_min
        dt / 50, ``max_move`` None: no cap), in the caller's time / length units.
    sync_every : int, optional
        Iterations between host status checks (default 25 on CUDA, 4 on the CPU).
    threads_per_replica : int, optional
        Threads per replica of the row passes (default on CUDA :func:`cuda_threads_per_replica`, 1 on the CPU).
    use_graph : bool, optional
        Capture ``sync_every`` iterations as a CUDA graph (default: on CUDA when ``force_fn`` is capturable;
        plain launches if capture fails).

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
        if dtype not in (wp.float32, wp.float64):
            raise ValueError(f"dtype must be wp.float32 or wp.float64, got {dtype!r}")
        rs = np.asarray(row_start, dtype=np.int64)
        if rs.ndim != 1 or rs.size < 2 or rs[0] < 0 or np.any(np.diff(rs) <= 0):
            raise ValueError("row_start must be increasing, >= 0, with at least one non-empty replica")
        self.R = int(rs.size - 1)
        self.n_rows = int(rs[-1]) if n_rows is None else int(n_rows)
        if self.n_rows < rs[-1]:
            raise ValueError("n_rows is smaller than row_start[-1]")
        if not (dt > 0 and math.isfinite(dt)):
            raise ValueError(f"dt must be a positive finite time, got {dt!r}")
        self.device = wp.get_device(device)
        self.dtype = dtype
        self.vec3 = wp.vec3d if dtype is wp.float64 else wp.vec3f
        self._np = np.float64 if dtype is wp.float64 else np.float32
        self.force_fn = force_fn
        self._k = fire_kernels(dtype)
        cuda = self.device.is_cuda
        self.sync_every = int(sync_every) if sync_every else (25 if cuda else 4)
        if self.sync_every < 1:
            raise ValueError("sync_every must be >= 1")
        max_rows = int(np.max(np.diff(rs)))
        self.nthr = int(threads_per_replica) if threads_per_replica else (
            cuda_threads_per_replica(self.R, max_rows) if cuda else 1)
        capturable = bool(getattr(force_fn, "capturable", True))
        self._chunks = ChunkGraph(self._iteration, self.device,
                                  cuda and capturable and (True if use_graph is None else bool(use_graph)))
        self.consts = dict(dt=float(dt), dt_max=10.0 * dt if dt_max is None else float(dt_max),
                           dt_min=dt / 50.0 if dt_min is None else float(dt_min),
                           max_move=-1.0 if max_move is None else float(max_move), n_delay=int(n_delay),
                           f_inc=float(f_inc), f_dec=float(f_dec), alpha0=float(alpha0), f_alpha=float(f_alpha))
        n, R, dev, T, V = self.n_rows, self.R, self.device, dtype, self.vec3
        fr = np.ones((n, 3), dtype=bool) if free is None else np.asarray(free, dtype=bool)
        if fr.shape != (n, 3):
            raise ValueError(f"free must be a [{n}, 3] boolean mask")
        inv_m = 1.0 / np.broadcast_to(np.asarray(mass, dtype=np.float64), (n,))
        self.row_start = wp.array(rs.astype(np.int32), dtype=wp.int32, device=dev)
        self.x = wp.zeros(n, dtype=V, device=dev)
        self.v = wp.zeros(n, dtype=V, device=dev)
        self.f = wp.zeros(n, dtype=V, device=dev)
        self.free = wp.array(fr.astype(self._np), dtype=V, device=dev)
        self.inv_mass = wp.array(inv_m.astype(self._np), dtype=T, device=dev)
        self.mean_comps = V(*[1.0 if c else 0.0 for c in remove_mean])
        self.remove_mean = bool(any(remove_mean))
        z = lambda dt_=T: wp.zeros(R, dtype=dt_, device=dev)  # noqa: E731
        self.active = z(wp.int32)
        self.status = z(wp.int32)
        self.iters = z(wp.int32)
        self.steps = z(wp.int32)
        self.npos = z(wp.int32)
        self.down = z(wp.int32)
        self.nonfin = z(wp.int32)
        self.dt_r, self.alpha_r, self.fnorm, self.fmax_out = z(), z(), z(), z()
        self.fmax_acc, self.fsq_acc, self.pow_acc, self.vsq_acc = z(), z(), z(), z()
        self.mean_acc = wp.zeros(R, dtype=V, device=dev)
        self.tol = z()
        self.max_steps = wp.zeros(1, dtype=wp.int32, device=dev)

    # ------------------------------------------------------------------------------------------
    def set_positions(self, x: np.ndarray) -> None:
        """Copy host positions onto the device.

        Parameters
        ----------
        x : numpy.ndarray
            [n_rows, 3] positions (caller's length unit).
        """
        self.x.assign(np.ascontiguousarray(x, dtype=self._np))

    def positions(self) -> np.ndarray:
        """Device positions (synchronises).

        Returns
        -------
        numpy.ndarray
            [n_rows, 3] float64.
        """
        return self.x.numpy().astype(np.float64)

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

    @property
    def use_graph(self) -> bool:
        """Whether the ``sync_every`` iterations between status checks replay as one CUDA graph."""
        return self._chunks.enabled

    def minimize(self, ftol: float | np.ndarray = 1e-3, max_steps: int = 10_000,
                 active: np.ndarray | None = None) -> DeviceFireResult:
        """Minimise every active replica from the current device positions ``self.x``.

        Parameters
        ----------
        ftol : float or numpy.ndarray, optional
            Convergence threshold on the largest per-row force norm (force unit), scalar or [R].
        max_steps : int, optional
            Maximum FIRE updates per replica.
        active : numpy.ndarray, optional
            [R] bool, replicas taking part (the others keep their rows and report 'frozen').

        Returns
        -------
        DeviceFireResult
            Positions stay on the device (``self.x`` / :meth:`positions`).

        Raises
        ------
        ValueError
            On a negative ``max_steps`` or a wrong ``active`` shape.
        """
        t0 = time.perf_counter()
        R, dev, c = self.R, self.device, self.consts
        if int(max_steps) < 0:
            raise ValueError(f"max_steps must be >= 0, got {max_steps!r}")
        act = np.ones(R, dtype=bool) if active is None else np.asarray(active, dtype=bool)
        if act.shape != (R,):
            raise ValueError(f"active must hold one flag per replica ({R})")
        tol = np.broadcast_to(np.asarray(ftol, dtype=np.float64), (R,))
        self.tol.assign(tol.astype(self._np))
        self.max_steps.assign(np.array([int(max_steps)], dtype=np.int32))
        self.active.assign(act.astype(np.int32))
        self.v.zero_()
        self.f.zero_()
        T = self.dtype
        wp.launch(self._k["reset_kernel"], dim=R,
                  inputs=[self.active, self.status, self.iters, self.steps, self.dt_r, self.alpha_r, self.npos,
                          self.down, self.fmax_out, self.fmax_acc, self.fsq_acc, self.pow_acc, self.nonfin,
                          self.vsq_acc, self.mean_acc, T(c["dt"]), T(c["alpha0"])], device=dev)
        n_eval = n_sync = 0
        max_chunks = (int(max_steps) + 1) // self.sync_every + 2
        st = np.where(act, ACTIVE, FROZEN).astype(np.int32)
        if act.any():
            for _ in range(max_chunks):
                self._chunks.run(self.sync_every)
                n_eval += self.sync_every
                st = self.status.numpy()
                n_sync += 1
                if not np.any(st == ACTIVE):
                    break
        fmax = self.fmax_out.numpy().astype(np.float64)
        fmax = np.where(st == NONFINITE, np.inf, fmax)
        fmax = np.where(st == FROZEN, np.nan, fmax)
        status = [STATUS_NAMES[int(s)] for s in st]
        return DeviceFireResult(status=status, converged=st == CONVERGED,
                                steps=self.steps.numpy().astype(np.int64), fmax=fmax, n_evaluations=n_eval,
                                n_syncs=n_sync, seconds=time.perf_counter() - t0)
