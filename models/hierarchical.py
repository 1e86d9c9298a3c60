"""Joint hierarchical model of one agent: population ψ, every bubble's Θ_i and σ_i, acoustic datasets.

Model (``shared/docs/inference.md`` §4), for the pooled parameters k of the PriorSpec (those with
``hyper_m``/``hyper_tau``) and bubbles i = 1..n (one loading curve each)::

    m_k   ~ Uniform(hyper_m_k)                                   sites 'm_<k>'
    τ_k   ~ Uniform(hyper_tau_k)                                 sites 'tau_<k>'
    Θ_i,k | ψ ~ Normal(m_k, τ_k²) truncated to prior_k            site '<k>', shape (n,) in plate 'curves'
    Θ_i,k ~ Uniform(prior_k)                (free, not pooled)   site '<k>', shape (n,)
    σ_i   ~ Uniform(prior_σ)                (never pooled)       site 'sigma' | 'sigma_mech', shape (n,)
    y_i   ~ mechanical likelihood of curve i (models.mechanical)  observed site 'y_<curve name>'

and, in acoustic workflows, for acoustic datasets j = 1..n_ac (Definity: one dataset of 14 bubbles;
SonoVue: one per bubble), each with its own latent k_a (the only shell parameter the resonance
frequency depends on) and its own noise amplitude::

    ka_ac_j | ψ ~ TruncNormal(m_ka, τ_ka², prior_ka)            site 'ka_ac', shape (n_ac,) in plate 'acoustic'
    σ_ac_j ~ Uniform(prior_σac)                                  site 'sigma_ac', shape (n_ac,)
    f_j ~ acoustic likelihood of dataset j (models.acoustic)      observed site 'f_<dataset name>'

The population density is normalised by the truncation mass (:func:`bubblecal.models.likelihood.log_truncnorm`,
via :class:`TruncatedNormalPopulation`), so the latent sites are *prior* sites (a TMCMC tempers only
the observed sites). ``noncentred=True`` samples u_i,k ~ Uniform(0, 1) (sites '<k>_u') and sets the
deterministic Θ_i,k = F⁻¹(u_i,k | ψ), the inverse CDF of the truncated normal: the same joint
distribution, without the funnel between τ_k and Θ_i,k that hampers NUTS when the data are weak.
Deterministic sites: ``E_MPa``/``kappa_kBT`` (per bubble) and ``E_MPa_ac`` (per acoustic dataset).

Units: DPD for shell parameters and curves, MHz and µm for acoustic data (see the two single-dataset
modules).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist
from numpyro.distributions import constraints
from numpyro.distributions.util import promote_shapes, validate_sample

from bubblecal.data import DEFAULT_UNITS, UnitSystem
from bubblecal.models.acoustic import predict_frequency
from bubblecal.models.likelihood import (
    SD_FLOOR_REL,
    log_truncnorm,
    noise_sd,
    predict_mechanical,
    sd_floor_for,
    truncnorm_icdf,
)
from bubblecal.models.mechanical import derived_sites, resolve_setup, shell_params
from bubblecal.priors import PriorSpec

__all__ = ["TruncatedNormalPopulation", "hierarchical_model", "curve_site_name", "acoustic_site_name"]


class TruncatedNormalPopulation(dist.Distribution):
    """Normal(loc, scale²) truncated to the fixed interval [low, high], normalised by the truncation mass.

    Unlike ``numpyro.distributions.TruncatedNormal`` its log density stays finite when the interval lies
    far in a tail (log-space mass, :func:`bubblecal.models.likelihood.log_truncation_mass`) and a zero
    scale is floored instead of producing NaN. Sampling is by the inverse CDF.
    """

    arg_constraints = {"loc": constraints.real, "scale": constraints.nonnegative}
    reparametrized_params = ["loc", "scale"]

    def __init__(self, loc, scale, low, high, *, validate_args=None):
        self.loc, self.scale, self.low, self.high = promote_shapes(
            jnp.asarray(loc), jnp.asarray(scale), jnp.asarray(low, dtype=jnp.result_type(float)),
            jnp.asarray(high, dtype=jnp.result_type(float)))
        batch_shape = jnp.broadcast_shapes(jnp.shape(loc), jnp.shape(scale), jnp.shape(low), jnp.shape(high))
        super().__init__(batch_shape=batch_shape, validate_args=validate_args)

    @constraints.dependent_property(is_discrete=False, event_dim=0)
    def support(self):
        return constraints.interval(self.low, self.high)

    def icdf(self, u):
        return truncnorm_icdf(u, self.loc, self.scale, self.low, self.high)

    def sample(self, key, sample_shape=()):
        u = jax.random.uniform(key, sample_shape + self.batch_shape)
        return self.icdf(u)

    @validate_sample
    def log_prob(self, value):
        return log_truncnorm(value, self.loc, self.scale, self.low, self.high)


def curve_site_name(curve, index: int) -> str:
    """Observed-site name of a curve: 'y_<curve.name>' (or 'y_<index>' for an unnamed curve)."""
    name = getattr(curve, "name", None)
    return f"y_{name}" if name else f"y_{index}"


def acoustic_site_name(dataset, index: int) -> str:
    """Observed-site name of an acoustic dataset: 'f_<dataset.name>' (or 'f_<index>')."""
    name = getattr(dataset, "name", None)
    return f"f_{name}" if name else f"f_{index}"


def _population_draw(site: str, k: str, spec: PriorSpec, m: dict, tau: dict, noncentred: bool):
    p = spec.parameters[k]
    lo, hi = float(p.prior.lo), float(p.prior.hi)
    if not p.pooled:
        return numpyro.sample(site, dist.Uniform(lo, hi))
    if noncentred:
        u = numpyro.sample(f"{site}_u", dist.Uniform(0.0, 1.0))
        return numpyro.deterministic(site, truncnorm_icdf(u, m[k], tau[k], lo, hi))
    return numpyro.sample(site, TruncatedNormalPopulation(m[k], tau[k], lo, hi))


def hierarchical_model(curves: Sequence, surrogates: Sequence[Callable], spec: PriorSpec, *,
                       acoustic: Sequence = (), f_res=None, noncentred: bool = False, observed: bool = True,
                       sd_floor_rel: float = SD_FLOOR_REL, units: UnitSystem = DEFAULT_UNITS):
    """NumPyro joint model of one agent (module docstring for the sites and equations).

    ``curves``: loading curves (objects with ``x``, ``y`` in DPD units and a ``name``, e.g.
    :class:`bubblecal.data.LoadingCurve`; an optional ``kind`` is checked against the spec's setup).
    ``surrogates[i]``: the surrogate callable of curve i's diameter. ``acoustic``: acoustic datasets
    (objects with ``diameter_um`` [µm], ``frequency_MHz`` [MHz] and a ``name``, e.g.
    :class:`bubblecal.data.AcousticDataset`), used only when the spec is an acoustic workflow; ``f_res``
    the acoustic surrogate ``(ka, diameter_um) -> MHz``. ``observed=False`` samples every observation
    (prior / posterior predictive) with the same noise floors.
    """
    curves = list(curves)
    surrogates = list(surrogates)
    acoustic = list(acoustic) if spec.acoustic else []
    if len(curves) != len(surrogates):
        raise ValueError(f"{len(curves)} curves but {len(surrogates)} surrogates (one per curve)")
    if not curves and not acoustic:
        raise ValueError("hierarchical_model needs at least one curve or acoustic dataset")
    if acoustic and f_res is None:
        raise ValueError("acoustic datasets given but no acoustic surrogate f_res")
    setups = [resolve_setup(spec, s, kind=getattr(c, "kind", None)) for c, s in zip(curves, surrogates, strict=True)]
    names = [curve_site_name(c, i) for i, c in enumerate(curves)] + [acoustic_site_name(d, j)
                                                                      for j, d in enumerate(acoustic)]
    if len(set(names)) != len(names):
        raise ValueError(f"observation site names collide: {names}")
    noise_name = spec.mechanical_noise_name

    # population level
    m, tau = {}, {}
    for k in spec.pooled_names:
        p = spec.parameters[k]
        m[k] = numpyro.sample(f"m_{k}", dist.Uniform(float(p.hyper_m.lo), float(p.hyper_m.hi)))
        tau[k] = numpyro.sample(f"tau_{k}", dist.Uniform(float(p.hyper_tau.lo), float(p.hyper_tau.hi)))

    # mechanical curves
    if curves:
        with numpyro.plate("curves", len(curves)):
            theta = {k: _population_draw(k, k, spec, m, tau, noncentred) for k in spec.free_names}
            b = spec.noise[noise_name].prior
            sigma = numpyro.sample(noise_name, dist.Uniform(float(b.lo), float(b.hi)))
        derived_sites(theta, units)
        for i, (curve, surrogate, setup) in enumerate(zip(curves, surrogates, setups, strict=True)):
            params, d0 = shell_params({k: v[i] for k, v in theta.items()}, spec)
            x = jnp.asarray(np.asarray(curve.x, dtype=float))
            y = np.asarray(curve.y, dtype=float)
            yhat = predict_mechanical(surrogate, setup, params, d0, x)
            sd = noise_sd(yhat, sigma[i], sd_floor_for(float(np.max(np.abs(y))), sd_floor_rel))
            numpyro.sample(names[i], dist.Normal(yhat, sd), obs=jnp.asarray(y) if observed else None)

    # acoustic datasets: own k_a and sigma_ac each
    if acoustic:
        if "ka" not in spec.parameters:
            raise ValueError(f"priors {spec.name!r}: ka must be free for the acoustic datasets")
        with numpyro.plate("acoustic", len(acoustic)):
            ka_ac = _population_draw("ka_ac", "ka", spec, m, tau, noncentred)
            b = spec.noise["sigma_ac"].prior
            sigma_ac = numpyro.sample("sigma_ac", dist.Uniform(float(b.lo), float(b.hi)))
        numpyro.deterministic("E_MPa_ac", ka_ac * (float(units.ka_to_young(1.0)) * 1e-6))
        for j, ds in enumerate(acoustic):
            f_obs = np.asarray(ds.frequency_MHz, dtype=float)
            fhat = predict_frequency(f_res, ka_ac[j], ds.diameter_um)
            sd = noise_sd(fhat, sigma_ac[j], sd_floor_for(float(np.max(np.abs(f_obs))), sd_floor_rel))
            numpyro.sample(names[len(curves) + j], dist.Normal(fhat, sd), obs=jnp.asarray(f_obs) if observed else None)
