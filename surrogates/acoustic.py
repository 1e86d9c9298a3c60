"""Acoustic surrogates: per-diameter quadratics of the squared resonance frequency in k_a.

Per simulated diameter d, a least-squares quadratic with free intercept

    f_res(k_a; d)^2 = a0 + a1 k_a + a2 k_a^2,     f_res in **physical MHz**, k_a in **DPD units**

(so ``A_d(k_a) = sqrt(a0 + a1 k_a + a2 k_a^2)`` is directly the model of docs/inference.md section 3), fitted
to ringdown resonance frequencies (:mod:`bubblecal.surrogates.ringdown`), with leave-one-out relative errors
of f_res (:mod:`bubblecal.surrogates.resonance`). Valid only inside the fitted k_a range: use
:meth:`AcousticSurrogate.in_range` / :meth:`AcousticSurrogate.check_range` (never silent). JSON format
``bubblecal-acoustic-surrogate`` version 1 (docs/data-formats.md; :meth:`AcousticSurrogate.to_dict`); version 2
files hold a law continuous in the diameter and load as
:class:`~bubblecal.surrogates.acoustic_law.AcousticLawSurrogate`.
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Mapping
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from bubblecal.data import atomic_write
from bubblecal.surrogates.fileio import read_versioned_json
from bubblecal.surrogates.resonance import DiameterFit, fit_quadratic

__all__ = ["AcousticSurrogate", "AcousticFormatError", "AcousticRangeError", "AcousticRangeWarning",
           "ACOUSTIC_FORMAT", "ACOUSTIC_FORMAT_VERSION"]

#: ``format`` of an acoustic surrogate file.
ACOUSTIC_FORMAT = "bubblecal-acoustic-surrogate"
#: ``format_version`` written and read.
ACOUSTIC_FORMAT_VERSION = 1
#: The law, as recorded in the file's ``model`` field.
MODEL = ("f_res^2 = a0 + a1*ka + a2*ka^2; f_res physical resonance frequency [MHz] (sqrt(mass_factor) applied), "
         "ka [DPD]")


class AcousticFormatError(ValueError):
    """An acoustic surrogate JSON file is malformed (message names file and field)."""


class AcousticRangeError(ValueError):
    """k_a outside the fitted range (or an unknown diameter)."""


class AcousticRangeWarning(UserWarning):
    """k_a outside the fitted range of an acoustic surrogate."""


class AcousticSurrogate:
    """Per-diameter f_res(k_a) quadratics; JAX evaluation, JSON save/load, out-of-range flags.

    Parameters
    ----------
    fits : Mapping of float to DiameterFit, or list of DiameterFit
        One fit per diameter.
    name : str
        Agent or label (e.g. ``'definity'``).
    meta : Mapping, optional
        Provenance stored in the file.
    path : str or Path, optional
        The file it was loaded from.
    """

    def __init__(self, fits: Mapping[float, DiameterFit] | list[DiameterFit], name: str = "",
                 meta: Mapping | None = None, path: str | Path | None = None):
        items = list(fits.values()) if isinstance(fits, Mapping) else list(fits)
        self.fits: dict[float, DiameterFit] = {float(f.diameter_um): f for f in items}
        self.name = name
        self.meta = dict(meta or {})
        self.path = None if path is None else Path(path)

    @classmethod
    def fit(cls, data: Mapping[float, tuple], name: str = "", meta: Mapping | None = None) -> AcousticSurrogate:
        """Fit one quadratic per diameter (:func:`fit_quadratic`).

        Parameters
        ----------
        data : Mapping of float to (array_like, array_like)
            diameter [um] -> (ka [DPD 2-D modulus], f_res [MHz]).
        name : str
            Agent or label.
        meta : Mapping, optional
            Provenance.

        Returns
        -------
        AcousticSurrogate
            The fitted surrogate.

        Raises
        ------
        ValueError
            When a diameter has fewer than 3 distinct usable k_a values.
        """
        return cls([fit_quadratic(ka, f, d) for d, (ka, f) in data.items()], name=name, meta=meta)

    @property
    def diameters(self) -> list[float]:
        """Fitted diameters [um], sorted."""
        return sorted(self.fits)

    def _lookup(self, diameter_um, atol: float = 1e-6):
        """The fits of the requested diameter(s); AcousticRangeError for a diameter not fitted."""
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
        """(..., 3) array of (a0, a1, a2) for the requested diameter(s).

        Parameters
        ----------
        diameter_um : float or array_like
            Fitted diameter(s) [um].

        Returns
        -------
        numpy.ndarray
            Coefficients [MHz^2, MHz^2 per DPD 2-D modulus, MHz^2 per (DPD 2-D modulus)^2].

        Raises
        ------
        AcousticRangeError
            For a diameter that was not fitted.
        """
        fits, shape, _ = self._lookup(diameter_um)
        c = np.array([[f.a0, f.a1, f.a2] for f in fits]).reshape(*shape, 3)
        return c if np.ndim(diameter_um) else c[0]

    def ka_ranges(self, diameter_um) -> np.ndarray:
        """(..., 2) array of the fitted (ka_min, ka_max) for the requested diameter(s).

        Parameters
        ----------
        diameter_um : float or array_like
            Fitted diameter(s) [um].

        Returns
        -------
        numpy.ndarray
            k_a ranges [DPD 2-D modulus].

        Raises
        ------
        AcousticRangeError
            For a diameter that was not fitted.
        """
        fits, shape, _ = self._lookup(diameter_um)
        r = np.array([[f.ka_min, f.ka_max] for f in fits]).reshape(*shape, 2)
        return r if np.ndim(diameter_um) else r[0]

    def f_res_squared(self, ka, diameter_um):
        """The squared resonance frequency a0 + a1 ka + a2 ka^2 (JAX).

        Parameters
        ----------
        ka : array_like
            Stretching modulus [DPD 2-D modulus]; broadcasts against the diameters' shape.
        diameter_um : float or array_like
            Fitted diameter(s) [um].

        Returns
        -------
        jax.Array
            f_res^2 [MHz^2] (may be negative outside the fitted range).
        """
        c = jnp.asarray(self.coefficients(diameter_um))
        ka = jnp.asarray(ka)
        return c[..., 0] + c[..., 1] * ka + c[..., 2] * ka * ka

    def f_res(self, ka, diameter_um):
        """Resonance frequency sqrt(max(f_res^2, 0)) (JAX, jit/vmap/grad-ready in ka).

        Use :meth:`in_range` / :meth:`check_range` for the validity of ``ka``.

        Parameters
        ----------
        ka : array_like
            Stretching modulus [DPD 2-D modulus]; broadcasts against the diameters' shape.
        diameter_um : float or array_like
            Host value(s) selecting fitted diameters [um] (exact match).

        Returns
        -------
        jax.Array
            f_res [MHz].

        Raises
        ------
        AcousticRangeError
            For a diameter that was not fitted.
        """
        return jnp.sqrt(jnp.maximum(self.f_res_squared(ka, diameter_um), 0.0))

    __call__ = f_res

    def in_range(self, ka, diameter_um, rtol: float = 1e-9):
        """Mask of ka inside the fitted range of its diameter (and a positive f_res^2); JAX.

        Parameters
        ----------
        ka : array_like
            Stretching modulus [DPD 2-D modulus].
        diameter_um : float or array_like
            Fitted diameter(s) [um].
        rtol : float
            Widening of the range, relative to its width.

        Returns
        -------
        jax.Array of bool
            True where ka is valid.
        """
        r = jnp.asarray(self.ka_ranges(diameter_um))
        ka = jnp.asarray(ka)
        w = (r[..., 1] - r[..., 0]) * rtol
        return (ka >= r[..., 0] - w) & (ka <= r[..., 1] + w) & (self.f_res_squared(ka, diameter_um) > 0)

    def check_range(self, ka, diameter_um, action: str = "warn") -> np.ndarray:
        """Host-side check of :meth:`in_range`: warn or raise naming the diameter(s) and the fitted ranges.

        Parameters
        ----------
        ka : array_like
            Stretching modulus [DPD 2-D modulus].
        diameter_um : float or array_like
            Fitted diameter(s) [um].
        action : {'warn', 'raise'}
            Emit an :class:`AcousticRangeWarning` or raise.

        Returns
        -------
        numpy.ndarray of bool
            The mask of valid points.

        Raises
        ------
        AcousticRangeError
            With ``action='raise'`` when a point is outside.
        ValueError
            For an unknown ``action``.
        """
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

    def to_dict(self) -> dict:
        """JSON-ready dict: format, version, model, units, name, meta, one entry per diameter."""
        return {"format": ACOUSTIC_FORMAT, "format_version": ACOUSTIC_FORMAT_VERSION, "model": MODEL,
                "frequency_units": "MHz", "ka_units": "DPD", "name": self.name, "meta": self.meta,
                "diameters": [self.fits[d].to_dict() for d in self.diameters]}

    def save(self, path: str | Path) -> Path:
        """Write the JSON file (:meth:`to_dict`) atomically.

        Parameters
        ----------
        path : str or Path
            Output file.

        Returns
        -------
        Path
            ``path``.
        """
        return atomic_write(path, lambda tmp: tmp.write_text(json.dumps(self.to_dict(), indent=2)))

    @classmethod
    def load(cls, path: str | Path) -> AcousticSurrogate:
        """Load an acoustic surrogate JSON file.

        Parameters
        ----------
        path : str or Path
            The file.

        Returns
        -------
        AcousticSurrogate
            The loaded surrogate: per-diameter quadratics (version 1) or an
            :class:`~bubblecal.surrogates.acoustic_law.AcousticLawSurrogate` (version 2, a law continuous in D).

        Raises
        ------
        FileNotFoundError
            When ``path`` is not a file.
        AcousticFormatError
            For invalid JSON, a wrong format or version, other frequency units or a missing field.
        """
        path = Path(path)
        d = read_versioned_json(path, ACOUSTIC_FORMAT, (ACOUSTIC_FORMAT_VERSION, 2), AcousticFormatError,
                                "acoustic surrogate file")
        if d["format_version"] == 2:  # a diameter-continuous law (the subclass lives beside its law)
            from bubblecal.surrogates.acoustic_law import AcousticLawSurrogate

            return AcousticLawSurrogate.from_file_dict(d, path)
        if d.get("frequency_units") != "MHz":
            raise AcousticFormatError(f"{path}: field 'frequency_units' must be 'MHz'")
        entries = d.get("diameters", [])
        if not isinstance(entries, list) or not entries:
            raise AcousticFormatError(f"{path}: field 'diameters' must be a non-empty list of fits")
        name, meta = d.get("name", ""), d.get("meta", {})
        if not isinstance(name, str) or not isinstance(meta, dict):
            raise AcousticFormatError(f"{path}: fields 'name' / 'meta' must be a string / an object")
        fits = [_fit_entry(path, i, e) for i, e in enumerate(entries)]
        return cls(fits, name=name, meta=meta, path=path)


def _number(value) -> bool:
    """A finite real number (not a bool)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _fit_entry(path: Path, i: int, e) -> DiameterFit:
    """One ``diameters[i]`` entry of a version-1 file as a :class:`DiameterFit`, every field's type checked."""
    where = f"{path}: diameters[{i}]"
    if not isinstance(e, dict):
        raise AcousticFormatError(f"{where} must be an object, got {type(e).__name__}")
    keys = ("diameter_um", "a0", "a1", "a2", "ka_min", "ka_max", "n_points", "loo_rel_errors")
    for k in keys:
        if k not in e:
            raise AcousticFormatError(f"{where} lacks field '{k}'")
    for k in ("diameter_um", "a0", "a1", "a2", "ka_min", "ka_max"):
        if not _number(e[k]):
            raise AcousticFormatError(f"{where} field '{k}' must be a finite number, got {e[k]!r}")
    if e["diameter_um"] <= 0 or e["ka_min"] > e["ka_max"]:
        raise AcousticFormatError(f"{where}: needs diameter_um > 0 and ka_min <= ka_max, got {e['diameter_um']!r}, "
                                  f"[{e['ka_min']!r}, {e['ka_max']!r}]")
    if not isinstance(e["n_points"], int) or isinstance(e["n_points"], bool) or e["n_points"] < 1:
        raise AcousticFormatError(f"{where} field 'n_points' must be an integer >= 1, got {e['n_points']!r}")
    loo = e["loo_rel_errors"]
    if not isinstance(loo, list) or not all(_number(v) for v in loo):
        raise AcousticFormatError(f"{where} field 'loo_rel_errors' must be a list of finite numbers")
    meta = e.get("meta", {})
    if not isinstance(meta, dict):
        raise AcousticFormatError(f"{where} field 'meta' must be an object")
    return DiameterFit(**{k: e[k] for k in keys}, meta=meta)
