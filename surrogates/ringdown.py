"""Ringdown fitting: a damped sine plus a linear trend fitted to a bubble-radius trace R(t).

A radius trace R(t) after a small perturbation is fitted with

    R(t) = R0 + c t + exp(-lam t) [A sin(w_d t) + B cos(w_d t)]

(:func:`fit_ringdown`). Start values: the linear trend by least squares, w_d from the peak of the
(Hann-windowed, zero-padded) spectrum of the detrended trace with parabolic interpolation, lam from the
logarithmic decrement of successive extrema. The fit itself is variable projection (R0, c, A, B solved
linearly for each (lam, w_d), ``scipy.optimize.least_squares`` over the two nonlinear parameters) followed by
a joint polish of all six for standard errors. Frequencies (cycles per time unit of ``t``):

    f_d = w_d / 2 pi,   f_0 = sqrt(w_d^2 + lam^2) / 2 pi,   f_res = sqrt(w_d^2 - lam^2) / 2 pi.

Fit quality (:class:`RingdownFit`): R^2 of the oscillating part, rmse relative to the initial amplitude, the
number of observed cycles, standard errors. Ringdown runs multiply the shell mass by a factor M (160 in the
published sweeps, docs/physics.md section 5); a DPD frequency converts to a physical one by ``f = f_dpd sqrt(M) / u_t``
(:meth:`RingdownFit.physical_MHz`, through :mod:`bubblecal.data.units`). The resonance frequencies feed the
acoustic surrogate (:mod:`bubblecal.surrogates.acoustic`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from bubblecal.data import DEFAULT_UNITS, UnitSystem

__all__ = ["damped_sine", "RingdownFit", "fit_ringdown"]


def damped_sine(t, R0, c, A, B, lam, omega_d):
    """The ringdown model R(t) = R0 + c t + exp(-lam t) [A sin(w_d t) + B cos(w_d t)] (numpy).

    Parameters
    ----------
    t : array_like
        Times (any time unit; DPD time for simulated traces).
    R0, c, A, B : float
        Offset and amplitudes [length units of R]; ``c`` per time unit.
    lam : float
        Decay rate [1 / time unit].
    omega_d : float
        Damped angular frequency [rad / time unit].

    Returns
    -------
    numpy.ndarray
        R(t), the shape of ``t``.
    """
    t = np.asarray(t, dtype=float)
    env = np.exp(-lam * t)
    return R0 + c * t + env * (A * np.sin(omega_d * t) + B * np.cos(omega_d * t))


@dataclass
class RingdownFit:
    """Result of :func:`fit_ringdown`, in the time units of the input ``t`` and the length units of ``R``.

    Parameters
    ----------
    R0, c, A, B, lam, omega_d : float
        Fitted parameters of :func:`damped_sine` (absolute time origin).
    stderr : dict
        Standard errors keyed by parameter name.
    r2 : float
        R^2 of the oscillating part.
    rel_rmse : float
        Residual rms relative to the initial oscillation amplitude.
    n_cycles : float
        Observed cycles.
    n_points : int
        Samples fitted.
    success : bool
        The optimiser converged and the quality check passed (R^2 > 0.9, under-damped).
    message : str
        The optimiser's message (with the quality numbers when it failed).
    start : dict
        Start values of ``omega_d`` and ``lam``.
    """

    R0: float
    c: float
    A: float
    B: float
    lam: float
    omega_d: float
    stderr: dict
    r2: float
    rel_rmse: float
    n_cycles: float
    n_points: int
    success: bool
    message: str
    start: dict = field(default_factory=dict)

    @property
    def f_d(self) -> float:
        """Damped frequency w_d / 2 pi [cycles per time unit]."""
        return self.omega_d / (2 * math.pi)

    @property
    def f_0(self) -> float:
        """Undamped frequency sqrt(w_d^2 + lam^2) / 2 pi [cycles per time unit]."""
        return math.sqrt(self.omega_d**2 + self.lam**2) / (2 * math.pi)

    @property
    def f_res(self) -> float:
        """Resonance frequency sqrt(w_d^2 - lam^2) / 2 pi [cycles per time unit] (NaN when over-damped, lam > w_d)."""
        v = self.omega_d**2 - self.lam**2
        return math.sqrt(v) / (2 * math.pi) if v > 0 else float("nan")

    @property
    def f_res_stderr(self) -> float:
        """Standard error of f_res propagated from (lam, w_d) (ignoring their covariance)."""
        s_w = self.stderr.get("omega_d", float("nan"))
        s_l = self.stderr.get("lam", float("nan"))
        v = self.omega_d**2 - self.lam**2
        if v <= 0:
            return float("nan")
        return math.hypot(self.omega_d * s_w, self.lam * s_l) / math.sqrt(v) / (2 * math.pi)

    def physical_MHz(self, mass_factor: float = 160.0, units: UnitSystem = DEFAULT_UNITS) -> dict:
        """f_res, f_0, f_d in MHz for ``t`` in DPD time units, with the sqrt(M) mass correction.

        Parameters
        ----------
        mass_factor : float
            Shell-mass factor M of the ringdown run.
        units : bubblecal.data.units.UnitSystem
            Unit system of the run.

        Returns
        -------
        dict
            ``{"f_res", "f_0", "f_d"}`` [MHz].
        """
        conv = float(units.frequency_to_physical(1.0, mass_factor)) / 1e6
        return {"f_res": self.f_res * conv, "f_0": self.f_0 * conv, "f_d": self.f_d * conv}

    def as_dict(self) -> dict:
        """Every field plus the frequencies ``f_res``, ``f_0``, ``f_d`` and ``f_res_stderr``."""
        d = asdict(self)
        d.update({"f_res": self.f_res, "f_0": self.f_0, "f_d": self.f_d, "f_res_stderr": self.f_res_stderr})
        return d

    def predict(self, t) -> np.ndarray:
        """The fitted R(t).

        Parameters
        ----------
        t : array_like
            Times (units of the fitted trace).

        Returns
        -------
        numpy.ndarray
            R(t) (units of the fitted trace).
        """
        return damped_sine(t, self.R0, self.c, self.A, self.B, self.lam, self.omega_d)


def _spectral_peak(t, r) -> float:
    """Angular frequency of the spectral peak of a uniformly sampled trace (parabolic refinement)."""
    n = r.size
    dt = (t[-1] - t[0]) / (n - 1)
    nfft = 1 << int(math.ceil(math.log2(8 * n)))
    spec = np.abs(np.fft.rfft((r - r.mean()) * np.hanning(n), nfft))
    freqs = np.fft.rfftfreq(nfft, dt)
    k = int(np.argmax(spec[1:])) + 1
    if 1 <= k < spec.size - 1:
        a, b, c = np.log(spec[k - 1:k + 2] + 1e-300)
        denom = a - 2 * b + c
        shift = 0.5 * (a - c) / denom if denom != 0 else 0.0
        k_ref = k + float(np.clip(shift, -0.5, 0.5))
    else:
        k_ref = float(k)
    return 2 * math.pi * k_ref * (freqs[1] - freqs[0])


def _log_decrement(t, r, omega) -> float:
    """Decay rate from the extrema of |r| (log decrement); a small positive default otherwise."""
    a = np.abs(r)
    idx = np.flatnonzero((a[1:-1] > a[:-2]) & (a[1:-1] >= a[2:])) + 1
    # keep extrema at least ~ a third of a period apart
    if idx.size >= 2 and omega > 0:
        min_sep = (math.pi / omega) * 0.6
        keep = [idx[0]]
        for i in idx[1:]:
            if t[i] - t[keep[-1]] >= min_sep:
                keep.append(i)
        idx = np.array(keep)
    if idx.size >= 3:
        slope = np.polyfit(t[idx], np.log(a[idx] + 1e-300), 1)[0]
        if slope < 0:
            return float(-slope)
    return float(omega / (2 * math.pi * 20))  # ~ 20 cycles to decay by e


def fit_ringdown(t, R, t_start: float | None = None) -> RingdownFit:
    """Fit the damped sine plus linear trend to a ringdown trace (module docstring).

    Parameters
    ----------
    t : array_like, shape (n,)
        Times, strictly increasing and (for the spectral start) roughly uniform (DPD time for simulations).
    R : array_like, shape (n,)
        Bubble radius (any length unit; DPD length for simulations). Non-finite samples are dropped.
    t_start : float, optional
        Samples before ``t_start`` are dropped.

    Returns
    -------
    RingdownFit
        Parameters in the absolute time origin of ``t``; ``success`` tells whether the fit is usable.

    Raises
    ------
    ValueError
        For mismatched or non-1-D arrays, fewer than 12 usable samples, or non-increasing times.
    RuntimeError
        When no start value could be fitted.
    """
    from scipy.optimize import least_squares

    t = np.asarray(t, dtype=float)
    R = np.asarray(R, dtype=float)
    if t.shape != R.shape or t.ndim != 1:
        raise ValueError(f"t and R must be 1-D arrays of equal length, got {t.shape} and {R.shape}")
    ok = np.isfinite(t) & np.isfinite(R)
    if t_start is not None:
        ok &= t >= t_start
    t, R = t[ok], R[ok]
    if t.size < 12:
        raise ValueError(f"ringdown trace too short after cleaning ({t.size} points; need >= 12)")
    if np.any(np.diff(t) <= 0):
        raise ValueError("t must be strictly increasing")
    t0 = t[0]
    tt = t - t0
    scale = float(np.std(R)) or 1.0
    y = (R - R.mean()) / scale
    trend = np.polyfit(tt, y, 1)
    r = y - np.polyval(trend, tt)
    omega0 = _spectral_peak(tt, r)
    lam0 = _log_decrement(tt, r, omega0)
    # the spectral peak of a damped sine sits near w_d; use it directly
    start = {"omega_d": omega0, "lam": lam0}

    def basis(lam, om):
        env = np.exp(-lam * tt)
        return np.column_stack([np.ones_like(tt), tt, env * np.sin(om * tt), env * np.cos(om * tt)])

    def vp_resid(theta):
        lam, om = theta
        M = basis(lam, om)
        coef, *_ = np.linalg.lstsq(M, y, rcond=None)
        return M @ coef - y

    span = tt[-1]
    om_hi = math.pi * (tt.size - 1) / span  # Nyquist
    best = None
    for om_try in (omega0, omega0 * 0.98, omega0 * 1.02):
        try:
            sol = least_squares(vp_resid, x0=[max(lam0, 1e-12), om_try],
                                bounds=([0.0, 1e-9 * om_hi], [50.0 * omega0 + 10.0 / span, om_hi]),
                                x_scale=[max(lam0, omega0 * 1e-3), omega0], xtol=1e-14, ftol=1e-14, gtol=1e-14)
        except ValueError:
            continue
        if best is None or sol.cost < best.cost:
            best = sol
    if best is None:
        raise RuntimeError("ringdown fit failed to start")
    lam, om = best.x
    coef, *_ = np.linalg.lstsq(basis(lam, om), y, rcond=None)

    def full_resid(p):
        return damped_sine(tt, *p) - y

    p0 = np.array([coef[0], coef[1], coef[2], coef[3], lam, om])
    sol = least_squares(full_resid, p0, xtol=1e-15, ftol=1e-15, gtol=1e-15,
                        x_scale=np.maximum(np.abs(p0), 1e-6))
    p = sol.x
    resid = sol.fun
    dof = max(1, tt.size - 6)
    s2 = float(resid @ resid) / dof
    try:
        cov = np.linalg.pinv(sol.jac.T @ sol.jac) * s2
        se = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:  # pragma: no cover
        se = np.full(6, np.nan)
    osc = y - (p[0] + p[1] * tt)
    ss_tot = float(osc @ osc)
    r2 = 1.0 - float(resid @ resid) / ss_tot if ss_tot > 0 else float("nan")
    amp = math.hypot(p[2], p[3])
    rel_rmse = math.sqrt(float(resid @ resid) / tt.size) / amp if amp > 0 else float("inf")
    names = ("R0", "c", "A", "B", "lam", "omega_d")
    # undo the scaling y = (R - mean)/scale
    R0 = R.mean() + scale * p[0]
    c_ = scale * p[1]
    A_, B_ = scale * p[2], scale * p[3]
    # shift the time origin back: exp(-lam (t - t0)) [A sin w(t-t0) + B cos w(t-t0)] in terms of t
    se_scaled = dict(zip(names, [scale * se[0], scale * se[1], scale * se[2], scale * se[3], se[4], se[5]],
                         strict=True))
    cosp, sinp = math.cos(p[5] * t0), math.sin(p[5] * t0)
    e0 = math.exp(p[4] * t0)
    A_abs = e0 * (A_ * cosp + B_ * sinp)
    B_abs = e0 * (B_ * cosp - A_ * sinp)
    success = bool(sol.success and r2 > 0.9 and p[5] > p[4])
    msg = sol.message if success else f"{sol.message}; quality check: R^2={r2:.3f}, lam={p[4]:.3g}, w_d={p[5]:.3g}"
    return RingdownFit(R0=float(R0 - c_ * t0), c=float(c_), A=float(A_abs), B=float(B_abs), lam=float(p[4]),
                       omega_d=float(p[5]), stderr={k: float(v) for k, v in se_scaled.items()}, r2=float(r2),
                       rel_rmse=float(rel_rmse), n_cycles=float(p[5] * span / (2 * math.pi)), n_points=int(tt.size),
                       success=success, message=str(msg), start=start)
