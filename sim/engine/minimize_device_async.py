"""Replica-asynchronous use of :class:`~bubblecal.sim.engine.minimize_device.DeviceFire` (a mixin of it).

Each replica is (re)started on its own and reported when it stops: :meth:`ReplicaAsyncFire.begin` freezes every
replica, :meth:`~ReplicaAsyncFire.restart` starts a group, :meth:`~ReplicaAsyncFire.advance` runs
``sync_every`` iterations and returns the status codes, and :meth:`~ReplicaAsyncFire.export_rows` /
:meth:`~ReplicaAsyncFire.import_rows` move replicas between minimisers with the same iterates.  Units are the
caller's (the quasi-static tier uses DPD units).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.fire import NONFINITE

wp = require("warp", "sim")

__all__ = ["ReplicaAsyncFire"]


class ReplicaAsyncFire:
    """Replica-asynchronous minimisation methods of :class:`~bubblecal.sim.engine.minimize_device.DeviceFire`."""

    def begin(self, ftol: float | np.ndarray = 1e-3, max_steps: int = 10_000) -> None:
        """Prepare replica-asynchronous minimisation and freeze every replica.

        :meth:`restart` then starts replicas one group at a time, :meth:`advance` runs them.

        Parameters
        ----------
        ftol : float or numpy.ndarray, optional
            Convergence threshold (force unit), scalar or [R].
        max_steps : int, optional
            Maximum FIRE updates per start.

        Raises
        ------
        ValueError
            On a negative ``max_steps``.
        """
        if int(max_steps) < 0:
            raise ValueError(f"max_steps must be >= 0, got {max_steps!r}")
        tol = np.broadcast_to(np.asarray(ftol, dtype=np.float64), (self.R,))
        self.tol.assign(tol.astype(self._np))
        self.max_steps.assign(np.array([int(max_steps)], dtype=np.int32))
        self.v.zero_()
        self.f.zero_()
        self.active.zero_()
        c, T = self.consts, self.dtype
        wp.launch(self._k["reset_kernel"], dim=self.R,
                  inputs=[self.active, self.status, self.iters, self.steps, self.dt_r, self.alpha_r, self.npos,
                          self.down, self.fmax_out, self.fmax_acc, self.fsq_acc, self.pow_acc, self.nonfin,
                          self.vsq_acc, self.mean_acc, T(c["dt"]), T(c["alpha0"])], device=self.device)

    def restart(self, flags: np.ndarray) -> None:
        """Start FIRE afresh (zero velocity, initial dt and alpha, step count 0) on flagged replicas.

        They start from their current positions; the other replicas keep their state and go on.

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
        c, T, dev = self.consts, self.dtype, self.device
        wp.launch(self._k["zero_rows_kernel"], dim=self.R * self.nthr,
                  inputs=[self.v, self.row_start, self.active, self.nthr], device=dev)
        wp.launch(self._k["restart_kernel"], dim=self.R,
                  inputs=[self.active, self.status, self.iters, self.steps, self.dt_r, self.alpha_r, self.npos,
                          self.down, self.fmax_out, T(c["dt"]), T(c["alpha0"])], device=dev)

    _REPLICA_STATE = ("active", "status", "iters", "steps", "npos", "down", "nonfin", "dt_r", "alpha_r", "fnorm",
                      "fmax_out", "fmax_acc", "fsq_acc", "pow_acc", "vsq_acc", "mean_acc", "tol")

    def export_rows(self, replicas: Sequence[int] | np.ndarray) -> dict:
        """Complete FIRE state of some replicas (host copies), for :meth:`import_rows` of another DeviceFire.

        Their particle rows of x, v, f and every per-replica scalar, so that another minimiser continues them with
        the same iterates (the last few relaxing replicas of a big batch run faster in a small one).

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
        out = {name: getattr(self, name).numpy()[rows] for name in ("x", "v", "f")}
        out.update({name: getattr(self, name).numpy()[idx] for name in self._REPLICA_STATE})
        out["max_steps"] = self.max_steps.numpy().copy()
        out["sizes"] = (rs[idx + 1] - rs[idx]) if idx.size else np.zeros(0, np.int64)
        return out

    def import_rows(self, state: Mapping[str, np.ndarray]) -> None:
        """Take over the state exported by :meth:`export_rows` of another DeviceFire (same dtype).

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
        for name in ("x", "v", "f"):
            arr = getattr(self, name)
            full = arr.numpy()
            full[:n] = state[name]
            arr.assign(full)
        for name in self._REPLICA_STATE:
            getattr(self, name).assign(np.asarray(state[name]))
        self.max_steps.assign(np.asarray(state["max_steps"]))

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
            [R] FIRE updates.
        fmax : numpy.ndarray
            [R] largest per-row force norm at the last convergence test (force unit; inf where non-finite).
        """
        st = self.status.numpy()
        fmax = np.where(st == NONFINITE, np.inf, self.fmax_out.numpy().astype(np.float64))
        return self.steps.numpy().astype(np.int64), fmax
