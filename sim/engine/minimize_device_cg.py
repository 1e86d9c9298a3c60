"""Batched nonlinear conjugate gradient whose whole state lives on a Warp device (CPU or CUDA).

Same rules as the NumPy reference :func:`bubblecal.sim.engine.minimize_cg.cg_minimize` (Polak-Ribiere+, a bracketing
secant line search on the directional force alone, convergence ``max_i |F_i| <= ftol`` tested at every evaluated
point), each replica with its own line state; the kernels are :mod:`bubblecal.sim.engine.kernels.cg`.  Forces,
projection (fixed components, mean-force removal), layout, status loop and replica-asynchronous use are those of
:class:`bubblecal.sim.engine.minimize_device_base.DeviceMinimizer`: a drop-in for
:class:`~bubblecal.sim.engine.minimize_device.DeviceFire` where no energy is available and FIRE's linear tail
dominates (buckled shells: docs/decisions.md, "FIRE work of compression at large sizes").

One iteration is one force evaluation; ``steps`` counts evaluations - 1 (a replica converged at its start reports 0).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.engine.kernels.cg import cg_kernels
from bubblecal.sim.engine.kernels.fire import fire_kernels
from bubblecal.sim.engine.minimize_cg import CG_DEFAULTS
from bubblecal.sim.engine.minimize_device_base import DeviceMinimizer

wp = require("warp", "sim")

__all__ = ["DeviceCG"]


class DeviceCG(DeviceMinimizer):
    """Batched nonlinear CG with device-resident state (see the module docstring).

    Parameters
    ----------
    row_start, force_fn, device, dtype, n_rows, free, remove_mean, sync_every, threads_per_replica, use_graph
        The replica layout, forces and execution, as for
        :class:`~bubblecal.sim.engine.minimize_device_base.DeviceMinimizer`.
    first_alpha, first_move, grow, accept, max_trials : optional
        Line-search constants of :func:`bubblecal.sim.engine.minimize_cg.cg_minimize` (``first_move`` in the
        caller's length unit).

    Raises
    ------
    ValueError
        On a bad layout (as the base) or a non-positive line-search constant.
    """

    _ROW_STATE = ("x", "f", "d", "f_b")
    _REPLICA_STATE = ("active", "status", "iters", "steps", "trials", "action", "nonfin", "fmax_out", "beta", "ls",
                      "red", "dn_acc", "mean_acc", "tol")

    def __init__(self, row_start: Sequence[int] | np.ndarray, force_fn: Callable, *, device: str = "cpu",
                 dtype=wp.float64, n_rows: int | None = None, free: np.ndarray | None = None,
                 remove_mean: Sequence[bool] = (False, False, False), sync_every: int | None = None,
                 threads_per_replica: int | None = None, use_graph: bool | None = None,
                 first_alpha: float = CG_DEFAULTS["first_alpha"], first_move: float = CG_DEFAULTS["first_move"],
                 grow: float = CG_DEFAULTS["grow"], accept: float = CG_DEFAULTS["accept"],
                 max_trials: int = CG_DEFAULTS["max_trials"]):
        if not min(first_alpha, first_move, grow, accept, max_trials) > 0:
            raise ValueError("the line-search constants must be positive")
        super().__init__(row_start, force_fn, device=device, dtype=dtype, n_rows=n_rows, free=free,
                         remove_mean=remove_mean, sync_every=sync_every, threads_per_replica=threads_per_replica,
                         use_graph=use_graph)
        self._k = cg_kernels(dtype)
        self._mean_kernel = fire_kernels(dtype)["mean_accum_kernel"]
        self.consts = dict(first_alpha=float(first_alpha), first_move=float(first_move), grow=float(grow),
                           accept=float(accept), max_trials=int(max_trials))
        n, R, dev, T, V = self.n_rows, self.R, self.device, dtype, self.vec3
        self.d = wp.zeros(n, dtype=V, device=dev)
        self.f_b = wp.zeros(n, dtype=V, device=dev)
        self.trials = wp.zeros(R, dtype=wp.int32, device=dev)
        self.action = wp.zeros(R, dtype=wp.int32, device=dev)
        self.beta = wp.zeros(R, dtype=T, device=dev)
        self.dn_acc = wp.zeros(R, dtype=T, device=dev)
        self.red = wp.zeros((R, 4), dtype=T, device=dev)
        self.ls = wp.zeros((R, 10), dtype=T, device=dev)

    def _reset_all(self) -> None:
        """``active`` replicas ACTIVE at their first evaluation, the others FROZEN."""
        for a in (self.f, self.d, self.f_b, self.red, self.dn_acc, self.nonfin, self.mean_acc):
            a.zero_()
        wp.launch(self._k["reset_kernel"], dim=self.R,
                  inputs=[self.active, 0, self.status, self.iters, self.steps, self.trials, self.action,
                          self.fmax_out, self.beta], device=self.device)

    def _restart_flagged(self) -> None:
        """The replicas flagged in ``active`` at their first evaluation; the others untouched."""
        wp.launch(self._k["reset_kernel"], dim=self.R,
                  inputs=[self.active, 1, self.status, self.iters, self.steps, self.trials, self.action,
                          self.fmax_out, self.beta], device=self.device)

    def _iteration(self) -> None:
        """One evaluation of every replica: forces, projection and reductions, line-search decision, row moves."""
        k, dev, c, T = self._k, self.device, self.consts, self.dtype
        dimv = self.R * self.nthr
        self.force_fn(self.x, self.f)
        if self.remove_mean:
            wp.launch(self._mean_kernel, dim=dimv,
                      inputs=[self.f, self.row_start, self.status, self.nthr, self.mean_acc], device=dev)
        wp.launch(k["project_reduce_kernel"], dim=dimv,
                  inputs=[self.f, self.d, self.f_b, self.free, self.row_start, self.status, self.nthr,
                          self.mean_comps, self.mean_acc, self.red, self.nonfin], device=dev)
        wp.launch(k["replica_kernel"], dim=self.R,
                  inputs=[self.status, self.iters, self.steps, self.trials, self.action, self.max_steps, self.tol,
                          self.red, self.nonfin, self.mean_acc, self.fmax_out, self.beta, self.ls,
                          T(c["first_alpha"]), T(c["first_move"]), T(c["grow"]), T(c["accept"]),
                          c["max_trials"]], device=dev)
        wp.launch(k["direction_kernel"], dim=dimv,
                  inputs=[self.x, self.f, self.d, self.f_b, self.row_start, self.action, self.nthr, self.beta,
                          self.ls, self.dn_acc], device=dev)
        wp.launch(k["first_step_kernel"], dim=self.R,
                  inputs=[self.action, self.ls, self.dn_acc, T(c["first_alpha"]), T(c["first_move"]), T(c["grow"])],
                  device=dev)
        wp.launch(k["line_move_kernel"], dim=dimv,
                  inputs=[self.x, self.d, self.row_start, self.action, self.nthr, self.ls], device=dev)
