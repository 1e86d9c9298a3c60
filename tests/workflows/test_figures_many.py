"""Figures and report of a calibration with 1 to 200 bubbles, on a fake summarised run (no sampling).

The fake :class:`AgentResult` carries what :func:`summarise_agent` fills (``summary`` rows through the same row
builder, ``bands``, ``population_predictive``) and what the figures read from the phases (phase-3 draws, phase-2
ψ draws); diameters are drawn in random order so the diameter ordering is exercised.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from bubblecal.data import DEFAULT_UNITS as U
from bubblecal.data import LoadingCurve

DRAWS = 200


def fake_result(out: Path, n: int, *, seed: int = 0, agent: str = "definity", workflow: str = "reduced"):
    """A summarised run of ``n`` compression curves (random diameters 1.5–6 um) and its top-level plan."""
    from bubblecal.inference.phase_results import PhaseResult, StagedResult
    from bubblecal.priors import load_priors
    from bubblecal.workflows.calibrate import AgentPlan, AgentResult, CalibrationConfig
    from bubblecal.workflows.summary import POPULATION_ROW, _param_rows

    rng = np.random.default_rng(seed)
    spec = load_priors(f"{agent}_{workflow}")
    box = {k: spec.parameters[k].prior.as_tuple() for k in spec.parameters}
    diam = rng.uniform(1.5, 6.0, n).round(2)
    curves, bands, rows, phase1, phase3 = [], {}, [], [], []
    for i, d in enumerate(diam):
        name = f"{agent}_b{i:03d}"
        x_nm = np.linspace(4.0, 25.0 * d, 25)
        f_nN = 0.01 * x_nm**1.3 * (1 + 0.04 * rng.standard_normal(x_nm.size))
        x, y = np.asarray(U.nm_to_dpd(x_nm)), np.asarray(U.nN_to_dpd(np.abs(f_nN)))
        curves.append(LoadingCurve(name=name, kind="compression", x=x, y=y, agent=agent, diameter_um=float(d),
                                   bubble_diameter_um=float(d)))
        grid = np.linspace(0.0, x.max() * 1.02, 80)
        gm = np.asarray(U.nN_to_dpd(0.01 * np.asarray(U.dpd_to_nm(grid)) ** 1.3))
        bands[name] = {"kind": "compression", "x": x, "y": y, "median": np.interp(x, grid, gm),
                       "lower": 0.85 * np.interp(x, grid, gm), "upper": 1.15 * np.interp(x, grid, gm), "grid": grid,
                       "grid_median": gm, "grid_lower": 0.85 * gm, "grid_upper": 1.15 * gm, "grid_model": None,
                       "map_curve": 1.02 * gm}
        samples = {}
        for k, (lo, hi) in box.items():
            centre = lo + (hi - lo) * rng.uniform(0.2, 0.8)
            samples[k] = np.clip(centre + 0.05 * (hi - lo) * rng.standard_normal(DRAWS), lo, hi)
        samples["sigma"] = np.abs(0.05 + 0.01 * rng.standard_normal(DRAWS))
        base = {"agent": agent, "workflow": workflow, "dataset": name, "kind": "compression", "diameter_um": float(d),
                "n_points": x.size, "coverage_90": float(rng.uniform(0.8, 1.0)), "crps": float(rng.uniform(0.1, 1)),
                "crps_sd": 0.01, "crps_unit": "nN"}
        rows += _param_rows(base, samples, [*spec.parameters, "sigma"], 0)
        phase1.append(PhaseResult(f"phase1_{name}", samples, -10.0 - i, 0.1, "converged", 1.0))
        phase3.append(PhaseResult(f"phase3_{name}", samples, -11.0 - i, 0.1, "converged", 1.0))
    psi = {}
    for k, (lo, hi) in box.items():
        psi[f"m_{k}"] = lo + (hi - lo) * (0.5 + 0.03 * rng.standard_normal(DRAWS))
        psi[f"tau_{k}"] = (hi - lo) * (0.1 + 0.01 * np.abs(rng.standard_normal(DRAWS)))
    pop = {k: np.clip(psi[f"m_{k}"] + psi[f"tau_{k}"] * rng.standard_normal(DRAWS), *box[k]) for k in box}
    base = {"agent": agent, "workflow": workflow, "dataset": POPULATION_ROW, "kind": "population",
            "diameter_um": math.nan, "n_points": 0, "coverage_90": math.nan, "crps": math.nan, "crps_sd": math.nan,
            "crps_unit": ""}
    rows += _param_rows(base, pop, list(box), None)
    for key, v in psi.items():
        rows += [r | {"dataset": "hyperparameters", "kind": "psi", "parameter": key}
                 for r in _param_rows(base, {key.split("_", 1)[1]: v}, [key.split("_", 1)[1]], None)]
    staged = StagedResult(phase1, PhaseResult("phase2", psi, -20.0, 0.2, "converged", 2.0), phase3)
    ess = pd.DataFrame({"dataset": [c.name for c in curves], "ess_min": 50.0, "ess_p05": 60.0, "ess_median": 90.0,
                        "ess_median_fraction": 0.45, "pareto_k": 0.3})
    out.mkdir(parents=True, exist_ok=True)
    ap = AgentPlan(agent, workflow, spec, Path(f"priors/{agent}_{workflow}.toml"), curves, [None] * n, [], None, out)
    result = AgentResult(ap, staged, None, {}, pd.DataFrame(rows), ess, pop, {"phase1": 1.0, "phase2": 2.0}, [])
    result.bands = bands
    plan = SimpleNamespace(synthetic_bundle=True, config=CalibrationConfig(), bundle_path=Path("bundle"),
                           bundle=SimpleNamespace(manifest={"notes": "fake"}))
    return result, plan


def _diameters(labels) -> list[float]:
    """The diameters of "bubble (D µm)" labels."""
    return [float(re.search(r"\(([\d.]+) µm\)$", t).group(1)) for t in labels]


@pytest.mark.parametrize("n", [1, 3, 50, 200])
def test_pages_panels_and_forest_rows_follow_the_bubbles(tmp_path, n):
    """Pages of at most 48 panels, equally full; one panel and one forest row per bubble, ordered by diameter."""
    from bubblecal.workflows.figures_fits import FIT_PANELS_PER_PAGE, fit_curves, fit_page, fit_pages
    from bubblecal.workflows.figures_population import diameter_page, forest_page

    result, plan = fake_result(tmp_path, n, seed=n)
    pages = fit_pages(n)
    assert len(pages) == math.ceil(n / FIT_PANELS_PER_PAGE) and sum(len(p) for p in pages) == n
    assert max(len(p) for p in pages) - min(len(p) for p in pages) <= 1
    curves = fit_curves(result)
    d = [c.bubble_diameter_um for c in curves]
    assert d == sorted(d) and len(curves) == n
    fig = fit_page(result, plan, [curves[j] for j in pages[-1]], len(pages), len(pages))
    titles = [ax.get_title() for ax in fig.axes]
    assert len(titles) == len(pages[-1]) and _diameters(titles) == sorted(_diameters(titles))
    assert _diameters(titles) == [curves[j].bubble_diameter_um for j in pages[-1]]

    forest = forest_page(result, plan)
    assert len(forest.axes) == 2  # E and kappa
    labels = [t.get_text() for t in forest.axes[0].get_yticklabels()]
    ticks = list(forest.axes[0].get_yticks())
    assert len(labels) == n and ticks == list(range(n))
    assert _diameters(labels) == sorted(float(x) for x in result.summary.groupby("dataset")["diameter_um"].first()
                                        if math.isfinite(x))
    lo, hi = forest.axes[0].get_ylim()
    assert lo > hi  # row 0 (the smallest bubble) on top
    diam = diameter_page(result, plan)
    assert len(diam.axes) == 2


def test_agent_figures_write_every_page_and_remove_stale_ones(tmp_path, monkeypatch):
    """Pages of 1 panel: 3 bubbles give fit.png, fit_2.png, fit_3.png, forest, diameter and the other figures;
    a rerun with pages of 2 in the same folder leaves fit.png and fit_2.png only."""
    from bubblecal.workflows import figures_fits
    from bubblecal.workflows.figures import agent_figures

    monkeypatch.setattr(figures_fits, "FIT_PANELS_PER_PAGE", 1)
    result, plan = fake_result(tmp_path / "run", 3)
    paths = agent_figures(result, plan)
    names = [p.name for p in paths]
    assert names[:3] == ["fit.png", "fit_2.png", "fit_3.png"]
    assert set(names[3:]) == {"forest.png", "diameter.png", "ka_kb.png", "population.png"}
    assert all(p.stat().st_size > 10_000 for p in paths)
    monkeypatch.setattr(figures_fits, "FIT_PANELS_PER_PAGE", 2)
    folder = tmp_path / "run" / "figures"
    assert [p.name for p in figures_fits.fit_figure(result, plan, folder / "fit.png")] == ["fit.png", "fit_2.png"]
    assert sorted(p.name for p in folder.glob("fit*.png")) == ["fit.png", "fit_2.png"]


def test_forest_size_grows_then_caps():
    """The forest plot grows with the rows up to its cap; beyond, the label font shrinks but stays legible."""
    from bubblecal.workflows.figures_population import forest_size

    h3, f3 = forest_size(3)
    h50, f50 = forest_size(50)
    h200, f200 = forest_size(200)
    assert h3 < h50 < h200 and f3 == f50 == 8.0
    assert h200 == forest_size(400)[0] and 4.5 <= f200 < f50


@pytest.mark.parametrize("n", [3, 200])
def test_report_one_line_per_bubble_and_population_in_physical_units(tmp_path, n):
    """report.md: one table line per bubble in diameter order, the population (m, τ) table, figures embedded;
    the full parameter table and per-phase rows only for a few datasets."""
    from bubblecal.workflows.report import write_report

    result, plan = fake_result(tmp_path, n, seed=1)
    result.figures = [tmp_path / "figures" / f"{name}.png" for name in ("fit", "forest", "diameter")]
    text = write_report(result, plan).read_text()
    section = text.split("## Posterior summary")[1].split("\n\n")[2].splitlines()
    assert section[0].startswith("| bubble | D [µm] | E [MPa] median [90 %] | kappa [k_BT] median [90 %]")
    body = section[2:]
    assert len(body) == n
    d = [float(line.split("|")[2]) for line in body]
    assert d == sorted(d)
    assert "| ka (E) | MPa |" in text and "| kb (kappa) | k_BT |" in text and "| d0 (d0) | nm |" in text
    assert "![forest](figures/forest.png)" in text and "![diameter](figures/diameter.png)" in text
    assert ("ka (E [MPa])" in text) == (n <= 8)  # the full table
    assert (f"| phase1 ({n} runs) |" in text) == (n > 8)
    assert len(text.splitlines()) < 2 * n + 80


@pytest.mark.parametrize("n", [3, 50])
def test_console_summary_lists_few_bubbles_and_keeps_the_population_for_many(tmp_path, n):
    from bubblecal.workflows.report import CONSOLE_ROWS, summary_table

    table = summary_table(fake_result(tmp_path, n)[0])
    names = list(table.columns[0].cells)
    assert "population (new bubble)" in names
    assert len(names) == (n + 1 if n + 1 <= CONSOLE_ROWS else 1)
    assert (f"{n} datasets in summary.csv" in table.title) == (n + 1 > CONSOLE_ROWS)


def test_agent_titles_keep_a_users_label_and_name_the_published_agents():
    from bubblecal.workflows.plotting import agent_title

    assert agent_title("lab-B") == "lab-B"  # a user's label as written, not "Lab-b"
    assert agent_title("mylipid") == "mylipid"
    assert agent_title("sonovue") == "SonoVue"
    assert agent_title("definity") == "Definity"
