"""Per-bubble posteriors against the population: ``forest.png`` and ``diameter.png``.

* ``forest.png`` — one row per bubble (sorted by diameter, labelled "bubble (D µm)"): posterior median and 90 %
  interval of E [MPa] and of κ [k_BT] (a column each, for the parameters that were sampled), over a shaded band
  for the 90 % interval of the population mean m (phase-2 draws) and a lighter band for the 5–95 % of the
  population predictive of a new bubble. The figure grows with the number of bubbles up to a cap, then the rows
  and their labels shrink.
* ``diameter.png`` — the same medians and intervals against the bubble diameter [um], the population bands drawn
  as horizontal bands (a panel for E, one for κ when sampled).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bubblecal.workflows.plotting import COLOURS, figure_title, new_figure, save_figure, styled
from bubblecal.workflows.summary import BUBBLE_PARAMETERS, bubble_rows, population_bands

__all__ = ["AXIS_LABELS", "forest_size", "forest_page", "forest_figure", "diameter_page", "diameter_figure"]

#: Axis label of each per-bubble parameter (physical units).
AXIS_LABELS = {"ka": "Young's modulus E [MPa]", "kb": "bending modulus κ [$k_BT$]"}
#: Height of one forest row while the figure is below its cap [inch].
_ROW_INCH = 0.22
#: Height of the forest plot beyond which rows shrink instead [inch].
_MAX_HEIGHT = 24.0
#: Height of the title, legend and axis label of the forest plot [inch].
_FRAME_INCH = 1.6
#: A positive axis spanning more than this ratio is drawn on a log scale.
_LOG_RATIO = 20.0


def forest_size(n: int) -> tuple[float, float]:
    """Height [inch] and label font size [pt] of a forest plot of ``n`` rows.

    Rows are :data:`_ROW_INCH` high until the figure reaches :data:`_MAX_HEIGHT`; beyond, they shrink and so does
    the label font (about 60 % of a row, between 4.5 and 8 pt).

    Parameters
    ----------
    n : int
        Number of rows (bubbles).

    Returns
    -------
    tuple of float
        (height [inch], font size [pt]).
    """
    height = min(_FRAME_INCH + _ROW_INCH * max(n, 1), _MAX_HEIGHT)
    row_pt = 72.0 * (height - _FRAME_INCH) / max(n, 1)
    return max(height, 3.0), float(np.clip(0.6 * row_pt, 4.5, 8.0))


def _curve_rows(result):
    """The loading-curve rows of :func:`~bubblecal.workflows.summary.bubble_rows` and the sampled parameters."""
    rows = bubble_rows(result)
    if rows.empty:
        return rows, []
    rows = rows[rows["kind"] != "acoustic"].reset_index(drop=True)
    params = [p for p in BUBBLE_PARAMETERS if p in result.plan.spec.parameters and f"{p}_median" in rows]
    return rows, params


def _population(ax, band: dict, horizontal: bool, first: bool) -> None:
    """Shade the population-predictive 5–95 % (light) and the 90 % interval of m (dark), with m's median."""
    span, line = (ax.axhspan, ax.axhline) if horizontal else (ax.axvspan, ax.axvline)
    if "new_q05" in band:
        span(band["new_q05"], band["new_q95"], color=COLOURS[0], alpha=0.12, lw=0,
             label="population predictive, new bubble (5–95 %)" if first else None)
    if "m_q05" in band:
        span(band["m_q05"], band["m_q95"], color=COLOURS[0], alpha=0.35, lw=0,
             label="population mean m (90 %)" if first else None)
        line(band["m_median"], color=COLOURS[0], lw=0.8)


def _scale(ax, rows, p: str, band: dict, horizontal: bool) -> None:
    """Log scale when every value is positive and they span more than :data:`_LOG_RATIO`, else few linear ticks."""
    vals = np.concatenate([rows[f"{p}_q05"], rows[f"{p}_q95"], [v for v in band.values() if np.isfinite(v)]])
    lo, hi = float(np.min(vals)), float(np.max(vals))
    if lo > 0 and hi / lo > _LOG_RATIO:
        (ax.set_yscale if horizontal else ax.set_xscale)("log")
    else:  # at most 6 ticks: six-digit κ labels of a narrow column run into each other otherwise
        from matplotlib.ticker import MaxNLocator

        (ax.yaxis if horizontal else ax.xaxis).set_major_locator(MaxNLocator(nbins=5))


def _legend(fig, ax) -> None:
    """The page's legend below the panels."""
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=7)


def forest_page(result, plan):
    """The forest plot of one agent: per bubble the median and 90 % interval of E and κ against the population.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
        A summarised run (``result.summary``; ψ draws and ``result.population_predictive`` for the bands).
    plan : bubblecal.workflows.calibrate.Plan

    Returns
    -------
    matplotlib.figure.Figure or None
        One column per sampled parameter of ``ka``, ``kb``; row i (top first) is the i-th bubble by diameter,
        its y tick label "bubble (D µm)". None without loading curves or without ``ka`` and ``kb``.
    """
    rows, params = _curve_rows(result)
    if rows.empty or not params:
        return None
    n = len(rows)
    height, fontsize = forest_size(n)
    fig, axes = new_figure(1, len(params), figsize=(3.3 * len(params) + 2.0, height), squeeze=False, sharey=True,
                           layout="constrained")
    bands = population_bands(result)
    y = np.arange(n)
    ms, lw = (4.0, 1.2) if n <= 40 else (2.5, 0.8) if n <= 100 else (1.6, 0.6)
    for j, (ax, p) in enumerate(zip(axes[0], params, strict=True)):
        band = bands.get(p, {})
        _population(ax, band, horizontal=False, first=j == 0)
        med = rows[f"{p}_median"].to_numpy()
        err = np.vstack([med - rows[f"{p}_q05"].to_numpy(), rows[f"{p}_q95"].to_numpy() - med])
        ax.errorbar(med, y, xerr=err, fmt="o", ms=ms, color="k", elinewidth=lw, capsize=0,
                    label="bubble: median, 90 % interval" if j == 0 else None)
        _scale(ax, rows, p, band, horizontal=False)
        ax.set_xlabel(AXIS_LABELS[p])
        ax.grid(axis="x", lw=0.3, alpha=0.5)
        ax.tick_params(axis="y", length=0)
        if n > 60:  # a tall plot repeats its scale on top
            ax.tick_params(axis="x", top=True, labeltop=True)
    axes[0][0].set_yticks(y, list(rows["label"]), fontsize=fontsize)
    axes[0][0].set_ylim(n - 0.5, -0.5)  # the smallest bubble on top
    _legend(fig, axes[0][0])
    fig.suptitle(figure_title(result, plan, f"{n} bubbles by diameter, and the population"), fontsize=10)
    return fig


def diameter_page(result, plan):
    """Per-bubble median and 90 % interval of E (and κ when sampled) against the bubble diameter [um].

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
        A summarised run.
    plan : bubblecal.workflows.calibrate.Plan

    Returns
    -------
    matplotlib.figure.Figure or None
        One panel per sampled parameter of ``ka``, ``kb`` with one point per bubble; None without loading
        curves or without ``ka`` and ``kb``.
    """
    rows, params = _curve_rows(result)
    if rows.empty or not params:
        return None
    n = len(rows)
    fig, axes = new_figure(1, len(params), figsize=(4.4 * len(params), 3.8), squeeze=False, layout="constrained")
    bands = population_bands(result)
    ms, lw, alpha = (4.0, 1.0, 1.0) if n <= 20 else (2.5, 0.7, 0.8) if n <= 80 else (1.8, 0.5, 0.6)
    d = rows["diameter_um"].to_numpy()
    for j, (ax, p) in enumerate(zip(axes[0], params, strict=True)):
        band = bands.get(p, {})
        _population(ax, band, horizontal=True, first=j == 0)
        med = rows[f"{p}_median"].to_numpy()
        err = np.vstack([med - rows[f"{p}_q05"].to_numpy(), rows[f"{p}_q95"].to_numpy() - med])
        ax.errorbar(d, med, yerr=err, fmt="o", ms=ms, color="k", elinewidth=lw, capsize=0, alpha=alpha,
                    label="bubble: median, 90 % interval" if j == 0 else None)
        _scale(ax, rows, p, band, horizontal=True)
        span = max(float(d.max() - d.min()), 0.5)
        ax.set_xlim(d.min() - 0.06 * span, d.max() + 0.06 * span)
        ax.set_xlabel("bubble diameter D [µm]")
        ax.set_ylabel(AXIS_LABELS[p])
    _legend(fig, axes[0][0])
    fig.suptitle(figure_title(result, plan, f"per-bubble moduli against diameter ({n} bubbles)"), fontsize=10)
    return fig


@styled
def forest_figure(result, plan, path: Path) -> Path | None:
    """Write ``forest.png`` (see :func:`forest_page`).

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
    plan : bubblecal.workflows.calibrate.Plan
    path : Path
        PNG to write.

    Returns
    -------
    Path or None
        ``path``; None when :func:`forest_page` draws nothing.
    """
    fig = forest_page(result, plan)
    return None if fig is None else save_figure(fig, path)


@styled
def diameter_figure(result, plan, path: Path) -> Path | None:
    """Write ``diameter.png`` (see :func:`diameter_page`).

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
    plan : bubblecal.workflows.calibrate.Plan
    path : Path
        PNG to write.

    Returns
    -------
    Path or None
        ``path``; None when :func:`diameter_page` draws nothing.
    """
    fig = diameter_page(result, plan)
    return None if fig is None else save_figure(fig, path)
