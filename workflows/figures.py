"""Figures of a calibration run (matplotlib, PNG): physical units, labelled axes, legends.

:func:`agent_figures` is the one entry point; it writes under ``out/<agent>/<workflow>/figures/``

* ``fit.png`` (``fit_2.png``, ... beyond 48 curves) — the grid of small fits, one panel per loading curve
  ordered by diameter (:mod:`bubblecal.workflows.figures_fits`);
* ``forest.png`` and ``diameter.png`` — per-bubble medians and 90 % intervals of E and κ against the population
  bands, by row and against the diameter (:mod:`bubblecal.workflows.figures_population`);
* ``ka_kb.png`` — phase-3 posteriors of (E, kappa) per curve and the population-predictive cloud (past
  :data:`_FEW_CLOUDS` curves, each curve's median coloured by diameter over the pooled clouds);
* ``population.png`` — posterior marginals of the hyperparameters m_k, tau_k (physical units);
* ``acoustic.png`` (acoustic workflows) — resonance frequency [MHz] against diameter [um]: data with
  error bars sigma_ac x f (posterior mean relative noise) and the f_res(D) band of the population-
  predictive k_a (median, 90 %), plus each acoustic dataset's phase-3 predictive interval.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bubblecal.data import DEFAULT_UNITS
from bubblecal.workflows.figures_fits import fit_figure
from bubblecal.workflows.figures_population import diameter_figure, forest_figure
from bubblecal.workflows.host_programs import frequency_program
from bubblecal.workflows.plotting import COLOURS, figure_title, new_figure, save_figure, styled

__all__ = ["agent_figures", "draw_figure", "draw_jobs", "figure_jobs", "FIGURES", "PHASE_FIGURES", "ka_kb_figure",
           "population_figure", "acoustic_figure", "acoustic_band"]

#: Up to this many curves ``ka_kb.png`` draws one coloured cloud (and legend entry) per curve.
_FEW_CLOUDS = 6


def _tick_label(v: float, _pos=None) -> str:
    """Plain numbers between 0.01 and 10^4, otherwise m x 10^e in mathtext."""
    if v <= 0 or 1e-2 <= v < 1e4:
        return f"{v:g}"
    e = int(np.floor(np.log10(v) + 1e-9))
    m = v / 10**e
    return f"$10^{{{e}}}$" if abs(m - 1) < 1e-6 else f"${m:g}\\times10^{{{e}}}$"


@styled
def ka_kb_figure(result, plan, path: Path) -> Path | None:
    """``ka_kb.png``: per-curve posteriors of (E [MPa], κ [k_BT]) and the population-predictive cloud.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
    plan : bubblecal.workflows.calibrate.Plan
    path : Path
        PNG to write.

    Returns
    -------
    Path or None
        ``path``; None when k_a or k_b is not sampled.
    """
    from bubblecal.workflows.summary import dataset_posteriors

    spec = result.plan.spec
    if "ka" not in spec.parameters or "kb" not in spec.parameters:
        return None
    fig, ax = new_figure(figsize=(4.6, 3.8))
    E = lambda v: np.asarray(DEFAULT_UNITS.ka_to_young(v)) * 1e-6  # noqa: E731
    K = lambda v: np.asarray(DEFAULT_UNITS.kb_to_bending_kBT(v))  # noqa: E731
    pop = result.population_predictive
    rng = np.random.default_rng(0)
    if pop is not None and "ka" in pop and "kb" in pop:
        idx = rng.choice(pop["ka"].size, min(2000, pop["ka"].size), replace=False)
        ax.scatter(E(pop["ka"][idx]), K(pop["kb"][idx]), s=2, c="0.65", alpha=0.4, lw=0, label="population predictive")
    post = [d for d in dataset_posteriors(result).values() if d["kind"] != "acoustic"]
    if len(post) <= _FEW_CLOUDS:
        for i, d in enumerate(post):
            s = d["samples"]
            idx = rng.choice(s["ka"].size, min(1500, s["ka"].size), replace=False)
            diam = d["obj"].bubble_diameter_um or d["obj"].diameter_um
            ax.scatter(E(s["ka"][idx]), K(s["kb"][idx]), s=3, alpha=0.35, lw=0, c=COLOURS[i % len(COLOURS)],
                       label=f"D = {diam:g} µm (phase 3)" if result.staged is not None else f"D = {diam:g} µm")
            ax.plot(np.median(E(s["ka"])), np.median(K(s["kb"])), "x", c=COLOURS[i % len(COLOURS)], ms=7, mew=1.8)
    else:  # one legend entry per curve is unreadable: medians coloured by diameter, 90 % intervals as thin crosses
        q = np.array([[np.quantile(E(d["samples"]["ka"]), [0.05, 0.5, 0.95]),
                       np.quantile(K(d["samples"]["kb"]), [0.05, 0.5, 0.95])] for d in post])
        diam = np.array([float(d["obj"].bubble_diameter_um or d["obj"].diameter_um) for d in post])
        ax.hlines(q[:, 1, 1], q[:, 0, 0], q[:, 0, 2], color="0.45", lw=0.4, alpha=0.6)
        ax.vlines(q[:, 0, 1], q[:, 1, 0], q[:, 1, 2], color="0.45", lw=0.4, alpha=0.6)
        sc = ax.scatter(q[:, 0, 1], q[:, 1, 1], c=diam, s=10, cmap="viridis", zorder=3,
                        label=f"{len(post)} bubbles: median, 90 % intervals")
        fig.colorbar(sc, ax=ax, label="bubble diameter D [µm]")
    lo_e, hi_e = E(np.array(spec.parameters["ka"].prior.as_tuple()))
    lo_k, hi_k = K(np.array(spec.parameters["kb"].prior.as_tuple()))
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    # 1-2-5 ticks labelled in plain numbers: a prior box of 1-2 decades otherwise gets a single label
    for axis, ratio in ((ax.xaxis, hi_e / lo_e), (ax.yaxis, hi_k / lo_k)):
        if ratio > 30:
            (ax.set_xscale if axis is ax.xaxis else ax.set_yscale)("log")
            if ratio < 1e3:
                axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
                axis.set_major_formatter(FuncFormatter(_tick_label))
            axis.set_minor_formatter(NullFormatter())
    ax.set_xlim(lo_e, hi_e)
    ax.set_ylim(lo_k, hi_k)
    ax.set_xlabel("Young's modulus E [MPa]  (from $k_a$, ν = 1/2)")
    ax.set_ylabel("bending modulus κ [$k_BT$]  (from $k_b$)")
    leg = ax.legend(fontsize=7, markerscale=3, loc="best")
    for h in leg.legend_handles:
        h.set_alpha(1)
    ax.set_title(figure_title(result, plan, "$k_a$–$k_b$ posteriors"), fontsize=9)
    return save_figure(fig, path)


@styled
def population_figure(result, plan, path: Path) -> Path | None:
    """``population.png``: posterior marginals of the hyperparameters m_k, τ_k over their hyperpriors.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
    plan : bubblecal.workflows.calibrate.Plan
    path : Path
        PNG to write.

    Returns
    -------
    Path or None
        ``path``; None when nothing is pooled.
    """
    from bubblecal.workflows.summary import PHYSICAL, psi_samples

    m, tau = psi_samples(result)
    if not m:
        return None
    names = list(m)
    fig, axes = new_figure(2, len(names), figsize=(2.9 * len(names), 4.6), squeeze=False)
    spec = result.plan.spec
    for j, k in enumerate(names):
        _u, pname, punit, conv = PHYSICAL[k]
        p = spec.parameters[k]
        label = {"ka": "E", "kb": "κ", "d0": "$d_0$"}.get(k, pname)
        unit = f" [{punit.replace('k_BT', '$k_BT$')}]" if punit != "1" else ""
        for row, (sym, values, box) in enumerate((("m", m[k], p.hyper_m), ("τ", tau[k], p.hyper_tau))):
            ax = axes[row][j]
            if sym == "m":
                v = conv(values)
                lo, hi = conv(np.array(box.as_tuple()))
            else:  # a spread converts with the same linear factor (all conversions are proportional)
                f = float(conv(1.0))
                v = np.asarray(values) * f
                lo, hi = np.array(box.as_tuple()) * f
            ax.hist(v, bins=40, range=(lo, hi), density=True, color=COLOURS[j % len(COLOURS)], alpha=0.75)
            ax.axhline(1.0 / (hi - lo), color="k", lw=0.8, ls=":", label="hyperprior")
            ax.set_xlim(lo, hi)
            ax.set_xlabel(f"{sym}$_{{{k}}}$: {label} {'mean' if sym == 'm' else 'spread'}{unit}")
            ax.set_ylabel("posterior density" if j == 0 else "")
            ax.set_yticks([])
    axes[0][0].legend(fontsize=7)
    fig.suptitle(figure_title(result, plan, "population hyperparameters ψ"), fontsize=10)
    return save_figure(fig, path)


def acoustic_band(result) -> dict | None:
    """The f_res(D) band of ``acoustic.png``: frequencies of the population-predictive k_a on the surrogate's
    diameters near the data (evaluated by a compiled program: call it where JAX runs).

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
        A summarised run.

    Returns
    -------
    dict or None
        'diameter_um' (the surrogate's diameters within 0.6 um of the data), 'lo_d' and 'hi_d' (the axis range
        [um]) and, with population-predictive k_a draws, 'q' ((3, diameters): 5, 50, 95 % quantiles [MHz]);
        None without acoustic data or surrogate.
    """
    ap = result.plan
    if not ap.acoustic or ap.f_res is None:
        return None
    diam_grid = np.array([d for d in ap.f_res.diameters])
    obs_d = np.concatenate([np.atleast_1d(ds.diameter_um) for ds in ap.acoustic])
    lo_d, hi_d = obs_d.min() - 0.6, obs_d.max() + 0.6
    diam_grid = diam_grid[(diam_grid >= lo_d) & (diam_grid <= hi_d)]
    band = {"diameter_um": diam_grid, "lo_d": lo_d, "hi_d": hi_d}
    pop = result.population_predictive
    if pop is not None and "ka" in pop and diam_grid.size:
        ka = pop["ka"][:2000]
        f = frequency_program(ap.f_res)(ka[:, None], diam_grid[None, :])
        band["q"] = np.quantile(f, [0.05, 0.5, 0.95], axis=0)
    return band


@styled
def acoustic_figure(result, plan, path: Path, band: dict | None = None) -> Path | None:
    """``acoustic.png``: measured resonance frequencies [MHz] against diameter [um] with the f_res(D) band
    of the population-predictive k_a and each dataset's predictive interval.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
    plan : bubblecal.workflows.calibrate.Plan
    path : Path
        PNG to write.
    band : dict or None
        :func:`acoustic_band` of the run (None: computed here).

    Returns
    -------
    Path or None
        ``path``; None without acoustic data.
    """
    ap = result.plan
    band = acoustic_band(result) if band is None else band
    if band is None:
        return None
    fig, ax = new_figure(figsize=(4.6, 3.5))
    diam_grid, lo_d, hi_d = band["diameter_um"], band["lo_d"], band["hi_d"]
    if "q" in band:
        q = band["q"]
        ax.fill_between(diam_grid, q[0], q[2], color=COLOURS[0], alpha=0.2, lw=0,
                        label="$f_{res}(D)$, population-predictive $k_a$ (90 %)")
        ax.plot(diam_grid, q[1], color=COLOURS[0], lw=1.4, label="median")
    for j, ds in enumerate(ap.acoustic):
        b = result.bands.get(ds.name)
        d = np.atleast_1d(ds.diameter_um)
        f = np.atleast_1d(ds.frequency_MHz)
        err = b["sigma_mean"] * f if b is not None else None
        ax.errorbar(d, f, yerr=err, fmt="o", ms=4, mfc="white", mec="k", ecolor="k", elinewidth=0.8, capsize=2,
                    label="measured ± $\\bar\\sigma_{ac} f$" if j == 0 else None)
        if b is not None:
            ax.vlines(d + 0.12, b["lower"], b["upper"], color=COLOURS[1], lw=2.5, alpha=0.7,
                      label="dataset posterior predictive (90 %)" if j == 0 else None)
    ax.set_xlabel("bubble diameter D [µm]")
    ax.set_ylabel("resonance frequency [MHz]")
    ax.set_xlim(lo_d, hi_d)
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7)
    ax.set_title(figure_title(result, plan, "acoustic resonance"), fontsize=9)
    return save_figure(fig, path)


#: Every figure of an agent in drawing order: (function, file name); ``fit_figure`` returns a list of pages.
FIGURES = (("fit_figure", "fit.png"), ("forest_figure", "forest.png"), ("diameter_figure", "diameter.png"),
           ("ka_kb_figure", "ka_kb.png"), ("population_figure", "population.png"), ("acoustic_figure", "acoustic.png"))


def draw_figure(name: str, result, plan, path: Path, **kwargs) -> list[Path]:
    """Draw one figure of :data:`FIGURES` (module level: a figure process unpickles it).

    Parameters
    ----------
    name : str
        A function name of :data:`FIGURES`.
    result : bubblecal.workflows.calibrate.AgentResult
        A summarised run.
    plan : bubblecal.workflows.calibrate.Plan
    path : Path
        PNG to write (the first page for ``fit_figure``).
    **kwargs
        Passed to the figure (``band`` of ``acoustic_figure``).

    Returns
    -------
    list of Path
        The written files (empty when the figure does not apply to the run).
    """
    draw = {"fit_figure": fit_figure, "forest_figure": forest_figure, "diameter_figure": diameter_figure,
            "ka_kb_figure": ka_kb_figure, "population_figure": population_figure,
            "acoustic_figure": acoustic_figure}[name]
    out = draw(result, plan, path, **kwargs)
    return [p for p in (out if isinstance(out, list) else [out]) if p is not None]


#: Figures that read the phases alone, not the summaries (figure processes start them before the summaries run).
PHASE_FIGURES = ("population_figure",)


def figure_jobs(result, names=None) -> list[tuple[str, Path, dict]]:
    """The figures of one agent to draw, as (name of :data:`FIGURES`, PNG path, keyword arguments of
    :func:`draw_figure`), in drawing order; creates ``out/<agent>/<workflow>/figures/``.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
        A summarised run (or only sampled, for :data:`PHASE_FIGURES`).
    names : collection of str or None
        Only these figures (None: all).

    Returns
    -------
    list of tuple
    """
    folder = result.plan.out_dir / "figures"
    folder.mkdir(parents=True, exist_ok=True)
    # the one figure that evaluates a compiled program does so here: the figure processes run no JAX
    return [(name, folder / file, {"band": acoustic_band(result)} if name == "acoustic_figure" else {})
            for name, file in FIGURES if names is None or name in names]


def agent_figures(result, plan, *, processes=None) -> list[Path]:
    """Draw every figure of one agent under ``out/<agent>/<workflow>/figures/``.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
        A summarised run.
    plan : bubblecal.workflows.calibrate.Plan
    processes : bubblecal.workflows.calibrate.FigureProcesses or None
        Draw the figures in these processes, at once (None: one after the other in this one).

    Returns
    -------
    list of Path
        The written PNG files: the fit pages, ``forest.png``, ``diameter.png``, ``ka_kb.png``,
        ``population.png``, ``acoustic.png`` (those that apply to the run).
    """
    jobs = figure_jobs(result)
    if processes is not None:
        return processes.draw(result, plan, jobs)
    return draw_jobs(result, plan, jobs)


def draw_jobs(result, plan, jobs) -> list[Path]:
    """Draw :func:`figure_jobs` one after the other in this process.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
        A summarised run.
    plan : bubblecal.workflows.calibrate.Plan
    jobs : sequence of (str, Path, dict)
        As :func:`figure_jobs` returns them.

    Returns
    -------
    list of Path
        The written files in the order of ``jobs``.
    """
    return [p for name, path, kwargs in jobs for p in draw_figure(name, result, plan, path, **kwargs)]
