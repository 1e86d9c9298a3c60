"""Settings of the quasi-static tier: the enclosed gas, the FIRE controls, point statuses, schedules, and the
checks of the arguments every quasi-static run shares."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from bubblecal.sim.engine.kernels.shell import ShellParams
    from bubblecal.sim.engine.mesh import ShellMesh

__all__ = [
    "IdealGas",
    "FireSettings",
    "SCHEDULES",
    "MINIMIZERS",
    "STATUS_OK",
    "STATUS_NOT_CONVERGED",
    "STATUS_NONFINITE",
    "STATUS_RUPTURED",
    "STATUS_COLLAPSED",
]

#: Point / curve verdicts of the quasi-static chain (the tier maps them to bubblecal.data.names.STATUSES).
STATUS_OK = "ok"
STATUS_NOT_CONVERGED = "not_converged"
STATUS_NONFINITE = "nonfinite"
STATUS_RUPTURED = "ruptured"
#: indentation only: the depth fell under the rising force (:mod:`bubblecal.sim.tiers.quasistatic.collapse`)
STATUS_COLLAPSED = "collapsed"
_FAILED = (STATUS_NONFINITE, STATUS_RUPTURED)
#: Minimisers of the load points (:class:`FireSettings`).
MINIMIZERS = ("fire", "cg")
#: Load-point schedules: every replica at its own point (``async``) or the batch at the same point (``lockstep``).
SCHEDULES = ("async", "lockstep")


@dataclass(frozen=True)
class IdealGas:
    """Isothermal ideal gas inside the shell: p = p0 V0 / V, a constant ambient pressure outside.

    The net outward pressure p - p_ambient acts on the shell as (p - p_ambient) dV/dx_v.

    Parameters
    ----------
    p0 : float
        Gas pressure at the reference volume V0 (DPD pressure, >= 0); 3 = ideal gas at number density 3,
        k_BT = 1.
    p_ambient : float, optional
        Ambient pressure (DPD pressure); None = p0, so the stress-free reference is force-free.

    Raises
    ------
    ValueError
        If ``p0`` is negative or not finite, or ``p_ambient`` is not finite.
    """

    p0: float = 3.0
    p_ambient: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.p0) and self.p0 >= 0):
            raise ValueError(f"IdealGas.p0 must be a finite number >= 0, got {self.p0!r}")
        if self.p_ambient is not None and not math.isfinite(self.p_ambient):
            raise ValueError(f"IdealGas.p_ambient must be finite, got {self.p_ambient!r}")

    @property
    def ambient(self) -> float:
        """The ambient pressure in force (DPD pressure)."""
        return self.p0 if self.p_ambient is None else float(self.p_ambient)


@dataclass(frozen=True)
class FireSettings:
    """Minimiser controls for every load point.

    Parameters
    ----------
    ftol : float
        Convergence: absolute per-vertex force norm (DPD force).
    max_steps : int
        FIRE iterations per load point.
    dt, dt_max : float
        Initial and largest FIRE time step (DPD time, unit FIRE mass).
    max_move : float
        Largest vertex move per iteration (DPD length).
    stop_at_max_steps : bool
        A replica whose FIRE reaches ``max_steps`` at a point ends its curve there ('not_converged', that point
        and the later ones NaN, the converged prefix kept) instead of going on to the last point.
    n_delay, f_inc, f_dec, alpha0, f_alpha : int or float
        The FIRE 2.0 constants of :func:`bubblecal.sim.engine.minimize.fire_minimize` (dimensionless).
    force_mode : str
        How the shell forces are summed (:class:`bubblecal.sim.engine.kernels.shell.ShellForceField`):
        ``"auto"`` (per-vertex gather on a GPU, per-element scatter with atomics on the CPU), ``"gather"`` or
        ``"scatter"``; the same forces up to the summation order.
    minimizer : str
        ``"fire"`` (FIRE 2.0, :class:`bubblecal.sim.engine.DeviceFire`; the shipped training sets) or ``"cg"``
        (the force-only nonlinear conjugate gradient, :class:`bubblecal.sim.engine.DeviceCG`: the same minima
        within ``ftol``, far fewer force evaluations on buckled shells).  ``ftol``, ``max_steps`` and
        ``stop_at_max_steps`` apply to both (``max_steps`` counts force evaluations for the CG); the other fields
        are FIRE's.

    Raises
    ------
    ValueError
        If ``force_mode`` or ``minimizer`` is unknown.
    """

    ftol: float = 0.05
    max_steps: int = 20_000
    dt: float = 5e-3
    dt_max: float = 5e-2
    max_move: float = 0.01
    stop_at_max_steps: bool = False
    n_delay: int = 5
    f_inc: float = 1.1
    f_dec: float = 0.5
    alpha0: float = 0.1
    f_alpha: float = 0.99
    force_mode: str = "auto"
    minimizer: str = "fire"

    def __post_init__(self) -> None:
        from bubblecal.sim.engine import FORCE_MODES  # Warp-free: settings stay cheap

        if self.force_mode not in FORCE_MODES:
            raise ValueError(f"FireSettings.force_mode must be one of {FORCE_MODES}, got {self.force_mode!r}")
        if self.minimizer not in MINIMIZERS:
            raise ValueError(f"FireSettings.minimizer must be one of {MINIMIZERS}, got {self.minimizer!r}")

    def constants(self) -> dict:
        """Keyword arguments of the minimiser's constants (FIRE's; none for the CG, which keeps its defaults).

        Returns
        -------
        dict
            FIRE: ``dt``, ``dt_max``, ``max_move`` and the FIRE 2.0 constants; CG: empty.
        """
        if self.minimizer == "cg":
            return {}
        return {"dt": self.dt, "dt_max": self.dt_max, "max_move": self.max_move, "n_delay": self.n_delay,
                "f_inc": self.f_inc, "f_dec": self.f_dec, "alpha0": self.alpha0, "f_alpha": self.f_alpha}


def _check_params(params, mesh: ShellMesh, gas: IdealGas | None) -> list[ShellParams]:
    """``params`` as a non-empty list of ShellParams; ``mesh`` and ``gas`` type-checked."""
    from bubblecal.sim.engine.kernels.shell import ShellParams
    from bubblecal.sim.engine.mesh import ShellMesh

    if isinstance(params, ShellParams):
        params = [params]
    params = list(params)
    if not params:
        raise ValueError("params must hold at least one ShellParams")
    for p in params:
        if not isinstance(p, ShellParams):
            raise ValueError(f"params must hold ShellParams, got {type(p).__name__}")
    if not isinstance(mesh, ShellMesh):
        raise ValueError(f"mesh must be a ShellMesh, got {type(mesh).__name__}")
    if gas is not None and not isinstance(gas, IdealGas):
        raise ValueError(f"gas must be an IdealGas or None, got {type(gas).__name__}")
    return params


def _check_max_replicas(max_replicas, schedule: str) -> None:
    """``max_replicas``: None or an integer >= 1, with the async schedule."""
    if max_replicas is None:
        return
    if isinstance(max_replicas, bool) or not isinstance(max_replicas, (int, np.integer)) or max_replicas < 1:
        raise ValueError(f"max_replicas must be an integer >= 1 or None, got {max_replicas!r}")
    if schedule != "async":
        raise ValueError("max_replicas (slot refill) needs schedule='async' with the device minimiser")


def _check_common(rupture_strain: float, fire: FireSettings, schedule: str | None = None) -> str:
    """Validate the shared arguments; returns the load-point schedule (default: async)."""
    if schedule is None:
        schedule = "async"
    if schedule not in SCHEDULES:
        raise ValueError(f"schedule must be one of {SCHEDULES}, got {schedule!r}")
    if not (math.isfinite(rupture_strain) and rupture_strain > 0):
        raise ValueError(f"rupture_strain must be a positive finite number, got {rupture_strain!r}")
    if not isinstance(fire, FireSettings):
        raise ValueError(f"fire must be a FireSettings, got {type(fire).__name__}")
    return schedule


def _dtype_name(dtype) -> str:
    """'float64' for None, else the Warp scalar type's name."""
    return "float64" if dtype is None else str(getattr(dtype, "__name__", dtype))
