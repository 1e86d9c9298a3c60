"""Confirm a calibration at its MAP with the DPD simulator: simulation vs surrogate vs data.

For every loading curve of a finished staged run (``RESULTS/<agent>/<workflow>/``, or the whole
``RESULTS`` root), take the phase-3 MAP draw (largest stored log likelihood; every staged prior is
uniform), re-simulate it with ``bubblecal.sim.tiers.get_tier(tier).run(CurveRequest(...))`` on the
curve's loading grid, and compare:

* compression: the grid is the data's x̃ = x − d0 (> 0; the tier imposes total displacements) and the
  simulated force is compared to the surrogate S(Θ; x̃) and to the data F(x);
* indentation: the grid is the applied force x; simulated depth + d0 vs the surrogate and the data.

Outputs under ``RESULTS/<agent>/<workflow>/confirm/``: ``confirm_<tier>.csv`` (pointwise, DPD and
physical units), ``confirm_<tier>_summary.csv`` (relative L2 of simulation vs surrogate and vs data per
curve, tier status, seconds) and ``confirm_<tier>.png`` (overlay, nN vs nm). Relative L2 =
||a − b||_2 / ||b||_2 over the curve's points.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from bubblecal.data import DEFAULT_UNITS
from bubblecal.workflows.plotting import agent_title, new_figure, save_figure, styled

__all__ = ["DEFAULT_TIER", "find_runs", "map_parameters", "confirm_run"]

#: DPD tier that re-simulates the MAP unless another is named.
DEFAULT_TIER = "explicit"


def find_runs(results: Path) -> list[Path]:
    """Calibration run folders (holding ``manifest.json``) at or under ``results``.

    Parameters
    ----------
    results : Path
        A run folder OUT/<agent>/<workflow>, an agent folder OUT/<agent> or an output root OUT.

    Returns
    -------
    list of Path
        ``results`` itself when it is a run, else every run below it (sorted); empty when there is none.
    """
    results = Path(results)
    if (results / "manifest.json").is_file():
        return [results]
    return sorted(p.parent for p in results.glob("*/*/manifest.json")) or sorted(
        p.parent for p in results.glob("*/manifest.json"))


def map_parameters(run_dir: Path, curve_name: str) -> dict[str, float] | None:
    """The phase-3 MAP draw of one curve: the draw with the largest stored log likelihood.

    Parameters
    ----------
    run_dir : Path
        A run folder.
    curve_name : str
        E.g. 'definity_compression_2.1um'.

    Returns
    -------
    dict of str to float or None
        Site -> value (DPD units); None when the phase-3 file or its log likelihoods are absent.
    """
    from bubblecal.inference.predictive import map_index
    from bubblecal.workflows.calibrate import read_phase

    for suffix in (".nc", ".npz"):
        path = Path(run_dir) / f"phase3_{curve_name}{suffix}"
        if path.is_file():
            result, loglik = read_phase(path)
            if loglik is None:
                return None
            i = map_index(loglik)
            return {k: float(np.asarray(v)[i]) for k, v in result.samples.items() if np.ndim(v) == 1}
    return None


def _rel_l2(a, b) -> float:
    """||a − b||_2 / ||b||_2 over the points where both are finite (NaN when none is)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    ok = np.isfinite(a) & np.isfinite(b)
    return float(np.linalg.norm(a[ok] - b[ok]) / np.linalg.norm(b[ok])) if ok.any() else math.nan


def confirm_run(run_dir: Path, *, tier: str = DEFAULT_TIER, device: str = "cpu", subdivisions: int | None = None,
                bundle=None, tier_settings: dict | None = None,
                progress: Callable[[str], None] | None = None):
    """Re-simulate the phase-3 MAP of every curve of one run folder and compare it with surrogate and data.

    Parameters
    ----------
    run_dir : Path
        A run folder (``manifest.json`` names its agent, priors and bundle).
    tier : str
        DPD tier: 'explicit', 'implicit' or 'quasistatic'.
    device : str
        Warp device, e.g. 'cpu' or 'cuda'.
    subdivisions : int or None
        Icosphere level (None: the tier's).
    bundle : bubblecal.surrogates.Bundle or None
        A loaded bundle whose surrogates replace the run's, of the kind and network role the run's manifest
        records (None: the run's own, as its manifest describes them).
    tier_settings : dict or None
        Keyword arguments of :func:`bubblecal.sim.tiers.get_tier` (e.g. ``scale``).
    progress : callable or None
        Receives one-line messages.

    Returns
    -------
    tuple
        (pointwise DataFrame, summary DataFrame, figure path or None); the CSVs and the PNG are written
        under ``run_dir/confirm/``.

    Raises
    ------
    bubblecal.workflows.calibrate.CalibrationError
        If the run's manifest or an input it names cannot be loaded (:func:`~bubblecal.workflows.calibrate.run_plan`).
    """
    import json

    import pandas as pd

    from bubblecal.data import SHELL_PARAMETERS
    from bubblecal.sim.tiers import CurveRequest, get_tier
    from bubblecal.workflows.calibrate import run_config, run_plan

    run_dir = Path(run_dir)
    say = progress or (lambda _m: None)
    ap = run_plan(run_dir)  # the run's own curves and surrogates: published or the user's bubbles
    agent, spec = ap.agent, ap.spec
    surrogates = ap.surrogates
    if bundle is not None:  # another bundle answers with the kind the run used
        lookup = run_config(run_dir)[0].surrogate_lookup()
        surrogates = [bundle.get(c.kind, c.diameter_um, **lookup) for c in ap.curves]
    settings = dict(tier_settings or {})
    if subdivisions is not None:
        settings["subdivisions"] = subdivisions
    sim = get_tier(tier, **settings)
    points, summary = [], []
    for curve, sur in zip(ap.curves, surrogates, strict=True):
        theta = map_parameters(run_dir, curve.name)
        if theta is None:
            say(f"{curve.name}: no phase-3 result with log likelihoods in {run_dir}; skipped")
            continue
        values = {k: theta.get(k, spec.fixed.get(k, 0.0)) for k in (*SHELL_PARAMETERS, "d0")}
        x, y = np.asarray(curve.x, float), np.asarray(curve.y, float)
        d0 = values["d0"]
        params = np.array([values[k] for k in SHELL_PARAMETERS])
        if curve.kind == "compression":
            keep = x - d0 > 1e-6
            grid = x[keep] - d0
            surrogate = np.maximum(0.0, np.asarray(sur(params, grid)))
        else:
            keep = np.ones_like(x, dtype=bool)
            grid = x
            surrogate = np.maximum(0.0, np.asarray(sur(params, grid)) + d0)
        diameter = float(curve.bubble_diameter_um or curve.diameter_um)
        request = CurveRequest(protocol=curve.kind, diameter_um=diameter, grid=tuple(grid),
                               params={k: np.array([values[k]]) for k in SHELL_PARAMETERS}, seeds=(0,),
                               subdivisions=subdivisions)
        say(f"{curve.name}: {tier} tier at the MAP (ka = {values['ka']:.4g}, kb = {values['kb']:.4g}, d0 = {d0:.3g})")
        batch = sim.run(request, device=device)
        obs = np.asarray(batch.observable[0], float)
        simulated = obs if curve.kind == "compression" else obs + d0
        data = y[keep]
        conv = DEFAULT_UNITS.dpd_to_nN if curve.kind == "compression" else DEFAULT_UNITS.dpd_to_nm
        for j in range(grid.size):
            points.append({"agent": agent, "curve": curve.name, "kind": curve.kind, "x_data_dpd": float(x[keep][j]),
                           "grid_dpd": float(grid[j]), "data_dpd": float(data[j]), "surrogate_dpd": float(surrogate[j]),
                           "simulation_dpd": float(simulated[j]), "data_phys": float(conv(data[j])),
                           "surrogate_phys": float(conv(surrogate[j])), "simulation_phys": float(conv(simulated[j])),
                           "unit_phys": "nN" if curve.kind == "compression" else "nm"})
        summary.append({"agent": agent, "curve": curve.name, "tier": tier, "status": batch.status[0],
                        "rel_l2_sim_vs_surrogate": _rel_l2(simulated, surrogate),
                        "rel_l2_sim_vs_data": _rel_l2(simulated, data),
                        "rel_l2_surrogate_vs_data": _rel_l2(surrogate, data), "seconds": batch.seconds,
                        **{f"map_{k}": v for k, v in values.items()}, "info": json.dumps(
                            {k: v for k, v in batch.info.items() if k in ("mesh_subdivisions", "n_vertices", "tier")})})
    folder = run_dir / "confirm"
    folder.mkdir(parents=True, exist_ok=True)
    pts = pd.DataFrame(points)
    summ = pd.DataFrame(summary)
    pts.to_csv(folder / f"confirm_{tier}.csv", index=False)
    summ.to_csv(folder / f"confirm_{tier}_summary.csv", index=False)
    fig = _figure(pts, summ, folder / f"confirm_{tier}.png", tier, agent) if len(pts) else None
    return pts, summ, fig


@styled
def _figure(pts, summ, path: Path, tier: str, agent: str) -> Path:
    """Overlay of simulation, surrogate and data per curve (force [nN] against displacement [nm])."""
    curves = list(dict.fromkeys(pts["curve"]))
    fig, axes = new_figure(1, len(curves), figsize=(max(3.6 * len(curves), 5.0), 3.4), squeeze=False)
    for ax, name in zip(axes[0], curves, strict=True):
        p = pts[pts["curve"] == name]
        kind = p["kind"].iloc[0]
        if kind == "compression":
            xd = DEFAULT_UNITS.dpd_to_nm(p["x_data_dpd"].to_numpy())
            ax.plot(xd, p["surrogate_phys"], "-", color="#1b6ca8", lw=1.5, label="surrogate at MAP")
            ax.plot(xd, p["simulation_phys"], "s--", color="#d1495b", ms=3, lw=1, label=f"{tier} simulation at MAP")
            ax.plot(xd, p["data_phys"], "o", ms=3.5, mfc="white", mec="k", label="AFM data")
            ax.set_xlabel("displacement [nm]")
        else:
            f = DEFAULT_UNITS.dpd_to_nN(p["x_data_dpd"].to_numpy())
            ax.plot(p["surrogate_phys"], f, "-", color="#1b6ca8", lw=1.5, label="surrogate at MAP")
            ax.plot(p["simulation_phys"], f, "s--", color="#d1495b", ms=3, lw=1, label=f"{tier} simulation at MAP")
            ax.plot(p["data_phys"], f, "o", ms=3.5, mfc="white", mec="k", label="AFM data")
            ax.set_xlabel("indentation depth [nm]")
        ax.set_ylabel("force [nN]")
        s = summ[summ["curve"] == name].iloc[0]
        ax.set_title(f"{name}\nrel. L2 sim–surrogate {s['rel_l2_sim_vs_surrogate']:.2f}, sim–data "
                     f"{s['rel_l2_sim_vs_data']:.2f}", fontsize=8)
        ax.set_xlim(left=0)
        ax.set_ylim(bottom=0)
    axes[0][0].legend(fontsize=7)
    fig.suptitle(f"{agent_title(agent)}: {tier} simulation at the phase-3 MAP", fontsize=10)
    return save_figure(fig, path)
