"""bubblecal.models: NumPyro model functions shared by every sampler and notebook.

- :func:`mechanical_model` — one loading curve, full or reduced shell (:func:`reduced_spec`), driven
  by a :class:`bubblecal.priors.PriorSpec`; :func:`mechanical_prediction` for predictive checks;
- :func:`acoustic_model` — one acoustic dataset (resonance frequency in MHz vs diameter);
- :func:`hierarchical_model` — the joint population model of one agent;
- :mod:`bubblecal.models.likelihood` — pure-JAX log densities (relative noise with its floor,
  truncated-normal population prior, the staged-hierarchy importance sums, population-predictive
  draws); ``population=`` on the single-dataset models gives the phase-3 target of the staged hierarchy;
- :func:`phase2_model` — phase 2 of the staged hierarchy (hyperparameters from phase-1 samples).

Surrogates are duck-typed: any JAX callable ``(params[..., 6], x[...]) -> y[...]`` (mechanics) or
``(ka, diameter_um) -> MHz`` (acoustics).
"""

from bubblecal.models.acoustic import acoustic_model, acoustic_prediction
from bubblecal.models.hierarchical import TruncatedNormalPopulation, hierarchical_model
from bubblecal.models.likelihood import (
    SD_FLOOR_REL,
    importance_ess,
    log_truncnorm,
    population_log_prob,
    population_predictive_log_density,
    relative_normal_loglik,
    sample_population_predictive,
    staged_log_likelihood,
)
from bubblecal.models.mechanical import (
    mechanical_model,
    mechanical_prediction,
    nuts_init_values,
    population_factor,
    reduced_spec,
)
from bubblecal.models.staged import hyperprior_sites, phase2_model

__all__ = [
    "mechanical_model", "mechanical_prediction", "reduced_spec", "acoustic_model", "acoustic_prediction",
    "hierarchical_model", "TruncatedNormalPopulation", "SD_FLOOR_REL", "relative_normal_loglik", "log_truncnorm",
    "population_log_prob", "population_predictive_log_density", "staged_log_likelihood", "importance_ess",
    "sample_population_predictive", "population_factor", "nuts_init_values", "phase2_model", "hyperprior_sites",
]
