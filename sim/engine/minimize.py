"""FIRE energy minimiser (Bitzek et al. 2006; FIRE 2.0 details from Guenole et al. 2020), batched.

The NumPy reference of the device-resident :class:`bubblecal.sim.engine.minimize_device.DeviceFire` (same
rules); used by the quasi-static tier's NumPy backend, the Reissner point-load check and the tests.  It knows
nothing about shells: it takes a callback ``energy_forces(x) -> (energy, forces)`` over positions ``x [N, 3]``
(NumPy float64; the callback may evaluate Warp kernels on any device), a replica index per row,
and minimises every replica independently with its own FIRE state (time step, mixing, counters).
A replica that has converged (max force norm over its free rows <= ``ftol``) is frozen while the
others go on; a replica whose forces become non-finite stops with status ``"nonfinite"``.

Rows with ``groups[i] < 0`` and components with ``free[i, k] == False`` never move (anchors,
pinned vertices, solvent rows that are not part of the minimisation).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

__all__ = ["FireResult", "fire_minimize", "STATUS_CONVERGED", "STATUS_MAX_STEPS", "STATUS_NONFINITE"]

#: Replica statuses of :class:`FireResult`.
STATUS_CONVERGED = "converged"
STATUS_MAX_STEPS = "max_steps"
STATUS_NONFINITE = "nonfinite"


@dataclass
class FireResult:
    """Outcome of :func:`fire_minimize`; per-replica arrays have length ``n_groups``.

    Attributes
    ----------
    x : numpy.ndarray
        [N, 3] final positions (caller's length unit).
    status : list of str
        :data:`STATUS_CONVERGED`, :data:`STATUS_MAX_STEPS` or :data:`STATUS_NONFINITE` per replica.
    converged : numpy.ndarray
        [n_groups] bool.
    steps : numpy.ndarray
        [n_groups] FIRE steps taken.
    fmax : numpy.ndarray
        [n_groups] largest per-row force norm at the last test (caller's force unit).
    energy : numpy.ndarray
        [n_groups] last reported energy (NaN when the callback reports none).
    n_evaluations : int
        Force evaluations.
    history : list
        (step, fmax per replica) every ``record_every`` steps.
    """

    x: np.ndarray
    status: list[str]
    converged: np.ndarray
    steps: np.ndarray
    fmax: np.ndarray
    energy: np.ndarray
    n_evaluations: int
    history: list = field(default_factory=list)

    @property
    def all_converged(self) -> bool:
        """Whether every replica converged."""
        return bool(np.all(self.converged))


def _group_sum(values: np.ndarray, groups: np.ndarray, n: int) -> np.ndarray:
    """Sum of ``values`` per group (rows with group < 0 left out)."""
    ok = groups >= 0
    return np.bincount(groups[ok], weights=values[ok], minlength=n)


def _group_max(values: np.ndarray, groups: np.ndarray, n: int) -> np.ndarray:
    """Maximum of ``values`` per group (0 for an empty group; rows with group < 0 left out)."""
    out = np.zeros(n)
    ok = groups >= 0
    np.maximum.at(out, groups[ok], values[ok])
    return out


def fire_minimize(
    energy_forces: Callable[[np.ndarray], tuple[np.ndarray | float | None, np.ndarray]],
    x0: np.ndarray,
    groups: np.ndarray | None = None,
    *,
    n_groups: int | None = None,
    free: np.ndarray | None = None,
    mass: float | np.ndarray = 1.0,
    ftol: float | np.ndarray = 1e-3,
    max_steps: int = 10_000,
    dt: float = 1e-2,
    dt_max: float | None = None,
    dt_min: float | None = None,
    max_move: float | None = 0.05,
    n_delay: int = 5,
    f_inc: float = 1.1,
    f_dec: float = 0.5,
    alpha0: float = 0.1,
    f_alpha: float = 0.99,
    record_every: int = 0,
) -> FireResult:
    """Minimise with FIRE; every replica (group of rows) has its own state and convergence test.

    Parameters
    ----------
    energy_forces : callable
        ``x [N, 3] -> (E, F)``; ``E`` per replica [n_groups], a scalar or None (only reported), ``F [N, 3]`` =
        -dE/dx (caller's units).
    x0 : numpy.ndarray
        [N, 3] start positions (not modified).
    groups : numpy.ndarray, optional
        Replica index per row (-1: the row never moves); default all rows in replica 0.
    n_groups : int, optional
        Number of replicas (default ``groups.max() + 1``).
    free : numpy.ndarray, optional
        [N, 3] bool mask of the components that may move (default all).
    mass : float or numpy.ndarray, optional
        Scalar or per-row masses (FIRE's inertia; only the ratio matters).
    ftol : float or numpy.ndarray, optional
        Convergence threshold on the largest per-row force norm (force unit), scalar or per replica.
    max_steps : int, optional
        Maximum number of FIRE steps (force evaluations after the first).
    dt, dt_max, dt_min : float, optional
        Initial, largest (default 10 dt) and smallest (default dt / 50) step (caller's time unit).
    max_move : float, optional
        Cap on any row's displacement per step (length unit; None: no cap).
    n_delay, f_inc, f_dec, alpha0, f_alpha : optional
        FIRE constants (dimensionless).
    record_every : int, optional
        If > 0, append (step, fmax per replica) to ``history`` every that many steps.

    Returns
    -------
    FireResult

    Raises
    ------
    ValueError
        When ``groups`` or ``free`` do not match ``x0``, or there is no replica.
    """
    x = np.array(x0, dtype=np.float64, copy=True)
    n = x.shape[0]
    g = np.zeros(n, dtype=np.int64) if groups is None else np.asarray(groups, dtype=np.int64)
    if g.shape != (n,):
        raise ValueError("groups must have one entry per row of x0")
    ng = int(g.max() + 1) if n_groups is None else int(n_groups)
    if ng <= 0:
        raise ValueError("no replica to minimise")
    fr = np.ones((n, 3), dtype=bool) if free is None else np.asarray(free, dtype=bool)
    if fr.shape != (n, 3):
        raise ValueError("free must be a [N, 3] boolean mask")
    fr = fr & (g >= 0)[:, None]
    m = np.broadcast_to(np.asarray(mass, dtype=np.float64), (n,))[:, None]
    tol = np.broadcast_to(np.asarray(ftol, dtype=np.float64), (ng,)).copy()
    dt_max = 10.0 * dt if dt_max is None else dt_max
    dt_min = dt / 50.0 if dt_min is None else dt_min
    gg = np.where(g >= 0, g, 0)

    v = np.zeros_like(x)
    dt_r = np.full(ng, float(dt))
    alpha_r = np.full(ng, float(alpha0))
    n_pos = np.zeros(ng, dtype=np.int64)
    active = np.ones(ng, dtype=bool)
    status = [STATUS_MAX_STEPS] * ng
    steps = np.zeros(ng, dtype=np.int64)
    history: list = []

    def evaluate(xx):
        e, f = energy_forces(xx)
        f = np.where(fr, np.asarray(f, dtype=np.float64), 0.0)
        e = np.full(ng, np.nan) if e is None else np.broadcast_to(np.asarray(e, dtype=np.float64), (ng,))
        return e, f

    energy, f = evaluate(x)
    n_eval = 1
    fnorm = np.linalg.norm(f, axis=1)
    for step in range(max_steps + 1):
        finite = _group_sum((~np.isfinite(fnorm)).astype(np.float64), g, ng) == 0
        fmax = _group_max(np.where(np.isfinite(fnorm), fnorm, 0.0), g, ng)
        for r in np.nonzero(active & ~finite)[0]:
            status[r] = STATUS_NONFINITE
        done = active & finite & (fmax <= tol)
        for r in np.nonzero(done)[0]:
            status[r] = STATUS_CONVERGED
        active &= finite & ~done
        steps[active] = step
        if record_every and step % record_every == 0:
            history.append((step, fmax.copy()))
        if not active.any() or step == max_steps:
            break
        row_on = active[gg] & (g >= 0)
        # FIRE power test, per replica
        power = _group_sum(np.einsum("ij,ij->i", f, v), g, ng)
        up = active & (power > 0)
        down = active & ~(power > 0)
        n_pos[up] += 1
        grow = up & (n_pos > n_delay)
        dt_r[grow] = np.minimum(dt_r[grow] * f_inc, dt_max)
        alpha_r[grow] *= f_alpha
        n_pos[down] = 0
        dt_r[down] = np.maximum(dt_r[down] * f_dec, dt_min)
        alpha_r[down] = alpha0
        back = down[gg] & row_on
        x[back] -= 0.5 * dt_r[gg][back, None] * v[back]  # FIRE 2.0 correction
        v[down[gg]] = 0.0
        # semi-implicit Euler with velocity mixing
        dtv = dt_r[gg][:, None]
        v = np.where(row_on[:, None] & fr, v + dtv * f / m, 0.0)
        vn = np.sqrt(_group_sum(np.einsum("ij,ij->i", v, v), g, ng))
        fn = np.sqrt(_group_sum(fnorm**2, g, ng))
        scale = np.where(fn > 0, vn / np.where(fn > 0, fn, 1.0), 0.0)
        a = alpha_r[gg][:, None]
        v = np.where(row_on[:, None] & fr, (1.0 - a) * v + a * scale[gg][:, None] * f, 0.0)
        dx = dtv * v
        if max_move is not None:
            dn = np.linalg.norm(dx, axis=1)
            big = dn > max_move
            if big.any():
                dx[big] *= (max_move / dn[big])[:, None]
        x += dx
        energy, f = evaluate(x)
        n_eval += 1
        fnorm = np.linalg.norm(f, axis=1)
    fmax = _group_max(np.where(np.isfinite(fnorm), fnorm, np.inf), g, ng)
    return FireResult(x=x, status=status, converged=np.array([s == STATUS_CONVERGED for s in status]),
                      steps=steps, fmax=fmax, energy=np.asarray(energy, dtype=np.float64).copy(),
                      n_evaluations=n_eval, history=history)
