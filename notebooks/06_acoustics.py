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
# # Acoustics: resonance frequency and the stretching modulus
#
# The acoustic data (resonance frequency in MHz of bubbles of known diameter), the acoustic surrogate
# f_res²(k_a) = a0 + a1 k_a + a2 k_a² per diameter with its leave-one-out errors, and the posterior of
# k_a and the relative noise σ_ac from one acoustic dataset through `bubblecal.models.acoustic_model`
# (`shared/docs/inference.md` §3).
#
# The surrogate is the shipped one (`bubblecal.surrogates.default_bundle_path()`): quadratics fitted to the
# resonance frequencies of DPD ringdown simulations (implicit tier) at each Definity diameter, so the
# posterior below is the Definity shell's.

# %%
import os

import jax
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from bubblecal.data import DEFAULT_UNITS as units
from bubblecal.data import acoustic_datasets, acoustic_observations
from bubblecal.inference import TMCMC, predictive_band
from bubblecal.models import acoustic_model, acoustic_prediction
from bubblecal.priors import load_priors
from bubblecal.surrogates import default_bundle_path, load_bundle

SMALL = os.environ.get("BUBBLECAL_NOTEBOOK_SMALL") == "1"
PARTICLES = 1000 if SMALL else 20_000




bundle = load_bundle(default_bundle_path(must_exist=True))
fres = bundle.acoustic["definity"]
print(f"{fres.name}: {len(fres.diameters)} diameters, source: {fres.meta.get('source')}")

# %% [markdown]
# ## The acoustic data
# Definity: 14 bubbles from one study, one dataset in the hierarchy (one k_a for all); SonoVue: three
# bubbles, three datasets.

# %%
obs = acoustic_observations()
table = pd.DataFrame([{"agent": o.agent, "diameter [µm]": o.diameter_um, "f_res [MHz]": o.frequency_MHz,
                       "source": o.source} for o in obs])
print(table.to_string(index=False))
print([d.name for d in acoustic_datasets("definity") + acoustic_datasets("sonovue")])

# %% [markdown]
# ## f_res²(k_a) per diameter and leave-one-out errors
# At each diameter the squared resonance frequency of the DPD ringdowns is fitted by a quadratic in k_a with
# a free intercept (`bubblecal.surrogates.fit_quadratic`); the leave-one-out relative error of f_res says how
# well the quadratic interpolates between the simulated k_a values. The shipped fits of three Definity
# diameters, with the leave-one-out errors stored with them.

# %%
fig, axes = plt.subplots(1, 2, figsize=(11, 4))
rows = []
for d in (4.68, 7.2, 11.2):
    fit = fres.fits[d]
    rows.append({"diameter [µm]": d, "ringdowns": fit.n_points, "a0 [MHz²]": fit.a0, "a1 [MHz²/DPD]": fit.a1,
                 "a2 [MHz²/DPD²]": fit.a2, "LOO median [%]": 100 * fit.loo_median,
                 "LOO max [%]": 100 * fit.loo_max})
    ka_fine = np.linspace(fit.ka_min, fit.ka_max, 200)
    axes[0].plot(units.ka_to_young(ka_fine) / 1e6, fit.a0 + fit.a1 * ka_fine + fit.a2 * ka_fine**2, "-",
                 label=f"{d:g} µm")
    axes[1].semilogy(100 * np.sort(np.asarray(fit.loo_rel_errors)), "o-", label=f"{d:g} µm")
axes[0].set(xlabel="Young's modulus E [MPa] (from k_a)", ylabel="f_res² [MHz²]")
axes[1].set(xlabel="ringdown (sorted by error)", ylabel="leave-one-out error of f_res [%]")
axes[0].legend(frameon=False)
fig.tight_layout()
print(pd.DataFrame(rows).to_string(index=False, float_format="%.4g"))

# %% [markdown]
# ## Posterior of k_a from the Definity acoustic dataset
# Priors of the Definity reduced + acoustic workflow (k_a and σ_ac; only k_a enters the resonance
# frequency). TMCMC through `acoustic_model`, then the predictive band of f_res against diameter.

# %%
spec = load_priors("definity_reduced_acoustic")
ds = acoustic_datasets("definity")[0]
tm = TMCMC(acoustic_model, num_particles=PARTICLES, target_cov=0.8)
tm.run(jax.random.PRNGKey(0), ds.diameter_um, ds.frequency_MHz, fres, spec)
post = tm.get_samples()
print(f"status {tm.status}, log Z = {tm.log_evidence:.2f}")
for name, conv, unit in (("ka", lambda v: v, "DPD"), ("E_MPa", lambda v: v, "MPa"), ("sigma_ac", lambda v: v, "-")):
    v = np.asarray(conv(post[name]))
    lo, med, hi = np.quantile(v, [0.05, 0.5, 0.95])
    print(f"{name:9s} median {med:10.4g}   90% interval [{lo:.4g}, {hi:.4g}] {unit}")
assert tm.status == "converged"
fres.check_range(np.asarray(post["ka"]), float(ds.diameter_um[0]))

# %%
f_scale = float(np.max(ds.frequency_MHz))
take = np.random.default_rng(0).choice(len(post["ka"]), size=min(2000, len(post["ka"])), replace=False)
means, sds = acoustic_prediction(post["ka"][take], post["sigma_ac"][take], fres, ds.diameter_um, f_scale=f_scale)
band = predictive_band(np.asarray(means, float), np.asarray(sds, float), level=0.9)
print(f"coverage of the 90% predictive band: {band.coverage(ds.frequency_MHz):.2f}")
order = np.argsort(ds.diameter_um)
fig, ax = plt.subplots(figsize=(6, 4))
ax.fill_between(ds.diameter_um[order], band.lower[order], band.upper[order], alpha=0.3, label="90% predictive")
ax.plot(ds.diameter_um[order], band.median[order], "-", label="predictive median")
ax.plot(ds.diameter_um, ds.frequency_MHz, "ko", ms=4, label="Definity (measured)")
ax.set(xlabel="bubble diameter [µm]", ylabel="resonance frequency [MHz]")
ax.legend(frameon=False)
fig.tight_layout()
