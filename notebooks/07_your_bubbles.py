# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#       jupytext_version: 1.19.6
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Your own bubbles: from a hand-written curves file to the report
#
# A new agent ("mylipid"), three bubbles compressed between AFM plates at diameters the published study never
# measured, and one resonance frequency per bubble. The path of a user:
#
# 1. write a tidy curves file (one row per measured point, in nm and nN) and a resonance file (one row per
#    bubble, in MHz);
# 2. check them (`bubblecal.data.read_bubble_curves`, `read_resonance`; shell: `bubblecal data check`): a
#    broken file is named row by row;
# 3. write an editable priors file for the agent (`bubblecal priors template`);
# 4. calibrate (`make_plan`, `run_calibration`; shell: `bubblecal calibrate --data`): one hierarchy per agent
#    label;
# 5. read `summary.csv`, the figures and `report.md`.
#
# The formats: [docs/data-formats.md](../docs/data-formats.md), "Tidy bubble files" and "Calibrating them".

# %%
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from IPython.display import Image, display

from bubblecal.data import DEFAULT_UNITS as units
from bubblecal.data import DataError, read_bubble_curves, read_resonance
from bubblecal.models.likelihood import predict_mechanical
from bubblecal.priors import load_priors, priors_template
from bubblecal.surrogates import default_bundle_path, load_bundle
from bubblecal.workflows.calibrate import CalibrationConfig, make_plan, run_calibration
from bubblecal.workflows.summary import POPULATION_ROW

SMALL = os.environ.get("BUBBLECAL_NOTEBOOK_SMALL") == "1"
POPULATION = 200 if SMALL else None  # None: the default population of `bubblecal calibrate`
MCMC_STEPS = 2 if SMALL else 10       # 10: the default of CalibrationConfig.num_mcmc_steps
# the small run also thins the summaries' predictive draws (default 5000)
SMALL_SUMMARIES = {"predictive_samples": 500, "phase2_samples": 200} if SMALL else {}
work = Path("my_bubbles")
work.mkdir(exist_ok=True)

# %% [markdown]
# ## 1. A curves file, written by hand
#
# **A real user writes measured values here**: per bubble its id, the agent label, the protocol, the diameter
# [µm] and the (displacement [nm], force [nN]) points of its loading curve. Having none, this notebook makes
# plausible curves: the shipped bundle's fast compression network over the diameter at known shell parameters
# (k_a, k_b, contact offset d0), converted from DPD to nm / nN by `bubblecal.data.DEFAULT_UNITS`, with 5 %
# relative noise. The known k_a are compared with the calibrated ones at the end.
#
# The displacements stay inside the network's loading box (`loading_range_per_size`: displacement over bubble
# diameter, both in DPD length) shifted by d0; the calibration refuses retained points beyond it, naming them.

# %%
bundle = load_bundle(default_bundle_path(must_exist=True))
known = pd.DataFrame({"bubble": ["ml-01", "ml-02", "ml-03"], "diameter_um": [2.4, 3.3, 4.6],
                      "ka": [13_500.0, 15_500.0, 17_000.0], "kb": [450.0, 550.0, 500.0], "d0": [0.15, 0.2, 0.25]})
known["E_MPa"] = units.ka_to_young(known["ka"]) * 1e-6
rng = np.random.default_rng(7)
rows = []
for b in known.itertuples():
    net = bundle.get("compression", b.diameter_um, prefer="over-diameter", network="fast")
    lo, hi = net.loading_range_per_size  # displacement / diameter [DPD length / DPD length]
    x = b.d0 + np.linspace(0.05, 0.9, 15) * hi * 2 * net.radius_dpd  # DPD length
    params = np.array([b.ka, b.kb, 0.0, 0.0, 0.0, 0.0])  # reduced shell: b1 = b2 = a3 = a4 = 0
    y = np.asarray(predict_mechanical(net, "compression", params, b.d0, x))  # DPD force
    y_obs = y * (1 + 0.05 * rng.standard_normal(y.shape))
    rows += [{"bubble": b.bubble, "agent": "mylipid", "protocol": "compression", "diameter_um": b.diameter_um,
              "displacement_nm": round(float(units.dpd_to_nm(xi)), 2), "force_nN": round(float(units.dpd_to_nN(yi)), 4),
              "retained": 1} for xi, yi in zip(x, y_obs, strict=True)]
curves = pd.DataFrame(rows)
curves_csv = work / "curves.csv"
curves.to_csv(curves_csv, index=False)
print(known.to_string(index=False, float_format="%.4g"))
print(curves_csv.read_text().splitlines()[:5])

# %% [markdown]
# A resonance file: one row per bubble (`agent`, `diameter_um`, `frequency_MHz`, optional `source`). Here from
# the acoustic law of the bundle's published compression agent at each bubble's k_a, with 5 % relative noise;
# each row becomes one acoustic dataset of the hierarchy (its own k_a, drawn from the same population).

# %%
law = bundle.acoustic_for("definity", known["diameter_um"].to_numpy())
f_res = np.array([float(law.f_res(np.array([b.ka]), b.diameter_um)[0]) for b in known.itertuples()])
resonance = pd.DataFrame({"agent": "mylipid", "diameter_um": known["diameter_um"],
                          "frequency_MHz": np.round(f_res * (1 + 0.05 * rng.standard_normal(len(f_res))), 3),
                          "source": "generated in notebook 07"})
resonance_csv = work / "resonance.csv"
resonance.to_csv(resonance_csv, index=False)
print(resonance.to_string(index=False))

# %% [markdown]
# ## 2. Checking the files
#
# A broken copy first: forces written in newtons for `ml-01`, and only two retained points for `ml-02`
# (`retained` = 0 removes a point from the likelihood; a bubble needs at least 3). The reader lists every problem
# of the file at once, each with its row, line, column, value and the allowed range, and reads nothing.

# %%
broken = curves.copy()
broken.loc[broken["bubble"] == "ml-01", "force_nN"] *= 1e-9
broken.loc[(broken["bubble"] == "ml-02") & (broken.groupby("bubble").cumcount() >= 2), "retained"] = 0
broken_csv = work / "curves_broken.csv"
broken.to_csv(broken_csv, index=False)
try:
    read_bubble_curves(broken_csv)
except DataError as exc:
    print(exc)
    assert "newtons" in str(exc) and "only 2 retained points" in str(exc), "the reader named other problems"
else:
    raise AssertionError(f"{broken_csv} was accepted")

# %% [markdown]
# The same check from the shell, `bubblecal data check FILE` (exit code 1 and every problem, or ok with counts):

# %%
cli = shutil.which("bubblecal") or str(Path(sys.executable).with_name("bubblecal"))  # the console script
check = subprocess.run([cli, "data", "check", str(broken_csv)], capture_output=True, text=True)
print("exit code", check.returncode)
print(check.stdout[-1500:], check.stderr[-1500:])
assert check.returncode == 1, "bubblecal data check accepted the broken file"

# %% [markdown]
# The fixed files pass: the bubbles per agent, their diameters and their points.

# %%
good = read_bubble_curves(curves_csv)
freqs = read_resonance(resonance_csv)
for b in good:
    print(f"{b.bubble}: {b.agent}, {b.protocol}, {b.diameter_um:g} µm, {len(b.x)} points, "
          f"{int(np.sum(b.retained))} retained")
print(f"{len(freqs.agent)} resonance rows")

# %% [markdown]
# ## 3. Priors for your agent
#
# Without priors of its own an agent gets the shipped priors of its protocol's published agent (compression:
# Definity), and the plan says so. `priors_template` (shell: `bubblecal priors template --agent mylipid
# --protocol compression --workflow reduced-acoustic --out mylipid.toml`) writes an editable copy: its header says
# what each range means and its units. Edit the ranges to what you know of your shell (e.g. a wider k_a
# hyperprior), keep `[workflow] agent` (the published agent whose surrogates and acoustic law serve yours), and
# check the edit with `bubblecal priors check mylipid.toml`.

# %%
priors_toml = work / "mylipid.toml"
priors_toml.write_text(priors_template("mylipid", "compression", workflow="reduced-acoustic"), encoding="utf-8")
spec = load_priors(priors_toml)
print(priors_toml.read_text().splitlines()[0])
for name, p in spec.parameters.items():
    print(f"{name:3s} prior [{p.prior.lo:g}, {p.prior.hi:g}]   population mean m in [{p.hyper_m.lo:g}, "
          f"{p.hyper_m.hi:g}], spread tau in [{p.hyper_tau.lo:g}, {p.hyper_tau.hi:g}]")

# %% [markdown]
# ## 4. Calibrating
#
# `make_plan` validates everything before any sampling (files, priors, each diameter against the bundle's range,
# each retained point against the network's loading box) and raises one `CalibrationError` listing every problem.
# One hierarchy per agent label: `out/mylipid/reduced-acoustic/`. Each bubble runs on the bundle's fast network
# over the diameter bound to its diameter. This notebook uses a small population when the test suite runs it;
# the command line's defaults otherwise.

# %%
config = CalibrationConfig(data=curves_csv, acoustic_data=resonance_csv, priors={"mylipid": str(priors_toml)},
                           population=POPULATION, num_mcmc_steps=MCMC_STEPS, out=work / "calibration",
                           **SMALL_SUMMARIES)
plan = make_plan(config)
for ap in plan.agents:
    print(f"{ap.agent}: workflow {ap.workflow}, {len(ap.curves)} curves, {len(ap.acoustic)} acoustic datasets, "
          f"out {ap.out_dir}")
    for note in ap.notes:
        print("  note:", note)
    for warning in ap.domain_warnings:
        print("  domain:", warning)

# %%
results = run_calibration(plan)
result = results[0]
print({phase: round(s, 1) for phase, s in result.seconds.items()})

# %% [markdown]
# ## 5. Reading the outputs
#
# `summary.csv`: one row per (dataset, parameter) with the posterior mean, 5 % / 95 % quantiles and the MAP in DPD
# units and in physical units (E [MPa] from k_a, κ [k_BT] from k_b, d0 [nm]); the dataset
# `population (new bubble)` holds the population-predictive draws, i.e. a new bubble of this agent.

# %%
out_dir = plan.agents[0].out_dir
summary = pd.read_csv(out_dir / "summary.csv")
print(list(summary.columns))
show = ["dataset", "kind", "diameter_um", "physical", "physical_unit", "median_phys", "q05_phys", "q95_phys",
        "coverage_90"]
print(summary.loc[summary["parameter"].isin(["ka", "kb"]), show].to_string(index=False, float_format="%.4g"))

# %% [markdown]
# Calibrated against known: each bubble's k_a (and E) next to the value its curve was generated at, and whether the
# 90 % interval holds it (a 90 % interval may miss now and then; the small run's intervals are rougher). A measured
# agent has no known column: its checks are the fits and the coverage of the predictive bands.

# %%
ka_rows = summary[summary["parameter"] == "ka"].set_index("dataset")
compare = known.set_index("bubble")[["diameter_um", "ka"]].rename(columns={"ka": "ka known"})
for col in ("median", "q05", "q95"):
    compare[f"ka {col}"] = ka_rows.loc[compare.index, col]
compare["inside 90 %"] = (compare["ka q05"] <= compare["ka known"]) & (compare["ka known"] <= compare["ka q95"])
compare["E known [MPa]"] = known.set_index("bubble")["E_MPa"]
compare["E median [MPa]"] = ka_rows.loc[compare.index, "median_phys"]
print(compare.to_string(float_format="%.4g"))
pop = ka_rows.loc[POPULATION_ROW]
print(f"population (a new bubble of mylipid): ka median {pop['median']:.4g} [{pop['q05']:.4g}, {pop['q95']:.4g}] DPD, "
      f"E {pop['median_phys']:.3g} MPa; the known ka average {known['ka'].mean():.4g}")

# %% [markdown]
# The figures, under `figures/`: the fit of every bubble with its 90 % predictive band (`fit.png`), the forest plot
# of E and κ per bubble against the population mean and a new bubble of the population (`forest.png`), and E and κ
# against the diameter (`diameter.png`). The flattening of ml-03 near 700 nm is the network's own response at
# 4.6 µm (the bundle's fast and accurate networks agree there), so the curve generated from it carries it too.

# %%
figures = out_dir / "figures"
print(sorted(p.name for p in figures.glob("*.png")))
for name in ("fit.png", "forest.png", "diameter.png"):
    display(Image(filename=str(figures / name), width=720))

# %%
print("report:", result.report)
print("\n".join(Path(result.report).read_text().splitlines()[:25]))

# %% [markdown]
# ## The same from the shell
#
# ```bash
# bubblecal data check my_bubbles/curves.csv --resonance my_bubbles/resonance.csv
# bubblecal data show my_bubbles/curves.csv
# bubblecal priors template --agent mylipid --protocol compression --workflow reduced-acoustic \
#     --out my_bubbles/mylipid.toml
# bubblecal priors check my_bubbles/mylipid.toml
# bubblecal calibrate --data my_bubbles/curves.csv --acoustic my_bubbles/resonance.csv \
#     --priors mylipid=my_bubbles/mylipid.toml --out my_bubbles/calibration
# ```
#
# A rerun with the same files reuses the finished phases (`manifest.json` holds their hashes); `--force` reruns
# them. `--networks accurate` uses the bundle's most accurate networks instead of the fast ones.
