"""Nonlinear conjugate gradient on forces alone (Polak-Ribiere+, a bracketing secant line search on F . d).

The NumPy reference of the device-resident :class:`bubblecal.sim.engine.minimize_device_cg.DeviceCG` (same rules,
same iterates up to the summation order).  It needs forces only, never an energy: the quasi-static tier's thermal
plate contact is a mean force with no energy the minimiser could test.  The line search therefore looks for a root
of the directional force g(a) = F(x + a d) . d (g > 0: still downhill along d).

Rules, per line (``d`` the search direction, ``slope = F(x) . d > 0``):

* the first trial step of the first line is ``a = min(first_alpha, first_move / max_i |d_i|)``; of every later line
  the last line's final step scaled by the ratio of the slopes, ``a_last slope_last / slope`` (Nocedal & Wright,
  Numerical Optimization, eq. 3.60), moving at most ``grow * first_move``;
* a trial with ``|g| <= accept * slope`` ends the line; so does the ``max_trials``-th trial (its point is kept);
* g > 0 and no bracket yet: extrapolate by the secant through the last two downhill trials, at most doubling the
  step and moving at most ``grow * first_move`` (vertex length) further;
* once a trial has g <= 0 the root is bracketed and every next trial is the secant inside the bracket;
* a new line: ``beta = max(0, F1 . (F1 - F0) / |F0|^2)``, ``d = F1 + beta d``; when that is not downhill
  (``F1 . d <= 0``) the direction restarts along ``F1``.

Convergence is tested at every evaluated point: ``max_i |F_i| <= ftol`` ends the minimisation there.  The budget
counts force evaluations; ``steps`` is evaluations - 1, as FIRE's updates are.  The result is always the last
evaluated point.  Units are the caller's.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bubblecal.sim.engine.minimize import STATUS_CONVERGED, STATUS_MAX_STEPS, STATUS_NONFINITE

__all__ = ["CgResult", "cg_minimize", "CG_DEFAULTS"]

#: Line-search constants shared by the reference and the device CG (dimensionless, except ``first_move``: length).
CG_DEFAULTS = {"first_alpha": 1e-3, "first_move": 0.05, "grow": 4.0, "accept": 0.1, "max_trials": 8}


@dataclass
class CgResult:
    """Outcome of :func:`cg_minimize`.

    Attributes
    ----------
    x : numpy.ndarray
        [N, 3] final positions (caller's length unit).
    status : str
        ``'converged'``, ``'max_steps'`` or ``'nonfinite'``.
    steps : int
        Force evaluations - 1.
    fmax : float
        Largest row force norm at the last evaluated point (caller's force unit).
    n_lines : int
        Line searches ended.
    """

    x: np.ndarray
    status: str
    steps: int
    fmax: float
    n_lines: int

    @property
    def converged(self) -> bool:
        """Whether ``fmax <= ftol`` was reached."""
        return self.status == STATUS_CONVERGED


def next_trial(a1: float, g1: float, a_lo: float, g_lo: float, a_hi: float, g_hi: float, step_cap: float):
    """The line search's next trial step after evaluating g(a1) = g1 (no acceptance test here).

    Parameters
    ----------
    a1, g1 : float
        The trial just evaluated and its directional force.
    a_lo, g_lo : float
        The last downhill trial (g > 0; a = 0 and the line's slope at first).
    a_hi, g_hi : float
        The bracketing uphill trial (g <= 0), ``a_hi < 0`` while there is none.
    step_cap : float
        Largest extrapolation beyond ``a1`` (step units: ``grow * first_move / max|d|``).

    Returns
    -------
    tuple of float
        ``(a_next, a_lo, g_lo, a_hi, g_hi)`` with the bracket updated.
    """
    if g1 > 0.0:
        if a_hi < 0.0:  # no bracket: extrapolate along the downhill secant, at most doubling the step
            grow = 2.0 * (a1 - a_lo)
            if g_lo > g1:
                grow = min(grow, (a1 - a_lo) * g1 / (g_lo - g1))
            return a1 + min(grow, step_cap), a1, g1, a_hi, g_hi
        a_lo, g_lo = a1, g1
    else:
        a_hi, g_hi = a1, g1
    return a_lo + g_lo * (a_hi - a_lo) / (g_lo - g_hi), a_lo, g_lo, a_hi, g_hi


def cg_minimize(force: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, ftol: float = 1e-3,
                max_steps: int = 10_000, *, first_alpha: float = CG_DEFAULTS["first_alpha"],
                first_move: float = CG_DEFAULTS["first_move"], grow: float = CG_DEFAULTS["grow"],
                accept: float = CG_DEFAULTS["accept"], max_trials: int = CG_DEFAULTS["max_trials"]) -> CgResult:
    """Minimise from ``x0`` with the forces ``force(x)`` (module docstring).

    Parameters
    ----------
    force : callable
        ``x [N, 3] -> F [N, 3]`` (-dE/dx, with any projection the caller wants: fixed components zero, mean removed).
    x0 : numpy.ndarray
        [N, 3] start (caller's length unit).
    ftol : float, optional
        Convergence threshold on the largest row force norm (force unit).
    max_steps : int, optional
        Largest number of force evaluations after the first.
    first_alpha, first_move, grow, accept, max_trials : optional
        Line-search constants (:data:`CG_DEFAULTS`; ``first_move`` in length units).

    Returns
    -------
    CgResult

    Raises
    ------
    ValueError
        On a negative ``max_steps`` or a non-positive constant.
    """
    if int(max_steps) < 0:
        raise ValueError(f"max_steps must be >= 0, got {max_steps!r}")
    if min(first_alpha, first_move, grow, accept, max_trials) <= 0:
        raise ValueError("the line-search constants must be positive")
    x = np.array(x0, dtype=np.float64)
    x1, f1 = x, np.asarray(force(x), dtype=np.float64)
    n_eval, n_lines, trials = 1, 0, -1
    d = f_b = f1
    fsq_b = slope = dn = a1 = a_lo = g_lo = a_hi = g_hi = 0.0
    while True:
        fmax = float(np.max(np.linalg.norm(f1, axis=1)))
        if not np.isfinite(fmax):
            status = STATUS_NONFINITE
            break
        if fmax <= ftol:
            status = STATUS_CONVERGED
            break
        if n_eval - 1 >= max_steps:
            status = STATUS_MAX_STEPS
            break
        trials += 1
        g1 = float(np.sum(f1 * d))
        if trials > 0 and abs(g1) > accept * slope and trials < max_trials:
            a_next, a_lo, g_lo, a_hi, g_hi = next_trial(a1, g1, a_lo, g_lo, a_hi, g_hi, grow * first_move / dn)
            a1 = a_next
        else:  # a new line from here: along F first, then F + beta d (Polak-Ribiere+)
            fsq = float(np.sum(f1 * f1))
            slope_prev = slope
            beta, slope = 0.0, fsq
            if trials > 0:
                beta = max(0.0, (fsq - float(np.sum(f1 * f_b))) / fsq_b)
                slope = fsq + beta * g1
                if slope <= 0.0:
                    beta, slope = 0.0, fsq
                n_lines += 1
            x, d, f_b, fsq_b = x1, f1 + beta * d, f1, fsq
            dn = fmax if beta == 0.0 else float(np.max(np.linalg.norm(d, axis=1)))
            if trials > 0:  # the last line's step, scaled by the slopes (Nocedal & Wright, eq. 3.60), capped
                a1 = min(a1 * slope_prev / slope, grow * first_move / dn)
            else:
                a1 = min(first_alpha, first_move / dn)
            a_lo, g_lo, a_hi, g_hi, trials = 0.0, slope, -1.0, 0.0, 0
        x1 = x + a1 * d
        f1 = np.asarray(force(x1), dtype=np.float64)
        n_eval += 1
    return CgResult(x=x1, status=status, steps=n_eval - 1, fmax=fmax, n_lines=n_lines)
