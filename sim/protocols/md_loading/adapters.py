"""One interface over the two MD systems for :func:`bubblecal.sim.protocols.md_loading.run_md_protocol`.

An adapter exposes the vertex positions ``x``, replica index ``vrep``, ``status``, ``step_counter``, device and
dtype, the replicas' vertex ``offsets`` / ``counts`` and centres ``zc``; ``f()`` (the vertex force array),
``add_callback(cb)`` (a force callback run every step), ``anchor(rows)`` (z-anchored vertex rows),
``advance(n)`` (n MD steps), ``health()`` (one verdict name per replica) and ``positions()``.
"""

import numpy as np

from bubblecal._extras import require
from bubblecal.sim.protocols.md_loading.kernels import md_loading_kernels

wp = require("warp", "sim")

__all__ = ["ImplicitAdapter", "ExplicitAdapter", "ANCHOR_BETA"]

#: Relaxation factor of the explicit tier's z anchoring (package docstring).
ANCHOR_BETA = 0.1


class ImplicitAdapter:
    """An implicit shell system seen by :func:`~bubblecal.sim.protocols.md_loading.run_md_protocol`.

    Parameters
    ----------
    system : bubblecal.sim.engine.implicit.ImplicitShellSystem
        R replicas of one mesh, centred at the origin.
    thresholds : bubblecal.sim.engine.HealthThresholds
        Its health checks.
    """

    def __init__(self, system, thresholds):
        self.s = system
        self.th = thresholds
        self.x, self.vrep, self.status = system.x, system.vrep, system.status
        self.step_counter = system.step_counter
        self.device, self.dtype, self.np_dtype = system.device, system.dtype, system.np_dtype
        self.R = system.R
        self.zc = np.zeros(self.R)  # meshes are centred at the origin
        self.offsets, self.counts = system.offsets, system.n_vertices

    def f(self):
        """The vertex force array (Warp, DPD force)."""
        return self.s.f

    def add_callback(self, cb):
        """Run ``cb()`` after the system's own forces at every step."""
        self.s.add_force_callback(lambda _s: cb())

    def anchor(self, rows: np.ndarray) -> None:
        """Anchor the vertex ``rows`` in z (native in the implicit system)."""
        mask = np.zeros(self.s.N, dtype=bool)
        mask[rows] = True
        self.s.set_anchor_z(mask)

    def advance(self, n: int) -> None:
        """``n`` MD steps."""
        if n > 0:
            self.s.step(n)

    def health(self) -> list[str]:
        """One health verdict name per replica (failed replicas are frozen)."""
        return self.s.check_health(self.th)["status"]

    def positions(self) -> np.ndarray:
        """Vertex positions [N, 3] (float64, DPD length)."""
        return self.s.x.numpy().astype(np.float64)


class ExplicitAdapter:
    """An explicit particle system seen by :func:`~bubblecal.sim.protocols.md_loading.run_md_protocol`; z anchoring
    goes through the force (package docstring).

    Parameters
    ----------
    system : bubblecal.sim.engine.system.ParticleSystem
        R bubble replicas (shell, water, gas).
    monitor : bubblecal.sim.engine.health.HealthMonitor
        Its health checks.
    """

    def __init__(self, system, monitor):
        from bubblecal.sim.engine.particles import VERTEX

        self.s = system
        self.monitor = monitor
        self.x, self.vrep, self.status = system.xv, system.vrep, system.status
        self.step_counter = system.step_counter
        self.device, self.dtype, self.np_dtype = system.device, system.dtype, system.np_dtype
        self.R = system.R
        self.zc = np.array([(np.asarray(sp.box, float) / 2 if sp.center is None else np.asarray(sp.center, float))[2]
                            for sp in system.specs])
        self.offsets, self.counts = system.vertex_offset, system.vertex_count
        self.mass = wp.array(system.mass_np[:, VERTEX].astype(self.np_dtype), dtype=self.dtype, device=self.device)

    def f(self):
        """The vertex force array (Warp, DPD force)."""
        return self.s.fv

    def add_callback(self, cb):
        """Run ``cb()`` after the system's own forces at every step."""
        self.s.force_callbacks.append(lambda _s: cb())

    def anchor(self, rows: np.ndarray) -> None:
        """Anchor the vertex ``rows`` at their current z through the force (applied by
        :meth:`finalize_callbacks`, after every other force callback)."""
        k = md_loading_kernels(self.dtype)
        zref = self.s.xv.numpy()[rows, 2].astype(self.np_dtype)
        rows_w = wp.array(rows.astype(np.int32), dtype=wp.int32, device=self.device)
        zref_w = wp.array(zref, dtype=self.dtype, device=self.device)
        s = self.s
        dt, beta = self.dtype(s.dt), self.dtype(ANCHOR_BETA)

        def cb():
            wp.launch(k["anchor_forces"], dim=len(rows),
                      inputs=[s.xv, s.vv, s.fv, rows_w, zref_w, s.vrep, self.mass, s.status, dt, beta],
                      device=self.device)

        self._anchor_cb = cb  # added last, after the pole forces (it overrides F_z)

    def finalize_callbacks(self):
        """Add the anchoring callback last (it overrides F_z)."""
        if getattr(self, "_anchor_cb", None) is not None:
            self.add_callback(self._anchor_cb)

    def advance(self, n: int) -> None:
        """``n`` MD steps."""
        if n > 0:
            self.s.step(n)

    def health(self) -> list[str]:
        """One health verdict name per replica (failed replicas are frozen)."""
        return self.monitor.check(self.s).status

    def positions(self) -> np.ndarray:
        """Vertex positions [N, 3] (float64, DPD length)."""
        return self.s.xv.numpy().astype(np.float64)
