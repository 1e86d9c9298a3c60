"""Fitting the diameter-continuous resonance law and scoring it by leaving diameters out.

The coefficients of a :class:`~bubblecal.surrogates.resonance_law.LawForm` are linear in f_res^2, so the fit is
a least-squares problem; each row is weighted by 1 / f_res^2 so that the residual is the relative error of
f_res^2 (about twice that of f_res) at every size and stiffness, instead of letting the stiff, small bubbles
(largest f_res^2) dominate. Hold-out errors are |f_hat - f| / f of f_res at rows never fitted: each simulated
diameter left out in turn (the end diameters are then extrapolations), and whole diameter bands.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from bubblecal.surrogates.resonance_law import DEFAULT_LAW_FORM, LAW_FORMS, LawForm, ResonanceLaw

__all__ = ["fit_law", "law_coefficients", "law_predict", "holdout_errors", "leave_diameters_out",
           "compare_forms", "DEFAULT_BANDS_UM"]

#: Diameter bands held out by default [um] (closed intervals).
DEFAULT_BANDS_UM = ((3.5, 4.5),)


def _form(form: str | LawForm) -> LawForm:
    """The :class:`LawForm` named ``form`` (ValueError naming the known forms otherwise)."""
    if isinstance(form, LawForm):
        return form
    if form not in LAW_FORMS:
        raise ValueError(f"unknown resonance-law form {form!r}; known: {', '.join(LAW_FORMS)}")
    return LAW_FORMS[form]


def _clean(diameter_um, ka, f_res):
    """Float arrays of equal length, keeping the rows with finite values and f_res > 0."""
    d, ka, f = (np.asarray(v, dtype=float).ravel() for v in (diameter_um, ka, f_res))
    if not d.size == ka.size == f.size:
        raise ValueError(f"diameter_um, ka and f_res must have one length, got {d.size}, {ka.size}, {f.size}")
    ok = np.isfinite(d) & np.isfinite(ka) & np.isfinite(f) & (f > 0) & (d > 0)
    return d[ok], ka[ok], f[ok]


def law_coefficients(diameter_um, ka, f_res, form: str | LawForm = DEFAULT_LAW_FORM) -> np.ndarray:
    """Relative least-squares coefficients of a form (no cleaning, no hold-out).

    Parameters
    ----------
    diameter_um, ka, f_res : array_like
        (n,) rows: diameter [um], stretching modulus [DPD 2-D modulus], resonance frequency [MHz] (> 0).
    form : str or LawForm
        The law's form.

    Returns
    -------
    numpy.ndarray
        Coefficients in the order of :meth:`LawForm.terms`.

    Raises
    ------
    ValueError
        When the rows cannot determine the coefficients (too few rows or diameters: rank deficient).
    """
    lf = _form(form)
    f2 = np.asarray(f_res, dtype=float) ** 2
    a = lf.design(diameter_um, ka) / f2[:, None]
    scale = np.abs(a).max(axis=0)
    scale[scale == 0] = 1.0
    sol, _, rank, _ = np.linalg.lstsq(a / scale, np.ones_like(f2), rcond=None)
    if rank < lf.n_coefficients:
        raise ValueError(f"form {lf.name!r}: {f2.size} rows over {np.unique(diameter_um).size} diameters cannot "
                         f"determine its {lf.n_coefficients} coefficients (rank {rank})")
    return sol / scale


def law_predict(coefficients, diameter_um, ka, form: str | LawForm = DEFAULT_LAW_FORM) -> np.ndarray:
    """f_res [MHz] of a form's coefficients (0 where the law's f_res^2 <= 0).

    Parameters
    ----------
    coefficients : array_like
        As returned by :func:`law_coefficients`.
    diameter_um, ka : array_like
        Diameters [um] and stretching moduli [DPD 2-D modulus].
    form : str or LawForm
        The law's form.

    Returns
    -------
    numpy.ndarray
        f_res [MHz].
    """
    f2 = _form(form).design(diameter_um, ka) @ np.asarray(coefficients, dtype=float)
    return np.sqrt(np.maximum(f2, 0.0))


def holdout_errors(diameter_um, ka, f_res, held_out, form: str | LawForm = DEFAULT_LAW_FORM) -> np.ndarray:
    """Relative errors of f_res at the held-out rows of a law fitted to the others.

    Parameters
    ----------
    diameter_um, ka, f_res : array_like
        (n,) rows [um, DPD 2-D modulus, MHz].
    held_out : array_like of bool
        (n,) rows left out of the fit.
    form : str or LawForm
        The law's form.

    Returns
    -------
    numpy.ndarray
        |f_hat - f| / f at the held-out rows.

    Raises
    ------
    ValueError
        When the remaining rows cannot determine the coefficients.
    """
    d, k, f = (np.asarray(v, dtype=float) for v in (diameter_um, ka, f_res))
    m = np.asarray(held_out, dtype=bool)
    c = law_coefficients(d[~m], k[~m], f[~m], form)
    return np.abs(law_predict(c, d[m], k[m], form) / f[m] - 1.0)


def leave_diameters_out(diameter_um, ka, f_res, form: str | LawForm = DEFAULT_LAW_FORM,
                        bands_um: Sequence[tuple[float, float]] = DEFAULT_BANDS_UM) -> dict:
    """Hold-out errors: each simulated diameter left out in turn, then each band of diameters.

    Parameters
    ----------
    diameter_um, ka, f_res : array_like
        (n,) rows [um, DPD 2-D modulus, MHz].
    form : str or LawForm
        The law's form.
    bands_um : sequence of (float, float)
        Closed diameter intervals [um] left out as a whole.

    Returns
    -------
    dict
        ``per_diameter`` (list of {diameter_um, median, max, n}), ``median`` and ``max`` over every
        left-out row of the single-diameter hold-outs, ``bands`` (list of {band_um, median, max, n}).

    Raises
    ------
    ValueError
        For a band that holds no simulated diameter or leaves too few rows to fit.
    """
    d, k, f = _clean(diameter_um, ka, f_res)
    per, every = [], []
    for dia in np.unique(d):
        e = holdout_errors(d, k, f, d == dia, form)
        every.append(e)
        per.append({"diameter_um": float(dia), "median": float(np.median(e)), "max": float(e.max()), "n": int(e.size)})
    every = np.concatenate(every)
    bands = []
    for lo, hi in bands_um:
        m = (d >= lo) & (d <= hi)
        if not m.any():
            raise ValueError(f"hold-out band [{lo:g}, {hi:g}] um holds no simulated diameter")
        e = holdout_errors(d, k, f, m, form)
        bands.append({"band_um": [float(lo), float(hi)], "diameters_um": np.unique(d[m]).tolist(),
                      "median": float(np.median(e)), "max": float(e.max()), "n": int(e.size)})
    return {"per_diameter": per, "median": float(np.median(every)), "max": float(every.max()), "bands": bands}


def fit_law(diameter_um, ka, f_res, form: str | LawForm = DEFAULT_LAW_FORM,
            bands_um: Sequence[tuple[float, float]] = DEFAULT_BANDS_UM, meta: Mapping | None = None) -> ResonanceLaw:
    """Fit a form to ringdown rows over several diameters, with its leave-diameters-out errors.

    Rows with a non-finite value or f_res <= 0 are dropped. The k_a range of each simulated diameter is the range
    of its kept rows.

    Parameters
    ----------
    diameter_um, ka, f_res : array_like
        (n,) rows: diameter [um], stretching modulus [DPD 2-D modulus], resonance frequency [MHz].
    form : str or LawForm
        The law's form (a key of :data:`~bubblecal.surrogates.resonance_law.LAW_FORMS`).
    bands_um : sequence of (float, float)
        Diameter bands [um] held out as a whole (besides each diameter).
    meta : Mapping, optional
        Provenance stored with the law.

    Returns
    -------
    ResonanceLaw
        Coefficients, diameter and k_a ranges, hold-out errors, in-sample errors in ``meta['in_sample']``.

    Raises
    ------
    ValueError
        For an unknown form, fewer than 3 simulated diameters, a diameter with fewer than 3 distinct k_a values,
        rows that cannot determine the coefficients, or an empty band.
    """
    lf = _form(form)
    d, k, f = _clean(diameter_um, ka, f_res)
    nodes = np.unique(d)
    if nodes.size < 3:
        raise ValueError(f"a resonance law needs >= 3 simulated diameters, got {nodes.size} ({nodes.tolist()})")
    for dia in nodes:
        if np.unique(k[d == dia]).size < 3:
            raise ValueError(f"diameter {dia:g} um: need >= 3 distinct ka values with finite f_res > 0")
    c = law_coefficients(d, k, f, lf)
    ins = np.abs(law_predict(c, d, k, lf) / f - 1.0)
    info = {"fit": "least squares of f_res^2 with weights 1/f_res^2 (relative residuals)",
            "in_sample": {"median": float(np.median(ins)), "max": float(ins.max())}, **dict(meta or {})}
    return ResonanceLaw(form=lf.name, powers=lf.powers, coefficients=tuple(float(v) for v in c),
                        diameters_um=tuple(float(v) for v in nodes),
                        ka_min=tuple(float(k[d == v].min()) for v in nodes),
                        ka_max=tuple(float(k[d == v].max()) for v in nodes), n_points=int(d.size),
                        holdout=leave_diameters_out(d, k, f, lf, bands_um), meta=info)


def compare_forms(diameter_um, ka, f_res, forms: Sequence[str] | None = None,
                  bands_um: Sequence[tuple[float, float]] = DEFAULT_BANDS_UM) -> dict:
    """In-sample and hold-out errors of several forms on the same rows (the measurement behind the choice).

    Parameters
    ----------
    diameter_um, ka, f_res : array_like
        (n,) rows [um, DPD 2-D modulus, MHz].
    forms : sequence of str, optional
        Form names (default: every form of :data:`~bubblecal.surrogates.resonance_law.LAW_FORMS`).
    bands_um : sequence of (float, float)
        Diameter bands [um] held out as a whole.

    Returns
    -------
    dict
        form name -> {n_coefficients, in_sample {median, max}, ldo_median, ldo_max, bands}.
    """
    out = {}
    for name in forms or list(LAW_FORMS):
        law = fit_law(diameter_um, ka, f_res, name, bands_um)
        out[name] = {"n_coefficients": LAW_FORMS[name].n_coefficients, "in_sample": law.meta["in_sample"],
                     "ldo_median": law.holdout["median"], "ldo_max": law.holdout["max"],
                     "bands": law.holdout["bands"]}
    return out
