"""bubblecal.models: NumPyro model functions shared by every sampler and notebook.

- :func:`mechanical_model` — one loading curve, full or reduced shell (:func:`reduced_spec`), driven
  by a :class:`bubblecal.priors.PriorSpec`; :func:`mechanical_prediction` for predictive checks;
- :func:`acoustic_model` — one acoustic dataset (resonance frequency in MHz vs diameter in um);
- :func:`hierarchical_model` — the joint population model of one agent;
- :func:`phase2_model` — phase 2 of the staged hierarchy (hyperparameters from phase-1 samples);
  ``population=`` on the single-dataset models gives its phase 3;
- :mod:`bubblecal.models.distributions` — the one prior constructor (:func:`uniform_prior`), the one
  observation distribution (:func:`relative_normal`) and the population prior
  (:class:`TruncatedNormalPopulation`) every model uses;
- :mod:`bubblecal.models.likelihood` — the pure-JAX observation model (mechanical prediction,
  relative noise with its floor);
- :mod:`bubblecal.models.population` — pure-JAX population densities (truncated-normal population
  prior, population-predictive draws); :mod:`bubblecal.models.importance` — phase 2's importance sums.

Surrogates are duck-typed: any JAX callable ``(params[..., 6], x[...]) -> y[...]`` (mechanics, DPD
units) or ``(ka, diameter_um) -> MHz`` (acoustics). Equations: ``docs/inference.md`` sections 2-4.
"""

from bubblecal.models.acoustic import FrequencyTable, acoustic_model, acoustic_prediction, predict_frequency
from bubblecal.models.distributions import (
    TruncatedNormalPopulation,
    hyperprior_sites,
    relative_normal,
    uniform_prior,
)
from bubblecal.models.hierarchical import hierarchical_model
from bubblecal.models.importance import (
    dataset_terms,
    grouped_log_weights,
    importance_ess,
    importance_log_weights,
    staged_log_likelihood,
    sum_dataset_terms,
)
from bubblecal.models.likelihood import (
    SD_FLOOR_REL,
    noise_sd,
    predict_mechanical,
    relative_normal_loglik,
    sd_floor_for,
)
from bubblecal.models.mechanical import (
    POPULATION_SITE,
    mechanical_model,
    mechanical_prediction,
    nuts_init_values,
    population_factor,
    reduced_spec,
)
from bubblecal.models.population import (
    TAU_FLOOR_REL,
    log_truncnorm,
    population_log_prob,
    population_predictive_log_density,
    sample_population_predictive,
    truncnorm_icdf,
)
from bubblecal.models.staged import (
    PHASE2_FACTOR,
    dataset_log_likelihood,
    dataset_log_likelihoods,
    ess_site_name,
    leave_one_out_log_weights,
    phase2_model,
    pooled_bounds,
)
from bubblecal.models.traced import TracedSurrogate, pad_curve

__all__ = [
    # models
    "mechanical_model", "mechanical_prediction", "reduced_spec", "nuts_init_values", "population_factor",
    "POPULATION_SITE",
    "TracedSurrogate", "pad_curve", "acoustic_model", "acoustic_prediction", "predict_frequency", "FrequencyTable",
    "hierarchical_model", "phase2_model", "pooled_bounds", "leave_one_out_log_weights",
    "dataset_log_likelihood", "dataset_log_likelihoods", "PHASE2_FACTOR", "ess_site_name",
    # distributions
    "uniform_prior", "hyperprior_sites", "relative_normal", "TruncatedNormalPopulation",
    # log densities
    "SD_FLOOR_REL", "TAU_FLOOR_REL", "sd_floor_for", "noise_sd", "relative_normal_loglik", "predict_mechanical",
    "log_truncnorm", "truncnorm_icdf", "population_log_prob", "population_predictive_log_density",
    "staged_log_likelihood", "importance_log_weights", "grouped_log_weights", "importance_ess",
    "dataset_terms", "sum_dataset_terms",
    "sample_population_predictive",
    # preflight
]
