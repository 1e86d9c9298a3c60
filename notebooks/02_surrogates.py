# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Surrogates and their validation
#
# The likelihood never calls the DPD simulator: it calls a small MLP surrogate S(k_a, k_b, b1, b2, a3,
# a4; x) per bubble diameter. This notebook checks the surrogate pipeline against a **known answer**:
# curves from a closed-form shell law (`bubblecal.surrogates.training.synthetic`, *not* DPD) with 1 % relative
# noise, so that the best achievable held-out error is the *noise floor* (the exact law scored against
# the noisy curves).
#
# Steps: synthetic data → architecture sweep with a grouped holdout (whole curves held out) → parity
# plot → held-out error against the noise floor → export to the JAX `.npz` format and parity of the
# JAX evaluation with the training-side (NumPy/torch) network. With `BUBBLECAL_NOTEBOOK_SMALL=1` the
# sizes are tiny; in full mode a published training table is swept too when
# `BUBBLECAL_PUBLISHED_SET` points to one (e.g. the 2.1 µm compression set, `F_Delta.dat` layout).

# %%
import os
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import bubblecal.surrogates as surrogates
from bubblecal.data import DEFAULT_UNITS as units
from bubblecal.data import radius_dpd_from_diameter_um
from bubblecal.surrogates.training import (
    SweepConfig,
    TrainConfig,
    export_sweep,
    filter_curves,
    make_synthetic,
    noise_floor,
    read_dataset,
    relative_l2,
    run_sweep,
)

SMALL = os.environ.get("BUBBLECAL_NOTEBOOK_SMALL") == "1"
N_CURVES, WIDTHS, DEPTHS, EPOCHS = (150, (8, 16), (2,), 300) if SMALL else (600, (32, 64, 128), (2, 3), 600)
print(f"small run: {SMALL}")

# %% [markdown]
# ## Known-answer data
# A Latin hypercube over the six shell parameters (DPD units), compression of a 2.1 µm bubble
# (R = 4.2 DPD lengths), 15 displacements up to 1.68 DPD = 420 nm, multiplicative noise of 1 %.
# `filter_curves` applies the same rupture/zero filters as for simulated data.

# %%
ts = make_synthetic(N_CURVES, "compression", radius_dpd=radius_dpd_from_diameter_um(2.1), noise=0.01, seed=1)
ts, report = filter_curves(ts)
print(report)
print(f"{ts.n_curves} curves x {ts.n_points} points; parameter ranges:")
for name, (lo, hi) in ts.param_ranges().items():
    print(f"  {name:3s} {lo:10.4g} .. {hi:10.4g}")

# %% [markdown]
# ## Architecture sweep with a grouped holdout
# 10 % of the *curves* are held out (never single points of a curve seen in training); every width x depth
# is trained and the one with the smallest median held-out relative L2 error is selected.

# %%
config = SweepConfig(widths=WIDTHS, depths=DEPTHS, holdout_frac=0.1, seed=0, min_curves=20,
                     train=TrainConfig(max_epochs=EPOCHS))
sweep = run_sweep(ts, config, progress=False)
print(sweep.markdown())

# %% [markdown]
# ## Parity and the noise floor
# Held-out curves: surrogate prediction against the noisy data (what the score measures) and against the
# exact law (what the surrogate should learn). A surrogate at the noise floor reproduces the law and
# no more; a score far below the floor would mean it fits noise (impossible on held-out curves).

# %%
hold = sweep.holdout_set
floor = noise_floor(ts, np.flatnonzero(np.isin(ts.curve_id, hold.curve_id)))
err_true = relative_l2(sweep.holdout_pred, hold.extra["y_true"])
print(f"held-out median rel. L2 vs data: {sweep.score:.3%}   noise floor: {floor:.3%}   "
      f"vs exact law: {np.median(err_true):.3%}")
assert np.isfinite(sweep.score) and floor > 0

fig, axes = plt.subplots(1, 2, figsize=(10, 4))
y_nN, p_nN = units.dpd_to_nN(hold.y.ravel()), units.dpd_to_nN(sweep.holdout_pred.ravel())
lim = [0, 1.05 * max(y_nN.max(), p_nN.max())]
axes[0].plot(lim, lim, "k-", lw=0.8)
axes[0].plot(y_nN, p_nN, ".", ms=3)
axes[0].set(xlabel="held-out data force [nN]", ylabel="surrogate force [nN]", title="parity (held-out curves)",
            xlim=lim, ylim=lim)
rows = sweep.rows
labels = [f"{r['depth']}x{r['width']}" for r in rows]
axes[1].bar(labels, [100 * r["holdout_median"] for r in rows])
axes[1].axhline(100 * floor, color="k", ls="--", label="noise floor")
axes[1].set(ylabel="median held-out rel. L2 error [%]", xlabel="architecture (depth x width)")
axes[1].legend(frameon=False)
fig.tight_layout()

# %% [markdown]
# ## Export to JAX and parity
# The selected network goes into the `.npz` format that calibration loads (`bubblecal.surrogates.load`),
# pure JAX (no torch at inference time). Its output must match the training-side network to float32
# round-off on the same inputs; inputs outside the training box are flagged, never silently used.

# %%
workdir = Path(tempfile.mkdtemp(prefix="bubblecal_nb02_"))
path = export_sweep(sweep, workdir / "compression_2.1um.npz", nominal_diameter_um=2.1)
S = surrogates.load(path)
print(S)
u, _, _ = hold.points()
y_np = sweep.best_model.predict(u)
y_jax = np.asarray(S(u[:, :6], u[:, 6]))
rel = np.max(np.abs(y_jax - y_np)) / np.max(np.abs(y_np))
print(f"JAX vs training-side network: max |difference| / max |y| = {rel:.2e}")
assert rel < 1e-4
outside = np.array([[1e6, 500.0, 0.0, 0.0, 0.0, 0.0]])
print("in training box:", bool(np.asarray(S.in_training_box(outside, 0.5))[0]))

# %% [markdown]
# ## A published training table (full mode only)
# Set `BUBBLECAL_PUBLISHED_SET=/path/to/F_Delta.dat` (published layout) to run the same sweep on real DPD
# training data; the score is then compared with the repeatability of the simulations instead of a
# known noise floor.

# %%
published = os.environ.get("BUBBLECAL_PUBLISHED_SET")
if not SMALL and published and Path(published).exists():
    real = filter_curves(read_dataset(published, setup="compression"))[0]
    real_sweep = run_sweep(real, SweepConfig(widths=(32, 64, 128, 256), depths=(2, 3, 4)), progress=False)
    print(real_sweep.markdown())
else:
    print("no published training table given (BUBBLECAL_PUBLISHED_SET): skipped")
