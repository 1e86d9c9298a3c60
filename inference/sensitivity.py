"""Variance-based (Sobol) sensitivity of a vectorised map along a loading coordinate.

The analysis of ``docs/inference.md`` section 8. Knows no physics. For a function
``fn(params[..., D], x[...]) -> y[...]`` (e.g. a surrogate, params in its input order) and a box of D
parameter ranges, :func:`sobol_along`

1. draws SALib's Saltelli design (``SALib.sample.sobol.sample``, scrambled Sobol' sequence) with
   base sample size N (default 2,048, a power of two), N (D + 2) rows without second-order terms;
2. evaluates ``fn`` at every design row and every loading coordinate x_p (one broadcast call, or
   batches of rows): outputs Y (N (D + 2), P);
3. computes first-order S1 and total ST indices with SALib's estimators and bootstrap confidence
   intervals (``SALib.analyze.sobol.analyze``: ``num_resamples`` resamples, half-widths at
   ``conf_level``) separately at every x_p;
4. averages indices and confidence half-widths over the points inside ``x_range`` (the
   experimentally explored range), ignoring points where the output has no variance (there the
   indices are undefined and stored as NaN).

SALib (the ``[sensitivity]`` extra) is imported inside the functions, so importing this module costs nothing.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from bubblecal._extras import require

__all__ = ["SobolResult", "saltelli_design", "sobol_indices", "sobol_along"]


@dataclass(frozen=True)
class SobolResult:
    """Sobol indices along a loading coordinate.

    Parameters
    ----------
    names : tuple of str
        The D varied inputs.
    x : numpy.ndarray
        (P,) loading coordinates (units of the map's x).
    S1, S1_conf, ST, ST_conf : numpy.ndarray
        (P, D) first-order and total indices and the half-widths of their ``conf_level`` bootstrap
        intervals (NaN where the output has no variance).
    x_range : tuple of float
        The averaging range of x.
    in_range : numpy.ndarray
        (P,) booleans: inside ``x_range`` and with non-zero output variance.
    S1_mean, S1_conf_mean, ST_mean, ST_conf_mean : numpy.ndarray
        (D,) averages over the points selected by ``in_range``.
    N : int
        Saltelli base sample size.
    n_evaluations : int
        Design rows, i.e. evaluations per point.
    conf_level : float
        Confidence level of the intervals.
    """

    names: tuple[str, ...]
    x: np.ndarray
    S1: np.ndarray
    S1_conf: np.ndarray
    ST: np.ndarray
    ST_conf: np.ndarray
    x_range: tuple[float, float]
    in_range: np.ndarray
    S1_mean: np.ndarray
    S1_conf_mean: np.ndarray
    ST_mean: np.ndarray
    ST_conf_mean: np.ndarray
    N: int
    n_evaluations: int
    conf_level: float

    def table(self) -> list[dict]:
        """One row per parameter: name, S1, S1_conf, ST, ST_conf (averaged over the x-range).

        Returns
        -------
        list of dict
        """
        return [{"parameter": n, "S1": float(self.S1_mean[j]), "S1_conf": float(self.S1_conf_mean[j]),
                 "ST": float(self.ST_mean[j]), "ST_conf": float(self.ST_conf_mean[j])}
                for j, n in enumerate(self.names)]

    def summary(self) -> str:
        """Plain-text table of the averaged indices.

        Returns
        -------
        str
        """
        lines = [f"Sobol indices (Saltelli N = {self.N}, {self.n_evaluations} evaluations per point, "
                 f"x in [{self.x_range[0]:g}, {self.x_range[1]:g}], {int(self.in_range.sum())} points, "
                 f"{100 * self.conf_level:g}% CI)",
                 f"{'parameter':>10} {'S1':>8} {'±':>7} {'ST':>8} {'±':>7}"]
        for row in self.table():
            lines.append(f"{row['parameter']:>10} {row['S1']:8.4f} {row['S1_conf']:7.4f} {row['ST']:8.4f} "
                         f"{row['ST_conf']:7.4f}")
        return "\n".join(lines)


def _problem(bounds):
    """SALib problem dict of a parameter box (validated)."""
    if isinstance(bounds, Mapping):
        names = tuple(bounds)
        box = [tuple(map(float, bounds[n])) for n in names]
    else:
        names, box = tuple(bounds[0]), [tuple(map(float, b)) for b in zip(bounds[1], bounds[2], strict=True)]
    if not names:
        raise ValueError("the parameter box is empty")
    for n, (lo, hi) in zip(names, box, strict=True):
        if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
            raise ValueError(f"parameter {n!r}: bounds must be finite with lo < hi, got [{lo}, {hi}]")
    return {"num_vars": len(names), "names": list(names), "bounds": [list(b) for b in box]}


def saltelli_design(bounds, N: int = 2048, *, calc_second_order: bool = False, seed: int | None = 0) -> np.ndarray:
    """SALib Saltelli design over a parameter box.

    Parameters
    ----------
    bounds : mapping or tuple
        Name -> (lo, hi) in the function's input order, or (names, lo, hi) (units of each input).
    N : int
        Base sample size, a power of two >= 2.
    calc_second_order : bool
        Include the second-order rows.
    seed : int or None
        Seed of the scrambled Sobol' sequence.

    Returns
    -------
    numpy.ndarray
        (N (D + 2), D) rows (N (2D + 2) with second-order terms).

    Raises
    ------
    ValueError
        For an N that is not a power of two, an empty box, or bounds that are not finite with lo < hi.
    """
    sobol_sample = require("SALib.sample.sobol", "sensitivity")

    if N < 2 or (N & (N - 1)) != 0:
        raise ValueError(f"N must be a power of two >= 2 (Sobol' sequence balance), got {N}")
    return sobol_sample.sample(_problem(bounds), N, calc_second_order=calc_second_order, seed=seed)


def sobol_indices(problem_bounds, Y, *, calc_second_order: bool = False, num_resamples: int = 100,
                  conf_level: float = 0.95, seed: int | None = 0):
    """First-order and total Sobol indices at every output column.

    Parameters
    ----------
    problem_bounds : mapping or tuple
        The box of the design (as :func:`saltelli_design`).
    Y : array_like
        Outputs on the design, shape (rows,) or (rows, P).
    calc_second_order : bool
        Whether the design has the second-order rows.
    num_resamples : int
        Bootstrap resamples of the confidence intervals.
    conf_level : float
        Confidence level.
    seed : int or None
        Seed of the bootstrap.

    Returns
    -------
    S1, S1_conf, ST, ST_conf : numpy.ndarray
        (P, D) each; columns of ``Y`` with zero variance give NaN.

    Raises
    ------
    ValueError
        If ``Y`` has non-finite values or the box is invalid.
    """
    sobol_analyze = require("SALib.analyze.sobol", "sensitivity")

    problem = _problem(problem_bounds)
    Y = np.asarray(Y, dtype=float)
    if Y.ndim == 1:
        Y = Y[:, None]
    if not np.isfinite(Y).all():
        raise ValueError("the function returned non-finite values on the design")
    D, P = problem["num_vars"], Y.shape[1]
    out = np.full((4, P, D), np.nan)
    for p in range(P):
        if np.var(Y[:, p]) <= 1e-300:
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            res = sobol_analyze.analyze(problem, Y[:, p], calc_second_order=calc_second_order,
                                        num_resamples=num_resamples, conf_level=conf_level,
                                        print_to_console=False, seed=seed)
        out[:, p, :] = res["S1"], res["S1_conf"], res["ST"], res["ST_conf"]
    return out[0], out[1], out[2], out[3]


def sobol_along(fn: Callable, bounds, x, *, N: int = 2048, x_range: tuple[float, float] | None = None,
                num_resamples: int = 100, conf_level: float = 0.95, seed: int | None = 0,
                batch_size: int | None = None, order: tuple[str, ...] | None = None,
                fixed: Mapping[str, float] | None = None) -> SobolResult:
    """First-order and total Sobol indices of ``fn`` pointwise along ``x`` and averaged over ``x_range``.

    Parameters
    ----------
    fn : callable
        ``fn(params, x)`` called with ``params`` of shape (n, 1, D) and ``x`` of shape (1, P); returns
        (n, P) (the broadcasting convention of the surrogates).
    bounds : mapping or tuple
        The D varied input names (in ``fn``'s order) -> (lo, hi), or (names, lo, hi).
    x : array_like
        (P,) loading coordinates (units of ``fn``'s x, e.g. DPD length).
    N : int
        Saltelli base sample size (a power of two).
    x_range : tuple of float or None
        Averaging range of x (default [min x, max x]).
    num_resamples : int
        Bootstrap resamples.
    conf_level : float
        Confidence level of the intervals.
    seed : int or None
        Seed of the design and of the bootstrap.
    batch_size : int or None
        Design rows per call of ``fn``.
    order : tuple of str or None
        ``fn``'s input names; with ``fixed`` varies only the names of ``bounds`` and holds the others
        constant, e.g. a reduced shell: ``order=("ka", "kb", "b1", "b2", "a3", "a4")``,
        ``fixed={"b1": 0, "b2": 0, "a3": 0, "a4": 0}``.
    fixed : mapping of str to float or None
        Values of the inputs that are not varied.

    Returns
    -------
    SobolResult

    Raises
    ------
    ValueError
        For an invalid box or N, inputs without a value, ``fixed`` without ``order``, non-finite
        outputs, or no point with output variance inside ``x_range``.
    """
    problem = _problem(bounds)
    names = tuple(problem["names"])
    x = np.atleast_1d(np.asarray(x, dtype=float))
    X = saltelli_design(bounds, N, seed=seed)
    rows = X.shape[0]
    if order is not None:
        fixed = dict(fixed or {})
        missing = [n for n in order if n not in names and n not in fixed]
        extra = [n for n in names if n not in order]
        if missing or extra:
            raise ValueError(f"order {order}: no value for {missing} (give bounds or fixed); unknown {extra}")
        full = np.empty((rows, len(order)))
        for j, n in enumerate(order):
            full[:, j] = X[:, names.index(n)] if n in names else float(fixed[n])
        X = full
    elif fixed:
        raise ValueError("fixed values need order= (the function's input names)")
    step = rows if batch_size is None else int(batch_size)
    chunks = []
    for start in range(0, rows, step):
        out = np.asarray(fn(X[start:start + step, None, :], x[None, :]), dtype=float)
        chunks.append(np.broadcast_to(out, (min(step, rows - start), x.size)))
    Y = np.concatenate(chunks, axis=0)
    S1, S1c, ST, STc = sobol_indices(bounds, Y, num_resamples=num_resamples, conf_level=conf_level, seed=seed)
    lo, hi = (float(x.min()), float(x.max())) if x_range is None else (float(x_range[0]), float(x_range[1]))
    in_range = (x >= lo) & (x <= hi) & np.isfinite(S1).all(axis=1)
    if not in_range.any():
        raise ValueError(f"no loading coordinate with output variance inside x_range [{lo:g}, {hi:g}]")
    mean = [a[in_range].mean(axis=0) for a in (S1, S1c, ST, STc)]
    return SobolResult(names=names, x=x, S1=S1, S1_conf=S1c, ST=ST, ST_conf=STc, x_range=(lo, hi),
                       in_range=in_range, S1_mean=mean[0], S1_conf_mean=mean[1], ST_mean=mean[2],
                       ST_conf_mean=mean[3], N=int(N), n_evaluations=int(rows), conf_level=float(conf_level))
