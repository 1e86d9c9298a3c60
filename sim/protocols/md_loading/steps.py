"""Step counts of the MD loading protocols (published defaults, optionally scaled)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = ["ProtocolSteps", "steps_per_curve"]


@dataclasses.dataclass(frozen=True)
class ProtocolSteps:
    """Step counts of one chained curve (published defaults).

    Parameters
    ----------
    ramp_steps : int
        MD steps per load increment (the linear ramp between two grid points).
    hold_steps : int
        MD steps held at each grid point (>= ``sample_every``).
    sample_every : int
        MD steps between two samples of the observable (>= 1).
    equilibration_steps : int
        MD steps before the first point (a choice: 20,000 = 2 DPD time units at dt = 1e-4).
    discard_fraction : float
        Fraction of the hold's indentation samples dropped before averaging, in [0, 1).

    Raises
    ------
    ValueError
        If a step count is not an integer >= 0, ``sample_every`` < 1, ``hold_steps`` < ``sample_every``, or
        ``discard_fraction`` lies outside [0, 1).
    """

    ramp_steps: int = 40_000
    hold_steps: int = 20_000
    sample_every: int = 400
    equilibration_steps: int = 20_000
    discard_fraction: float = 0.1

    def __post_init__(self) -> None:
        for name in ("ramp_steps", "hold_steps", "sample_every", "equilibration_steps"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
                raise ValueError(f"ProtocolSteps.{name} must be an integer >= 0, got {v!r}")
        if self.sample_every < 1 or self.hold_steps < self.sample_every:
            raise ValueError("ProtocolSteps: need sample_every >= 1 and hold_steps >= sample_every")
        if not (0.0 <= self.discard_fraction < 1.0):
            raise ValueError(f"ProtocolSteps.discard_fraction must lie in [0, 1), got {self.discard_fraction!r}")

    def scaled(self, scale: float) -> ProtocolSteps:
        """Every step count multiplied by ``scale``.

        Parameters
        ----------
        scale : float
            Positive factor; ``sample_every`` stays >= 1 and the hold keeps a whole number (>= 1) of samples.

        Returns
        -------
        ProtocolSteps
            The scaled counts (``self`` when ``scale`` is 1).

        Raises
        ------
        ValueError
            If ``scale`` is not a positive finite number.
        """
        if not (math.isfinite(scale) and scale > 0):
            raise ValueError(f"scale must be a positive number, got {scale!r}")
        if scale == 1.0:
            return self
        se = max(1, int(round(self.sample_every * scale)))
        return dataclasses.replace(self, ramp_steps=int(round(self.ramp_steps * scale)),
                                   hold_steps=max(se, int(round(self.hold_steps * scale / se)) * se),
                                   sample_every=se,
                                   equilibration_steps=int(round(self.equilibration_steps * scale)))


def steps_per_curve(steps: ProtocolSteps, grid) -> int:
    """Total MD steps of one chained curve.

    Parameters
    ----------
    steps : ProtocolSteps
        The step counts.
    grid : array_like
        The loading grid [P] (DPD length for compression, DPD force for indentation); ramps are skipped where
        the load does not change (the first point at 0).

    Returns
    -------
    int
        Equilibration + ramps + holds, in MD steps.
    """
    g = np.asarray(grid, dtype=np.float64)
    n_ramps = int(np.sum(np.diff(np.concatenate([[0.0], g])) != 0))
    return steps.equilibration_steps + n_ramps * steps.ramp_steps + len(g) * steps.hold_steps
