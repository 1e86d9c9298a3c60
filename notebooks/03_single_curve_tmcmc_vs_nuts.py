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
# # One force curve, two samplers: TMCMC and NUTS
#
# The Definity 2.1 µm compression curve fitted with the reduced shell (k_a, k_b, d0 and the relative
# noise σ free; b1 = b2 = a3 = a4 = 0) through `bubblecal.models.mechanical_model`, sampled once with
# TMCMC (which also gives the evidence log Z) and once with NumPyro NUTS. The same model function
# feeds both samplers; `compare_posteriors` says whether their marginals agree. TMCMC is also a NumPyro
# kernel: `MCMC(NUTS(model), ...)` becomes `MCMC(TMCMCKernel(model), ...)` and `run`, `get_samples`,
# `print_summary` and `az.from_numpyro` stay as they are.
#
# The surrogate here is a small MLP trained on a *synthetic* known-answer data set (closed-form shell
# force law), made in a temporary folder in a few seconds: the numbers illustrate the workflow, not
# the calibrated Definity shell. Set `BUBBLECAL_NOTEBOOK_SMALL=1` for a quick run with small sizes.
# The command line does the same: `bubblecal compare --curve definity-2.1 --surrogate FILE.npz`.

# %%
import os
import shutil
import tempfile
from pathlib import Path

import arviz as az
import jax
import matplotlib.pyplot as plt
import numpy as np
from numpyro.infer import MCMC, NUTS, init_to_value

import bubblecal.surrogates as surrogates
from bubblecal.data import DEFAULT_UNITS as units
from bubblecal.data import load_reference, radius_dpd_from_diameter_um
from bubblecal.inference import TMCMC, TMCMCKernel, compare_posteriors, predictive_band
from bubblecal.models import mechanical_model, mechanical_prediction, nuts_init_values
from bubblecal.priors import load_priors
from bubblecal.surrogates.training import (
    DEFAULT_RANGES,
    SweepConfig,
    TrainConfig,
    export_sweep,
    filter_curves,
    make_synthetic,
    run_sweep,
)

SMALL = os.environ.get("BUBBLECAL_NOTEBOOK_SMALL") == "1"
N_CURVES, WIDTH, DEPTH, EPOCHS = (120, 16, 2, 60) if SMALL else (400, 64, 3, 400)
PARTICLES, REPLICAS = (500, 2) if SMALL else (10_000, 4)
NUTS_SAMPLES, NUTS_CHAINS = (150, 2) if SMALL else (1000, 4)
print(f"small run: {SMALL}")

# %% [markdown]
# ## A small surrogate
# Synthetic compression curves of a 2.1 µm bubble over a Latin hypercube of the six shell parameters.
# The nonlinear coefficients b1, b2, a3, a4 range over intervals that contain 0, so that the reduced
# shell (all four at 0) is evaluated inside the training box.

# %%
ranges = dict(DEFAULT_RANGES["compression"])
ranges.update({"b1": (-0.3, 3.0), "b2": (-0.5, 10.0), "a4": (-0.3, 4.0)})
ts = make_synthetic(N_CURVES, "compression", radius_dpd=radius_dpd_from_diameter_um(2.1), noise=0.01, seed=3,
                    ranges=ranges)
ts, report = filter_curves(ts)
config = SweepConfig(widths=(WIDTH,), depths=(DEPTH,), holdout_frac=0.1, seed=0, min_curves=2,
                     train=TrainConfig(max_epochs=EPOCHS))
sweep = run_sweep(ts, config, progress=False)
workdir = Path(tempfile.mkdtemp(prefix="bubblecal_nb03_"))
S = surrogates.load(export_sweep(sweep, workdir / "compression_2.1um.npz", nominal_diameter_um=2.1))
shutil.rmtree(workdir)  # the weights now live in S
print(S)

# %% [markdown]
# ## The curve, the priors, and both samplers
# Everything below is in DPD units (`bubblecal.data.units` converts for the plots).

# %%
curve = load_reference("definity", 2.1)
spec = load_priors("definity_reduced")
print(f"{curve.name}: {curve.x.size} points; free parameters {list(spec.parameters)} + {spec.mechanical_noise_name}")

tm = TMCMC(mechanical_model, num_particles=PARTICLES, num_replicas=REPLICAS)
tm.run(jax.random.PRNGKey(0), curve.x, curve.y, S, spec)
print(f"TMCMC: status {tm.status}, log Z = {tm.log_evidence:.3f} ± {tm.log_evidence_se:.3f} "
      f"({len(tm.stage_info) - 1} stages, {REPLICAS} replicas of N = {PARTICLES})")

nuts = MCMC(NUTS(mechanical_model, init_strategy=init_to_value(values=nuts_init_values(spec))),
            num_warmup=NUTS_SAMPLES, num_samples=NUTS_SAMPLES, num_chains=NUTS_CHAINS, chain_method="vectorized",
            progress_bar=False)
nuts.run(jax.random.PRNGKey(1), curve.x, curve.y, S, spec)
nuts.print_summary()  # r_hat, bulk ESS and the divergences

# %% [markdown]
# ## The swap: TMCMC as a NumPyro kernel
# The NUTS call above with one change, the kernel. `init` runs the whole tempering (the front end
# `TMCMC` with the same settings); each draw is then one particle of the final population, in random
# order, so `num_samples = num_particles` returns the whole population (further blocks of N draws come
# from MH moves at β = 1), warmup iterations draw nothing, and each chain is an independent tempering.
# The evidence is in the last state. `n_eff` in the summary counts particles, not independent draws.

# %%
kmc = MCMC(TMCMCKernel(mechanical_model, num_particles=PARTICLES), num_warmup=0, num_samples=PARTICLES,
           progress_bar=False)
kmc.run(jax.random.PRNGKey(2), curve.x, curve.y, S, spec)
kmc.print_summary()
print(f"log Z = {float(kmc.last_state.log_evidence):.3f} (front end above: {tm.log_evidence:.3f} "
      f"± {tm.log_evidence_se:.3f}), beta = {float(kmc.last_state.beta):g}")
idata = az.from_numpyro(kmc)
print(idata)

# %%
names = [*spec.parameters, spec.mechanical_noise_name]
print(compare_posteriors(tm, nuts, names=names))
print(compare_posteriors(kmc, nuts, names=names))

# %% [markdown]
# With the small settings (a few hundred NUTS draws from two chains, an MLP trained for seconds) the
# verdicts often fail: read them together with NUTS's r_hat, ESS and divergences above. The full
# settings (`BUBBLECAL_NOTEBOOK_SMALL` unset) use 4 × 1000 NUTS draws and 4 × 10,000 particles.

# %% [markdown]
# ## Marginals
# k_a and k_b in DPD units (E = 1790.92 Pa × k_a), d0 converted to nm.

# %%
tm_s, nuts_s = tm.get_samples(), nuts.get_samples()
panels = [("ka", "k_a [DPD 2-D modulus]", lambda v: v), ("kb", "k_b [DPD energy]", lambda v: v),
          ("d0", "d0 [nm]", units.dpd_to_nm)]
fig, axes = plt.subplots(1, 3, figsize=(12, 3.4))
for ax, (name, label, conv) in zip(axes, panels, strict=True):
    a, b = np.asarray(conv(tm_s[name])), np.asarray(conv(nuts_s[name]))
    bins = np.linspace(min(a.min(), b.min()), max(a.max(), b.max()), 40)
    ax.hist(a, bins=bins, density=True, alpha=0.5, label="TMCMC")
    ax.hist(b, bins=bins, density=True, histtype="step", lw=2, label="NUTS")
    ax.set(xlabel=label, yticks=[])
axes[0].legend()
fig.tight_layout()

# %% [markdown]
# ## Posterior predictive band
# The Gaussian-mixture predictive of the TMCMC posterior (median and central 90 %) at the data's
# displacements, against the data, in nm and nN.

# %%
y_scale = float(np.max(np.abs(curve.y)))
x_fine = np.linspace(curve.x.min(), curve.x.max(), 80)
take = np.random.default_rng(0).choice(PARTICLES, size=min(PARTICLES, 2000), replace=False)
means, sds = mechanical_prediction({k: v[take] for k, v in tm_s.items()}, S, spec, x_fine, y_scale=y_scale)
band = predictive_band(np.asarray(means, float), np.asarray(sds, float), level=0.9)
m_pts, s_pts = mechanical_prediction({k: v[take] for k, v in tm_s.items()}, S, spec, curve.x, y_scale=y_scale)
band90 = predictive_band(np.asarray(m_pts, float), np.asarray(s_pts, float))
print(f"coverage of the 90% band: {band90.coverage(curve.y):.2f}")

fig, ax = plt.subplots(figsize=(6, 4))
xn = units.dpd_to_nm(x_fine)
ax.fill_between(xn, units.dpd_to_nN(band.lower), units.dpd_to_nN(band.upper), alpha=0.3, label="90% predictive")
ax.plot(xn, units.dpd_to_nN(band.median), label="predictive median")
ax.plot(units.dpd_to_nm(curve.x), units.dpd_to_nN(curve.y), "k.", label=curve.name)
ax.set(xlabel="imposed displacement [nm]", ylabel="force [nN]")
ax.legend()
fig.tight_layout()
