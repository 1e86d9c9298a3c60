"""What the device-resident batched minimisers share: the replica layout, the status loop and replica-asynchronous use.

:class:`DeviceMinimizer` is the base of :class:`~bubblecal.sim.engine.minimize_device.DeviceFire` and
:class:`~bubblecal.sim.engine.minimize_device_cg.DeviceCG`.  Replica r owns the contiguous rows
``[row_start[r], row_start[r+1])``.  Forces come from a ``force_fn(x, f)`` that *adds* -dE/dx into ``f`` (zero before
every call) with Warp launches only; with graph capture on, every input that changes between minimisations must live
in device arrays.  The host only reads the per-replica status every ``sync_every`` iterations (one force evaluation
each); on CUDA those iterations replay as one CUDA graph.

Replica-asynchronous use: :meth:`DeviceMinimizer.begin` freezes every replica, :meth:`~DeviceMinimizer.restart` starts
a group, :meth:`~DeviceMinimizer.advance` runs ``sync_every`` iterations and returns the status codes, and
:meth:`~DeviceMinimizer.export_rows` / :meth:`~DeviceMinimizer.import_rows` move replicas between minimisers of the
same kind with the same iterates.  Units are the caller's (the quasi-static tier uses DPD units).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.engine.graphs import ChunkGraph
from bubblecal.sim.engine.kernels.fire import ACTIVE, CONVERGED, FROZEN, MAX_STEPS, NONFINITE

wp = require("warp", "sim")

__all__ = ["DeviceMinimizer", "DeviceMinimizeResult", "STATUS_NAMES", "cuda_threads_per_replica"]

#: status code -> name (names shared with :mod:`bubblecal.sim.engine.minimize`, plus ``"frozen"``)
STATUS_NAMES = {ACTIVE: "max_steps", CONVERGED: "converged", MAX_STEPS: "max_steps", NONFINITE: "nonfinite",
                FROZEN: "frozen"}


@dataclass
class DeviceMinimizeResult:
    """Outcome of :meth:`DeviceMinimizer.minimize`; per-replica arrays have length R.

    Attributes
    ----------
    status : list of str
        ``'converged'``, ``'max_steps'``, ``'nonfinite'`` or ``'frozen'`` per replica.
    converged : numpy.ndarray
        [R] bool.
    steps : numpy.ndarray
        [R] updates (force evaluations - 1).
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
    """Threads per replica of the minimisers' row passes on a GPU.

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


class DeviceMinimizer:
    """Replica layout, status loop and replica-asynchronous methods of the device minimisers (module docstring).

    A subclass allocates its own state after ``super().__init__`` and provides ``_iteration()`` (one force evaluation
    and update of every replica), ``_reset_all()`` (fresh state: ``active`` replicas ACTIVE, the others FROZEN) and
    ``_restart_flagged()`` (fresh state for the replicas flagged in ``active``, the others untouched), and names its
    per-row and per-replica arrays in ``_ROW_STATE`` / ``_REPLICA_STATE`` (what :meth:`export_rows` copies).

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
    remove_mean : sequence of bool, optional
        Per component, subtract the replica's mean force (pins the centre of mass).
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
        On a bad ``dtype``, ``row_start``, ``n_rows``, ``sync_every`` or ``free`` shape.
    """

    _ROW_STATE: tuple[str, ...] = ("x", "f")
    _REPLICA_STATE: tuple[str, ...] = ()

    def __init__(self, row_start: Sequence[int] | np.ndarray, force_fn: Callable, *, device: str = "cpu",
                 dtype=wp.float64, n_rows: int | None = None, free: np.ndarray | None = None,
                 remove_mean: Sequence[bool] = (False, False, False), sync_every: int | None = None,
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
        self.device = wp.get_device(device)
        self.dtype = dtype
        self.vec3 = wp.vec3d if dtype is wp.float64 else wp.vec3f
        self._np = np.float64 if dtype is wp.float64 else np.float32
        self.force_fn = force_fn
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
        n, R, dev, V = self.n_rows, self.R, self.device, self.vec3
        fr = np.ones((n, 3), dtype=bool) if free is None else np.asarray(free, dtype=bool)
        if fr.shape != (n, 3):
            raise ValueError(f"free must be a [{n}, 3] boolean mask")
        self.row_start = wp.array(rs.astype(np.int32), dtype=wp.int32, device=dev)
        self.x = wp.zeros(n, dtype=V, device=dev)
        self.f = wp.zeros(n, dtype=V, device=dev)
        self.free = wp.array(fr.astype(self._np), dtype=V, device=dev)
        self.mean_comps = V(*[1.0 if c else 0.0 for c in remove_mean])
        self.remove_mean = bool(any(remove_mean))
        self.mean_acc = wp.zeros(R, dtype=V, device=dev)
        self.active, self.status, self.iters, self.steps, self.nonfin = (
            wp.zeros(R, dtype=wp.int32, device=dev) for _ in range(5))
        self.fmax_out = wp.zeros(R, dtype=dtype, device=dev)
        self.tol = wp.zeros(R, dtype=dtype, device=dev)
        self.max_steps = wp.zeros(1, dtype=wp.int32, device=dev)

    # ----- hooks of the subclasses (class docstring) -----
    def _iteration(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    _reset_all = _restart_flagged = _iteration

    # ----- positions -----
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

    @property
    def use_graph(self) -> bool:
        """Whether the ``sync_every`` iterations between status checks replay as one CUDA graph."""
        return self._chunks.enabled

    # ----- one minimisation of the whole batch -----
    def _prepare(self, ftol, max_steps: int) -> None:
        """Tolerances and the step budget of the next minimisation."""
        if int(max_steps) < 0:
            raise ValueError(f"max_steps must be >= 0, got {max_steps!r}")
        tol = np.broadcast_to(np.asarray(ftol, dtype=np.float64), (self.R,))
        self.tol.assign(tol.astype(self._np))
        self.max_steps.assign(np.array([int(max_steps)], dtype=np.int32))

    def minimize(self, ftol: float | np.ndarray = 1e-3, max_steps: int = 10_000,
                 active: np.ndarray | None = None) -> DeviceMinimizeResult:
        """Minimise every active replica from the current device positions ``self.x``.

        Parameters
        ----------
        ftol : float or numpy.ndarray, optional
            Convergence threshold on the largest per-row force norm (force unit), scalar or [R].
        max_steps : int, optional
            Maximum updates per replica.
        active : numpy.ndarray, optional
            [R] bool, replicas taking part (the others keep their rows and report 'frozen').

        Returns
        -------
        DeviceMinimizeResult
            Positions stay on the device (``self.x`` / :meth:`positions`).

        Raises
        ------
        ValueError
            On a negative ``max_steps`` or a wrong ``active`` shape.
        """
        t0 = time.perf_counter()
        R = self.R
        act = np.ones(R, dtype=bool) if active is None else np.asarray(active, dtype=bool)
        if act.shape != (R,):
            raise ValueError(f"active must hold one flag per replica ({R})")
        self._prepare(ftol, max_steps)
        self.active.assign(act.astype(np.int32))
        self._reset_all()
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
        return DeviceMinimizeResult(status=status, converged=st == CONVERGED,
                                    steps=self.steps.numpy().astype(np.int64), fmax=fmax, n_evaluations=n_eval,
                                    n_syncs=n_sync, seconds=time.perf_counter() - t0)

    # ----- replica-asynchronous use -----
    def begin(self, ftol: float | np.ndarray = 1e-3, max_steps: int = 10_000) -> None:
        """Prepare replica-asynchronous minimisation and freeze every replica.

        Parameters
        ----------
        ftol : float or numpy.ndarray, optional
            Convergence threshold (force unit), scalar or [R].
        max_steps : int, optional
            Maximum updates per start.

        Raises
        ------
        ValueError
            On a negative ``max_steps``.
        """
        self._prepare(ftol, max_steps)
        self.active.zero_()
        self._reset_all()

    def restart(self, flags: np.ndarray) -> None:
        """Start afresh (fresh minimiser state, step count 0) on flagged replicas, from their current positions.

        The other replicas keep their state and go on.

        Parameters
        ----------
        flags : numpy.ndarray
            [R] bool.

        Raises
        ------
        ValueError
            On a wrong shape.
        """
        fl = np.asarray(flags, dtype=bool)
        if fl.shape != (self.R,):
            raise ValueError(f"flags must hold one flag per replica ({self.R})")
        if not fl.any():
            return
        self.active.assign(fl.astype(np.int32))
        self._restart_flagged()

    def advance(self) -> np.ndarray:
        """Run ``sync_every`` iterations (one CUDA-graph replay) and read the status.

        Returns
        -------
        numpy.ndarray
            [R] status codes (``ACTIVE`` while a replica still relaxes).
        """
        self._chunks.run(self.sync_every)
        return self.status.numpy()

    def replica_report(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-replica progress of the current or last minimisation.

        Returns
        -------
        steps : numpy.ndarray
            [R] updates.
        fmax : numpy.ndarray
            [R] largest per-row force norm at the last convergence test (force unit; inf where non-finite).
        """
        st = self.status.numpy()
        fmax = np.where(st == NONFINITE, np.inf, self.fmax_out.numpy().astype(np.float64))
        return self.steps.numpy().astype(np.int64), fmax

    def export_rows(self, replicas: Sequence[int] | np.ndarray) -> dict:
        """Complete minimiser state of some replicas (host copies), for :meth:`import_rows` of another minimiser.

        Every per-row and per-replica array, so that another minimiser of the same kind continues them with the
        same iterates (the last relaxing replicas of a big batch run faster in a small one).

        Parameters
        ----------
        replicas : sequence of int
            Replica indices.

        Returns
        -------
        dict of numpy.ndarray
        """
        idx = np.asarray(replicas, dtype=np.int64).reshape(-1)
        rs = self.row_start.numpy().astype(np.int64)
        rows = np.concatenate([np.arange(rs[r], rs[r + 1]) for r in idx]) if idx.size else np.zeros(0, np.int64)
        out = {name: getattr(self, name).numpy()[rows] for name in self._ROW_STATE}
        out.update({name: getattr(self, name).numpy()[idx] for name in self._REPLICA_STATE})
        out["max_steps"] = self.max_steps.numpy().copy()
        out["sizes"] = (rs[idx + 1] - rs[idx]) if idx.size else np.zeros(0, np.int64)
        return out

    def import_rows(self, state: Mapping[str, np.ndarray]) -> None:
        """Take over the state exported by :meth:`export_rows` of another minimiser of this kind (same dtype).

        Parameters
        ----------
        state : mapping
            The exported state; this minimiser must have exactly that many replicas with the same row counts, in
            the same order.

        Raises
        ------
        ValueError
            When the replica sizes do not match.
        """
        sizes = np.asarray(state["sizes"], dtype=np.int64)
        rs = self.row_start.numpy().astype(np.int64)
        if sizes.shape != (self.R,) or np.any(np.diff(rs) != sizes):
            raise ValueError(f"import_rows: {len(sizes)} replicas of sizes {sizes.tolist()[:4]}... do not match "
                             f"this minimiser's {self.R} replicas")
        n = int(rs[-1])
        for name in self._ROW_STATE:
            arr = getattr(self, name)
            full = arr.numpy()
            full[:n] = state[name]
            arr.assign(full)
        for name in self._REPLICA_STATE:
            getattr(self, name).assign(np.asarray(state[name]))
        self.max_steps.assign(np.asarray(state["max_steps"]))
