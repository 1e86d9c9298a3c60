"""Fixed-length chunks of device work replayed as one CUDA graph.

Shared by the particle system (:mod:`bubblecal.sim.engine.system`), the implicit shell system
(:mod:`bubblecal.sim.engine.implicit`) and the device FIRE (:mod:`bubblecal.sim.engine.minimize_device`): each calls
``step()`` n times per chunk, and on CUDA the launches of a chunk are captured once and replayed.
"""

from __future__ import annotations

from collections.abc import Callable

from bubblecal._extras import require

wp = require("warp", "sim")

__all__ = ["ChunkGraph"]


class ChunkGraph:
    """Run ``step()`` (Warp launches only) ``n`` times per :meth:`run`, as a CUDA graph when ``enabled``.

    The first chunk runs uncaptured (lazy allocations, e.g. a HashGrid, happen there), the second is captured and
    then launched, later ones replay the graph.  A capture that fails disables graphs for good (plain launches).
    The graph holds the chunk length of its capture: call :meth:`run` with ``capture=True`` only for that length,
    and :meth:`invalidate` after anything the launches bake in changes (reallocated arrays, new callbacks).

    Parameters
    ----------
    step : callable
        One step: Warp launches only (no host synchronisation).
    device : warp device
        The device of the launches.
    enabled : bool
        Use CUDA graphs (only meaningful on CUDA).
    """

    def __init__(self, step: Callable[[], None], device, enabled: bool):
        self.step = step
        self.device = device
        self.enabled = bool(enabled)
        self.graph = None
        self._warm = False

    def invalidate(self) -> None:
        """Drop the captured graph; the next full chunk is captured again."""
        self.graph = None

    def _plain(self, n: int) -> None:
        """Run ``n`` steps as plain launches."""
        for _ in range(n):
            self.step()

    def run(self, n: int, capture: bool = True) -> None:
        """Execute ``n`` steps.

        Parameters
        ----------
        n : int
            Number of steps.
        capture : bool, optional
            False: plain launches (e.g. a shorter last chunk); True: the captured graph of this chunk length.
        """
        if not (self.enabled and capture):
            self._plain(n)
            return
        if not self._warm:
            self._warm = True
            self._plain(n)
            return
        if self.graph is None:
            try:
                with wp.ScopedCapture(device=self.device, force_module_load=True) as cap:
                    self._plain(n)  # recorded, not executed: the launch below runs them
                self.graph = cap.graph
            except Exception:  # pragma: no cover - capture unsupported -> plain launches
                self.enabled = False
                self.graph = None
                self._plain(n)
                return
        wp.capture_launch(self.graph)
