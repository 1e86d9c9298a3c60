"""The NumPyro distributions every model is built from: uniform priors, the relative-noise observation
distribution and the truncated-normal population prior.

One constructor per role, used by :mod:`bubblecal.models.mechanical`, :mod:`bubblecal.models.acoustic`,
:mod:`bubblecal.models.hierarchical` and :mod:`bubblecal.models.staged`:

- :func:`uniform_prior` — Uniform(lo, hi) of a prior range or a hyperprior range (``docs/inference.md``
  section 4); :func:`hyperprior_sites` samples the population hyperparameters ψ with it;
- :func:`relative_normal` — y ~ N(ŷ, (σ ŷ)² + s_floor²), the observation model of curves and acoustic
  datasets (sections 2-3; the floor is explained in :mod:`bubblecal.models.likelihood`);
- :class:`TruncatedNormalPopulation` — Θ_k | ψ ~ Normal(m_k, τ_k²) truncated to the prior range.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpyro
import numpyro.distributions as dist
from numpyro.distributions import constraints
from numpyro.distributions.util import promote_shapes, validate_sample

from bubblecal.models.likelihood import noise_sd
from bubblecal.models.population import log_truncnorm, truncnorm_icdf
from bubblecal.priors import Bounds, PriorSpec

__all__ = ["uniform_prior", "hyperprior_sites", "relative_normal", "TruncatedNormalPopulation"]


def uniform_prior(bounds: Bounds) -> dist.Uniform:
    """Uniform(lo, hi) over a prior or hyperprior range.

    Parameters
    ----------
    bounds : Bounds
        The range (units of its parameter, e.g. DPD 2-D modulus for ``ka``); ``lo`` and ``hi`` are
        passed as Python floats, so JAX treats them as weakly typed scalars.

    Returns
    -------
    numpyro.distributions.Uniform
    """
    return dist.Uniform(float(bounds.lo), float(bounds.hi))


def hyperprior_sites(spec: PriorSpec) -> tuple[dict, dict]:
    """Sample the population hyperparameters ψ: ``m_<k>`` ~ U(hyper_m_k), ``tau_<k>`` ~ U(hyper_tau_k).

    Parameters
    ----------
    spec : PriorSpec
        Gives the pooled parameters k and their hyperprior ranges (units of each parameter).

    Returns
    -------
    m, tau : dict
        Pooled parameter name -> sampled population mean / spread.
    """
    m, tau = {}, {}
    for k in spec.pooled_names:
        p = spec.parameters[k]
        m[k] = numpyro.sample(f"m_{k}", uniform_prior(p.hyper_m))
        tau[k] = numpyro.sample(f"tau_{k}", uniform_prior(p.hyper_tau))
    return m, tau


def relative_normal(yhat, sigma, sd_floor) -> dist.Normal:
    """Observation distribution with relative Gaussian noise: N(ŷ, (σ ŷ)² + s_floor²).

    Parameters
    ----------
    yhat : array_like
        Predicted observations ŷ (units of the data: DPD force or length for curves, MHz for
        acoustic data).
    sigma : array_like
        Relative noise amplitude σ [-], broadcast against ``yhat``.
    sd_floor : array_like
        Standard-deviation floor s_floor (units of ``yhat``), e.g. from
        :func:`~bubblecal.models.likelihood.sd_floor_for`.

    Returns
    -------
    numpyro.distributions.Normal
        Normal(ŷ, :func:`~bubblecal.models.likelihood.noise_sd` (ŷ, σ, s_floor)).
    """
    return dist.Normal(yhat, noise_sd(yhat, sigma, sd_floor))


class TruncatedNormalPopulation(dist.Distribution):
    """Normal(loc, scale²) truncated to the fixed interval [low, high], normalised by the truncation mass.

    Unlike ``numpyro.distributions.TruncatedNormal`` its log density stays finite when the interval lies
    far in a tail (log-space mass, :func:`~bubblecal.models.population.log_truncation_mass`) and a zero
    scale is floored instead of producing NaN. Sampling is by the inverse CDF.

    Parameters
    ----------
    loc : array_like
        Population mean m (units of the parameter).
    scale : array_like
        Population spread τ >= 0 (units of the parameter).
    low, high : array_like
        The prior range of the parameter.
    validate_args : bool or None
        NumPyro's argument validation.
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
        """The interval [low, high]."""
        return constraints.interval(self.low, self.high)

    def icdf(self, u):
        """Quantile function at u ∈ [0, 1]."""
        return truncnorm_icdf(u, self.loc, self.scale, self.low, self.high)

    def sample(self, key, sample_shape=()):
        """Draws by the inverse CDF of uniform variates."""
        u = jax.random.uniform(key, sample_shape + self.batch_shape)
        return self.icdf(u)

    @validate_sample
    def log_prob(self, value):
        """Log density, −∞ outside [low, high]."""
        return log_truncnorm(value, self.loc, self.scale, self.low, self.high)
