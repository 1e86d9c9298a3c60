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
# # Sensitivity: which shell parameters does a force curve see?
#
# First-order (S1) and total (ST) Sobol indices of the surrogate output with respect to the shell
# parameters (k_a, k_b, b1, b2, a3, a4), over the prior box of a workflow, pointwise along the loading
# coordinate and averaged over the experimentally explored range (`shared/docs/inference.md` §8).
# Saltelli design and SALib estimators with bootstrap confidence intervals, through
# `bubblecal.workflows.sensitivity.surrogate_sensitivity` (the same code as `bubblecal sensitivity`).
#
# The surrogates are those of the shipped DPD bundle (`bubblecal.surrogates.default_bundle_path()`), trained on
# the shipped DPD training sets: the indices describe the DPD shell model over the prior box.
# `BUBBLECAL_NOTEBOOK_SMALL=1` uses N = 256 instead of the published N = 2,048.

# %%
import os

import matplotlib.pyplot as plt
import numpy as np

from bubblecal.data import DEFAULT_UNITS as units
from bubblecal.data import load_reference
from bubblecal.priors import load_priors
from bubblecal.surrogates import default_bundle_path, load_bundle
from bubblecal.workflows import averaging_range, surrogate_sensitivity

SMALL = os.environ.get("BUBBLECAL_NOTEBOOK_SMALL") == "1"
N, POINTS = (256, 16) if SMALL else (2048, 40)




bundle = load_bundle(default_bundle_path(must_exist=True))

# %% [markdown]
# ## Definity, compression, full shell
# Loading coordinate: imposed displacement; indices averaged over the displacements of the 2.1 µm curve.

# %%
runs = {}
for agent, diameter, setup in (("definity", 2.1, "compression"), ("sonovue", 3.2, "indentation")):
    curve = load_reference(agent, diameter)
    spec = load_priors(f"{agent}_full")
    sur = bundle.get(setup, diameter)
    x_range, cut = averaging_range(curve.x, sur)  # the data may reach past the training grid: said, not hidden
    if cut:
        print(f"{curve.name}: {cut}")
    run = surrogate_sensitivity(sur, spec, x_range, N=N, num_points=POINTS)
    runs[curve.name] = run
    print(f"{curve.name} ({spec.name} prior box)")
    print(run.result.summary())
    print(f"design points outside the surrogate's training box: {100 * run.outside_training_fraction:.1f} %\n")

# %% [markdown]
# ## Along the loading coordinate
# Solid: first-order S1, dashed: total ST, shaded: 95 % bootstrap intervals. The grey span is the range
# explored by the experiment (the average is taken there). Compression in nm of displacement,
# indentation in nN of applied force.

# %%
fig, axes = plt.subplots(1, 2, figsize=(12, 4.2), sharey=True)
for ax, (name, run) in zip(axes, runs.items(), strict=True):
    r = run.result
    if run.setup == "compression":
        x, lo, hi, label = units.dpd_to_nm(r.x), *units.dpd_to_nm(np.array(r.x_range)), "imposed displacement [nm]"
    else:
        x, lo, hi, label = units.dpd_to_nN(r.x), *units.dpd_to_nN(np.array(r.x_range)), "applied force [nN]"
    ax.axvspan(lo, hi, color="0.92", zorder=0)
    for j, pname in enumerate(r.names):
        (line,) = ax.plot(x, r.S1[:, j], "-", label=pname)
        ax.plot(x, r.ST[:, j], "--", color=line.get_color())
        ax.fill_between(x, r.S1[:, j] - r.S1_conf[:, j], r.S1[:, j] + r.S1_conf[:, j], color=line.get_color(),
                        alpha=0.15, lw=0)
    ax.set(xlabel=label, title=name, ylim=(-0.05, 1.05))
axes[0].set_ylabel("Sobol index (S1 solid, ST dashed)")
axes[1].legend(frameon=False, ncol=2)
fig.tight_layout()

# %% [markdown]
# ## Reduced shell
# With b1 = b2 = a3 = a4 = 0 only k_a and k_b vary; their indices add up to about 1 when the two act
# additively (S1 ≈ ST) and the gap ST − S1 measures their interaction.

# %%
curve = load_reference("definity", 2.1)
reduced = surrogate_sensitivity(bundle.get("compression", 2.1), load_priors("definity_reduced"),
                                (float(curve.x.min()), float(curve.x.max())), N=N, num_points=POINTS)
print(reduced.result.summary())
table = reduced.result.table()
assert all(np.isfinite([row["S1"] for row in table]))
