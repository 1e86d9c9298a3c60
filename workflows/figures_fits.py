"""The grid of small fits: ``fit.png`` (then ``fit_2.png``, ``fit_3.png``, ... beyond one page).

One small panel per loading curve: the retained AFM points, the 90 % posterior-predictive band (observation noise
included), the predictive median and the MAP model curve; force [nN] against displacement [nm] for both protocols
(indentation: the model predicts the depth at each applied force, so its band is horizontal). Panels are ordered
by the bubble's diameter and titled "bubble (D µm)"; a page shares its force label and its legend and holds at most
:data:`FIT_PANELS_PER_PAGE` panels, the pages of a run being equally full.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from bubblecal.data import DEFAULT_UNITS
from bubblecal.workflows.plotting import COLOURS, figure_title, new_figure, save_figure, short_label, styled

__all__ = ["FIT_PANELS_PER_PAGE", "fit_pages", "grid_shape", "fit_curves", "fit_page", "fit_figure"]

#: Most panels on one page of the fit grid.
FIT_PANELS_PER_PAGE = 48
#: Most panel columns of a page (the page stays about as wide as a screen).
_MAX_COLUMNS = 8
#: Pages of at most this many panels use the large panels of a few-curve study.
_FEW = 4


def _nm(v):
    """DPD length -> nm."""
    return np.asarray(DEFAULT_UNITS.dpd_to_nm(v))


def _nN(v):
    """DPD force -> nN."""
    return np.asarray(DEFAULT_UNITS.dpd_to_nN(v))


def fit_pages(n: int, per_page: int = FIT_PANELS_PER_PAGE) -> list[range]:
    """Split ``n`` panels into the fewest pages of at most ``per_page`` panels, equally full.

    Parameters
    ----------
    n : int
        Number of panels (curves).
    per_page : int
        Most panels on one page.

    Returns
    -------
    list of range
        The panel indices of each page, in order; empty for ``n = 0``.
    """
    if n <= 0:
        return []
    pages = math.ceil(n / per_page)
    size = math.ceil(n / pages)
    return [range(i, min(i + size, n)) for i in range(0, n, size)]


def grid_shape(n: int) -> tuple[int, int]:
    """Rows and columns of a page of ``n`` panels: one row up to 4 panels, else the fewest empty cells with
    about as many columns as rows (at most 8 columns; a tie goes to the wider grid).

    Parameters
    ----------
    n : int
        Panels on the page (>= 1).

    Returns
    -------
    tuple of int
        (rows, columns).
    """
    if n <= _FEW:
        return 1, max(n, 1)
    best = None
    for cols in range(math.ceil(math.sqrt(n)), min(_MAX_COLUMNS, math.ceil(math.sqrt(2 * n))) + 1):
        rows = math.ceil(n / cols)
        key = (rows * cols - n, -cols)
        if best is None or key < best[0]:
            best = (key, (rows, cols))
    return best[1]


def _diameter(curve) -> float:
    """The bubble's measured diameter [um] (the nominal one when no measured one is known)."""
    return float(curve.bubble_diameter_um or curve.diameter_um)


def fit_curves(result) -> list:
    """The loading curves that have predictive bands, ordered by diameter (equal diameters keep the plan's order).

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
        A summarised run (``result.bands`` set).

    Returns
    -------
    list of bubblecal.data.LoadingCurve
    """
    curves = [c for c in result.plan.curves if c.name in result.bands]
    return sorted(curves, key=_diameter)


def _panel(ax, curve, b: dict, coverage: float, small: bool) -> None:
    """Draw one curve's data, predictive band, median and MAP curve on ``ax``."""
    ms, lw = (2.0, 1.0) if small else (3.5, 1.5)
    if b["kind"] == "compression":
        gx = _nm(b["grid"])
        ax.fill_between(gx, _nN(b["grid_lower"]), _nN(b["grid_upper"]), color=COLOURS[0], alpha=0.25, lw=0,
                        label="90 % predictive band")
        ax.plot(gx, _nN(b["grid_median"]), color=COLOURS[0], lw=lw, label="predictive median")
        if b.get("map_curve") is not None:
            ax.plot(gx, _nN(b["map_curve"]), color="k", lw=0.6 * lw, ls="--", label="MAP model")
        ax.plot(_nm(b["x"]), _nN(b["y"]), "o", ms=ms, mfc="white", mec="k", mew=0.6 * lw, label="AFM data")
    else:
        gf = _nN(b["grid"])
        ax.fill_betweenx(gf, _nm(b["grid_lower"]), _nm(b["grid_upper"]), color=COLOURS[1], alpha=0.25, lw=0,
                         label="90 % predictive band")
        ax.plot(_nm(b["grid_median"]), gf, color=COLOURS[1], lw=lw, label="predictive median")
        if b.get("map_curve") is not None:
            ax.plot(_nm(b["map_curve"]), gf, color="k", lw=0.6 * lw, ls="--", label="MAP model")
        ax.plot(_nm(b["y"]), _nN(b["x"]), "o", ms=ms, mfc="white", mec="k", mew=0.6 * lw, label="AFM data")
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)
    bubble = curve.name.removeprefix(f"{curve.agent}_") if curve.agent else curve.name
    ax.set_title(f"{short_label(bubble)} ({_diameter(curve):g} µm)", fontsize=7 if small else 9)
    if small:
        ax.tick_params(labelsize=6, length=2, pad=1)
    if math.isfinite(coverage):
        ax.text(0.03, 0.97, f"cov. {coverage:.2f}", transform=ax.transAxes, va="top", fontsize=6 if small else 8)


def _x_label(kinds: set[str]) -> str:
    """The shared x label of a page: displacement (compression), indentation depth, or both."""
    if kinds == {"compression"}:
        return "displacement [nm]"
    if kinds == {"indentation"}:
        return "indentation depth [nm]"
    return "displacement (compression) / indentation depth (indentation) [nm]"


def fit_page(result, plan, curves, page: int = 1, pages: int = 1):
    """One page of the fit grid: a panel per curve of ``curves``, in the given order.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
        A summarised run (``result.bands`` and ``result.summary`` set).
    plan : bubblecal.workflows.calibrate.Plan
    curves : sequence of bubblecal.data.LoadingCurve
        The page's curves (each with an entry in ``result.bands``).
    page, pages : int
        This page's number and the number of pages (named in the title when above 1).

    Returns
    -------
    matplotlib.figure.Figure
        One axes per curve (the empty cells of the grid are removed).
    """
    n = len(curves)
    rows, cols = grid_shape(n)
    small = n > _FEW
    w, h = (2.15, 1.8) if small else (3.4, 3.1)
    fig, axes = new_figure(rows, cols, figsize=(max(w * cols, 5.0), h * rows + 0.9), squeeze=False,
                           layout="constrained")
    flat = list(axes.ravel())
    cov = result.summary.groupby("dataset", sort=False)["coverage_90"].first()
    for ax, curve in zip(flat, curves, strict=False):
        _panel(ax, curve, result.bands[curve.name], float(cov.get(curve.name, math.nan)), small)
    for ax in flat[n:]:
        fig.delaxes(ax)
    # the x label under the lowest panel of each column (a figure-level label would collide with the legend)
    xlabel = _x_label({result.bands[c.name]["kind"] for c in curves})
    for i in range(n):
        if i + cols >= n:
            flat[i].set_xlabel(xlabel, fontsize=7 if small else 9)
    fig.supylabel("force [nN]", fontsize=9)
    handles, labels = flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=8)
    what = "loading curves by diameter, posterior predictive" + (f", page {page} of {pages}" if pages > 1 else "")
    fig.suptitle(figure_title(result, plan, what), fontsize=10)
    return fig


def _page_path(path: Path, page: int) -> Path:
    """``fit.png`` for page 1, ``fit_<page>.png`` after."""
    return path if page == 1 else path.with_name(f"{path.stem}_{page}{path.suffix}")


@styled
def fit_figure(result, plan, path: Path) -> list[Path]:
    """Write the fit grid: ``path`` and, beyond :data:`FIT_PANELS_PER_PAGE` curves, ``<stem>_2.png``, ...

    Further pages left by an earlier run with more curves in the same folder are removed, so the folder holds
    exactly this run's pages.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
        A summarised run (``result.bands`` set).
    plan : bubblecal.workflows.calibrate.Plan
    path : Path
        PNG of the first page.

    Returns
    -------
    list of Path
        The written pages in order; empty when no curve has bands.
    """
    curves = fit_curves(result)
    pages = fit_pages(len(curves), FIT_PANELS_PER_PAGE)
    out = []
    for i, idx in enumerate(pages, start=1):
        fig = fit_page(result, plan, [curves[j] for j in idx], i, len(pages))
        out.append(save_figure(fig, _page_path(path, i)))
    pattern = re.compile(rf"{re.escape(path.stem)}_(\d+){re.escape(path.suffix)}")
    for old in path.parent.glob(f"{path.stem}_*{path.suffix}"):
        m = pattern.fullmatch(old.name)
        if m and int(m.group(1)) > len(pages):
            old.unlink()
    return out
