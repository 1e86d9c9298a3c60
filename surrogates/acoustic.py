"""Acoustic surrogates: ringdown (damped-sine) fit and per-diameter f_res^2(k_a) quadratics.

Ringdown fit
------------
A radius trace R(t) after a small perturbation is fitted with

    R(t) = R0 + c t + exp(-lam t) [A sin(w_d t) + B cos(w_d t)]

(:func:`fit_ringdown`). Start values: the linear trend by least squares, w_d from the peak of
the (Hann-windowed, zero-padded) spectrum of the detrended trace with parabolic interpolation,
lam from the logarithmic decrement of successive extrema. The fit itself is variable projection
(R0, c, A, B solved linearly for each (lam, w_d), ``scipy.optimize.least_squares`` over the two
nonlinear parameters) followed by a joint polish of all six for standard errors. Frequencies
(cycles per time unit of ``t``):

    f_d = w_d / 2 pi,   f_0 = sqrt(w_d^2 + lam^2) / 2 pi,   f_res = sqrt(w_d^2 - lam^2) / 2 pi.

Fit quality (:class:`RingdownFit`): R^2 of the oscillating part, rmse relative to the initial
amplitude, the number of observed cycles, standard errors. Ringdown runs multiply the shell mass
by M (160 in the published sweeps); a DPD frequency converts to a physical one by
``f = f_dpd sqrt(M) / u_t`` (:meth:`RingdownFit.physical_MHz`, through ``bubblecal.data.units``).

Acoustic surrogate
------------------
Per simulated diameter d, a least-squares quadratic with free intercept

    f_res(k_a; d)^2 = a0 + a1 k_a + a2 k_a^2,     f_res in **physical MHz**, k_a in **DPD units**

(so ``A_d(k_a) = sqrt(a0 + a1 k_a + a2 k_a^2)`` is directly the model of ``docs/inference.md`` §3),
with leave-one-out relative errors of f_res. Valid only inside the fitted k_a range: use
:meth:`AcousticSurrogate.in_range` / :meth:`AcousticSurrogate.check_range` (never silent).
JSON format ``bubblecal-acoustic-surrogate`` version 1 (see :meth:`AcousticSurrogate.to_dict`).
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from bubblecal.data import DEFAULT_UNITS, UnitSystem, atomic_write

__all__ = ["RingdownFit", "fit_ringdown", "damped_sine", "DiameterFit", "fit_quadratic", "AcousticSurrogate",
           "AcousticFormatError", "AcousticRangeError", "AcousticRangeWarning", "ACOUSTIC_FORMAT",
           "ACOUSTIC_FORMAT_VERSION"]

ACOUSTIC_FORMAT = "bubblecal-acoustic-surrogate"
ACOUSTIC_FORMAT_VERSION = 1
MODEL = "f_res^2 = a0 + a1*ka + a2*ka^2; f_res physical resonance frequency [MHz] (sqrt(mass_factor) applied), ka [DPD]"


class AcousticFormatError(ValueError):
    """An acoustic surrogate JSON file is malformed (message names file and field)."""


class AcousticRangeError(ValueError):
    """k_a outside the fitted range (or an unknown diameter)."""


class AcousticRangeWarning(UserWarning):
    """k_a outside the fitted range of an acoustic surrogate."""


# ------------------------------------------------------------------------------------------------
# ringdown
# ------------------------------------------------------------------------------------------------
def damped_sine(t, R0, c, A, B, lam, omega_d):
    """R(t) = R0 + c t + exp(-lam t) [A sin(w_d t) + B cos(w_d t)] (numpy)."""
    t = np.asarray(t, dtype=float)
    env = np.exp(-lam * t)
    return R0 + c * t + env * (A * np.sin(omega_d * t) + B * np.cos(omega_d * t))


@dataclass
class RingdownFit:
    """Result of :func:`fit_ringdown` (time units of the input ``t``)."""

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
        return self.omega_d / (2 * math.pi)

    @property
    def f_0(self) -> float:
        return math.sqrt(self.omega_d**2 + self.lam**2) / (2 * math.pi)

    @property
    def f_res(self) -> float:
        """sqrt(w_d^2 - lam^2) / 2 pi (NaN when over-damped, lam > w_d)."""
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
        """f_res, f_0, f_d in MHz for ``t`` in DPD time units, with the sqrt(M) mass correction."""
        conv = float(units.frequency_to_physical(1.0, mass_factor)) / 1e6
        return {"f_res": self.f_res * conv, "f_0": self.f_0 * conv, "f_d": self.f_d * conv}

    def as_dict(self) -> dict:
        d = asdict(self)
        d.update({"f_res": self.f_res, "f_0": self.f_0, "f_d": self.f_d, "f_res_stderr": self.f_res_stderr})
        return d

    def predict(self, t) -> np.ndarray:
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
    """Fit the damped sine plus linear trend to a ringdown trace (see module docstring).

    ``t`` must be increasing and (for the spectral start) roughly uniform; points before
    ``t_start`` are dropped; time is measured from the first kept sample.
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


# ------------------------------------------------------------------------------------------------
# f_res^2(k_a) quadratics
# ------------------------------------------------------------------------------------------------
@dataclass
class DiameterFit:
    """Quadratic f_res^2 = a0 + a1 ka + a2 ka^2 at one diameter, with its leave-one-out errors."""

    diameter_um: float
    a0: float
    a1: float
    a2: float
    ka_min: float
    ka_max: float
    n_points: int
    loo_rel_errors: list[float]
    meta: dict = field(default_factory=dict)

    @property
    def loo_max(self) -> float:
        return float(np.max(self.loo_rel_errors)) if self.loo_rel_errors else float("nan")

    @property
    def loo_median(self) -> float:
        return float(np.median(self.loo_rel_errors)) if self.loo_rel_errors else float("nan")

    def to_dict(self) -> dict:
        d = asdict(self)
        d.update({"loo_max": self.loo_max, "loo_median": self.loo_median})
        return d


def fit_quadratic(ka, f_res, diameter_um: float, meta: Mapping | None = None) -> DiameterFit:
    """Least-squares quadratic of f_res^2 against ka (free intercept) + leave-one-out relative errors.

    ``f_res`` in physical MHz (see module docstring); LOO errors are |f_hat - f| / f of f_res.
    """
    ka = np.asarray(ka, dtype=float)
    f = np.asarray(f_res, dtype=float)
    ok = np.isfinite(ka) & np.isfinite(f) & (f > 0)
    ka, f = ka[ok], f[ok]
    if ka.size < 3 or np.unique(ka).size < 3:
        raise ValueError(f"diameter {diameter_um} um: need >= 3 distinct ka values with finite f_res > 0, "
                         f"got {np.unique(ka).size}")
    # fit in a scaled variable for conditioning, then convert back
    s = float(np.max(np.abs(ka)))
    q = np.polynomial.polynomial.polyfit(ka / s, f**2, 2)
    a0, a1, a2 = q[0], q[1] / s, q[2] / s**2
    loo = []
    if ka.size >= 4:
        for i in range(ka.size):
            m = np.arange(ka.size) != i
            qi = np.polynomial.polynomial.polyfit(ka[m] / s, f[m] ** 2, 2)
            f2 = qi[0] + qi[1] * ka[i] / s + qi[2] * (ka[i] / s) ** 2
            loo.append(float(abs(math.sqrt(max(f2, 0.0)) - f[i]) / f[i]))
    return DiameterFit(diameter_um=float(diameter_um), a0=float(a0), a1=float(a1), a2=float(a2),
                       ka_min=float(ka.min()), ka_max=float(ka.max()), n_points=int(ka.size), loo_rel_errors=loo,
                       meta=dict(meta or {}))


class AcousticSurrogate:
    """Per-diameter f_res(k_a) quadratics; JAX evaluation, JSON save/load, out-of-range flags."""

    def __init__(self, fits: Mapping[float, DiameterFit] | list[DiameterFit], name: str = "", meta: Mapping | None = None,
                 path: str | Path | None = None):
        items = list(fits.values()) if isinstance(fits, Mapping) else list(fits)
        self.fits: dict[float, DiameterFit] = {float(f.diameter_um): f for f in items}
        self.name = name
        self.meta = dict(meta or {})
        self.path = None if path is None else Path(path)

    @classmethod
    def fit(cls, data: Mapping[float, tuple], name: str = "", meta: Mapping | None = None) -> AcousticSurrogate:
        """``data`` maps diameter_um -> (ka array, f_res array [MHz])."""
        return cls([fit_quadratic(ka, f, d) for d, (ka, f) in data.items()], name=name, meta=meta)

    @property
    def diameters(self) -> list[float]:
        return sorted(self.fits)

    def _lookup(self, diameter_um, atol: float = 1e-6):
        d = np.atleast_1d(np.asarray(diameter_um, dtype=float))
        have = np.array(self.diameters)
        out = []
        for v in d.ravel():
            j = np.flatnonzero(np.abs(have - v) <= atol)
            if j.size == 0:
                raise AcousticRangeError(f"acoustic surrogate {self.name!r}: no fit at diameter {v:g} um "
                                         f"(fitted: {', '.join(f'{x:g}' for x in have)})")
            out.append(self.fits[float(have[j[0]])])
        return out, d.shape, np.ndim(diameter_um)

    def coefficients(self, diameter_um) -> np.ndarray:
        """(..., 3) array of (a0, a1, a2) for the requested diameter(s)."""
        fits, shape, _ = self._lookup(diameter_um)
        c = np.array([[f.a0, f.a1, f.a2] for f in fits]).reshape(*shape, 3)
        return c if np.ndim(diameter_um) else c[0]

    def ka_ranges(self, diameter_um) -> np.ndarray:
        """(..., 2) array of fitted (ka_min, ka_max) for the requested diameter(s)."""
        fits, shape, _ = self._lookup(diameter_um)
        r = np.array([[f.ka_min, f.ka_max] for f in fits]).reshape(*shape, 2)
        return r if np.ndim(diameter_um) else r[0]

    def f_res_squared(self, ka, diameter_um):
        """a0 + a1 ka + a2 ka^2 [MHz^2] (JAX); ``ka`` broadcasts against the diameter(s)' shape."""
        c = jnp.asarray(self.coefficients(diameter_um))
        ka = jnp.asarray(ka)
        return c[..., 0] + c[..., 1] * ka + c[..., 2] * ka * ka

    def f_res(self, ka, diameter_um):
        """Resonance frequency [MHz] = sqrt(max(f_res^2, 0)) (JAX, jit/vmap/grad-ready in ka).

        ``diameter_um`` is a host value (float or array) selecting fitted diameters (exact match).
        Use :meth:`in_range` / :meth:`check_range` for the validity of ``ka``.
        """
        return jnp.sqrt(jnp.maximum(self.f_res_squared(ka, diameter_um), 0.0))

    __call__ = f_res

    def in_range(self, ka, diameter_um, rtol: float = 1e-9):
        """Mask of ka inside the fitted range of its diameter (and a positive f_res^2). JAX."""
        r = jnp.asarray(self.ka_ranges(diameter_um))
        ka = jnp.asarray(ka)
        w = (r[..., 1] - r[..., 0]) * rtol
        return (ka >= r[..., 0] - w) & (ka <= r[..., 1] + w) & (self.f_res_squared(ka, diameter_um) > 0)

    def check_range(self, ka, diameter_um, action: str = "warn") -> np.ndarray:
        """Host-side check: warn or raise naming the diameter(s) and the fitted ranges."""
        if action not in ("warn", "raise"):
            raise ValueError(f"action must be 'warn' or 'raise', got {action!r}")
        mask = np.asarray(self.in_range(ka, diameter_um))
        if mask.all():
            return mask
        ka_b = np.broadcast_to(np.asarray(ka, dtype=float), mask.shape)
        d_b = np.broadcast_to(np.asarray(diameter_um, dtype=float), mask.shape)
        parts = []
        for d in np.unique(d_b[~mask]):
            sel = (~mask) & (d_b == d)
            lo, hi = self.ka_ranges(float(d))
            parts.append(f"{d:g} um: {int(sel.sum())} ka value(s) {ka_b[sel].min():.6g}..{ka_b[sel].max():.6g} "
                         f"outside the fitted [{lo:.6g}, {hi:.6g}]")
        msg = f"acoustic surrogate {self.name!r}: evaluation outside the fitted ka range: " + "; ".join(parts)
        if action == "raise":
            raise AcousticRangeError(msg)
        warnings.warn(msg, AcousticRangeWarning, stacklevel=2)
        return mask

    # -- persistence ------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """JSON-ready dict: format, version, model, units, name, meta, one entry per diameter."""
        return {"format": ACOUSTIC_FORMAT, "format_version": ACOUSTIC_FORMAT_VERSION, "model": MODEL,
                "frequency_units": "MHz", "ka_units": "DPD", "name": self.name, "meta": self.meta,
                "diameters": [self.fits[d].to_dict() for d in self.diameters]}

    def save(self, path: str | Path) -> Path:
        return atomic_write(path, lambda tmp: tmp.write_text(json.dumps(self.to_dict(), indent=2)))

    @classmethod
    def load(cls, path: str | Path) -> AcousticSurrogate:
        from bubblecal.surrogates.bundle import read_versioned_json

        path = Path(path)
        d = read_versioned_json(path, ACOUSTIC_FORMAT, ACOUSTIC_FORMAT_VERSION, AcousticFormatError,
                                "acoustic surrogate file")
        if d.get("frequency_units") != "MHz":
            raise AcousticFormatError(f"{path}: field 'frequency_units' must be 'MHz'")
        fits = []
        keys = ("diameter_um", "a0", "a1", "a2", "ka_min", "ka_max", "n_points", "loo_rel_errors")
        for i, e in enumerate(d.get("diameters", [])):
            for k in keys:
                if k not in e:
                    raise AcousticFormatError(f"{path}: diameters[{i}] lacks field '{k}'")
            fits.append(DiameterFit(**{k: e[k] for k in keys}, meta=e.get("meta", {})))
        if not fits:
            raise AcousticFormatError(f"{path}: field 'diameters' is empty")
        return cls(fits, name=d.get("name", ""), meta=d.get("meta", {}), path=path)
