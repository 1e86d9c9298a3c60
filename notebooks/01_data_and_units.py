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
# # Data and units
#
# The six AFM force curves and the 17 acoustic resonance observations that bubblecal calibrates
# against, and the DPD unit system that connects them to the simulations.
#
# Everything in the code is in DPD units: 1 length unit = 250 nm, k_BT = 1 at 300 K, and shell
# forces carry the force scale `fscale` = 0.0074 (1 nN = 446.698 DPD force).

# %%
import matplotlib.pyplot as plt
import numpy as np

from bubblecal.data import DEFAULT_UNITS as units
from bubblecal.data import acoustic_datasets, acoustic_observations, reference_curves

print(f"1 DPD length = {units.dpd_to_nm(1.0):g} nm")
print(f"1 nN = {units.nN_to_dpd(1.0):.3f} DPD force")
print(f"time unit = {units.time_s * 1e6:.4f} µs (rho_water = {units.rho_water:g} kg/m^3)")
print(f"E = 10 MPa  <->  k_a = {units.young_to_ka(10e6):.1f}  (Yt = {units.yt_per_ka:.2f} k_a Pa)")

# %% [markdown]
# ## Force spectroscopy
# Definity bubbles were compressed between parallel plates (x = displacement, y = force); SonoVue
# bubbles were indented at the poles (x = force, y = indentation depth). Only the retained points
# (filled) enter the likelihood; the open symbols are the rest of each digitised source curve.

# %%
curves = reference_curves()
fig, axes = plt.subplots(1, 2, figsize=(10, 4))
for curve in curves:
    ax = axes[0] if curve.kind == "compression" else axes[1]
    src = curve.source_curve
    disp, force = (src.x, src.y) if curve.kind == "compression" else (src.y, src.x)
    (line,) = ax.plot(curve.displacement_nm, curve.force_nN, "o", ms=4, label=f"{curve.diameter_um:g} µm")
    ax.plot(disp[~src.retained], force[~src.retained], "o", mfc="none", color=line.get_color(), ms=4)
for ax, title in zip(axes, ("Definity, compression", "SonoVue, indentation"), strict=True):
    ax.set(xlabel="displacement [nm]", ylabel="force [nN]", title=title)
    ax.legend(frameon=False)
fig.tight_layout()

# %%
for curve in curves:
    print(f"{curve.name:28s} R = {curve.radius_dpd:5.2f} DPD  points {curve.n_points:2d}"
          f"  max force {curve.force_nN.max():5.2f} nN = {curve.force_dpd.max():7.1f} DPD")

# %% [markdown]
# ## Acoustic resonance
# Definity's 14 bubbles form one acoustic dataset in the hierarchy; SonoVue's 3 bubbles are three.

# %%
obs = acoustic_observations()
fig, ax = plt.subplots(figsize=(5, 4))
for agent, marker in (("definity", "o"), ("sonovue", "s")):
    rows = [o for o in obs if o.agent == agent]
    ax.plot([o.diameter_um for o in rows], [o.frequency_MHz for o in rows], marker, label=agent)
ax.set(xlabel="diameter [µm]", ylabel="resonance frequency [MHz]")
ax.legend(frameon=False)
print([d.name for d in acoustic_datasets("definity") + acoustic_datasets("sonovue")])

# %%
# frequencies in a ringdown run with a 160x heavier shell convert with sqrt(160)
f_dpd = 0.02  # cycles per DPD time
print(f"{f_dpd} per u_t at mass factor 160 -> {units.frequency_to_physical(f_dpd, 160.0) / 1e6:.3f} MHz")
assert np.isclose(units.frequency_to_dpd(units.frequency_to_physical(f_dpd, 160.0), 160.0), f_dpd)
