"""NumPyro models of the staged (Korali-style) hierarchy: phase 2 over ψ, phase 3 per dataset.

Phase 1 is every dataset's single-level model (:func:`bubblecal.models.mechanical.mechanical_model`,
:func:`bubblecal.models.acoustic.acoustic_model`) under its uniform prior p0. Phase 2 samples the
population hyperparameters ψ = (m_k, τ_k) of the pooled parameters with the importance-sampling
likelihood of ``docs/inference.md`` section 4::

    log L(ψ) = Σ_i [ logsumexp_k (log p(θ_i^k | ψ) − log p0(θ_i^k)) − log N_i ]

(:func:`phase2_model`). Phase 3 re-weights one dataset by the learned population: pass
``population=(m_samples, tau_samples)`` to its single-level model (a factor
log mean_s p(θ | ψ_s) − log p0(θ); p0 is constant on the box, so the prior is not counted twice).

Phase 3 as published uses ψ_s ~ p(ψ | D), which already contains dataset i's own data, so D_i enters its
phase-3 posterior twice (once directly, once through ψ) and Θ_i is not the joint model's marginal.  The
exact marginal p(Θ_i | D) needs ψ ~ p(ψ | D_{-i}) ∝ p(ψ | D) / L_i(ψ), with L_i(ψ) the dataset's own
term of log L(ψ) above: :func:`leave_one_out_log_weights` gives those importance weights.

Units: DPD for shell parameters (see :mod:`bubblecal.data.units`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import numpyro

from bubblecal.models.distributions import hyperprior_sites
from bubblecal.models.importance import (
    dataset_terms,
    grouped_log_weights,
    importance_ess,
    sum_dataset_terms,
)
from bubblecal.priors import PriorSpec

__all__ = ["phase2_model", "pooled_bounds", "PHASE2_FACTOR", "ess_site_name", "leave_one_out_log_weights",
           "dataset_log_likelihood", "dataset_log_likelihoods"]

#: Name of the factor site that carries log L(ψ) (TMCMC tempers it as the likelihood).
PHASE2_FACTOR = "population_likelihood"


def ess_site_name(name: str) -> str:
    """Name of the phase-2 deterministic site holding a dataset's importance-sampling ESS.

    Parameters
    ----------
    name : str
        Dataset name.

    Returns
    -------
    str
        ``is_ess_<name>``.
    """
    return f"is_ess_{name}"


def pooled_bounds(spec: PriorSpec) -> dict[str, tuple[float, float]]:
    """Prior range of every pooled parameter.

    Parameters
    ----------
    spec : PriorSpec
        The priors.

    Returns
    -------
    dict
        Pooled parameter name -> (lo, hi) in DPD units.
    """
    return {k: spec.parameters[k].prior.as_tuple() for k in spec.pooled_names}


def phase2_model(phase1_samples: Sequence[Mapping[str, jnp.ndarray]], spec: PriorSpec,
                 names: Sequence[str] | None = None):
    """Phase 2 of the staged hierarchy: hyperparameters ψ of ``spec`` given phase-1 posterior samples.

    Sites: ``m_<k>``, ``tau_<k>``, the factor :data:`PHASE2_FACTOR` and the deterministic
    :func:`ess_site_name` of each dataset (IS effective sample size; small values mean phase 1 did not
    cover what ψ proposes).

    Parameters
    ----------
    phase1_samples : sequence of mapping of str to array_like
        ``phase1_samples[i]`` maps parameter names to dataset i's (N_i,) phase-1 posterior draws (DPD
        units); datasets that sampled only some pooled parameters (acoustic datasets: only ``ka``)
        contribute those.
    spec : PriorSpec
        Hyperpriors and prior ranges of the pooled parameters.
    names : sequence of str or None
        Dataset names (default ``dataset0``, ``dataset1``, ...).

    Raises
    ------
    ValueError
        For mismatched names, no datasets, or a dataset with none of the pooled parameters.
    """
    names = [f"dataset{i}" for i in range(len(phase1_samples))] if names is None else list(names)
    if len(names) != len(phase1_samples):
        raise ValueError(f"{len(phase1_samples)} phase-1 sample sets but {len(names)} names")
    if not phase1_samples:
        raise ValueError("phase2_model needs the phase-1 samples of at least one dataset")
    bounds = pooled_bounds(spec)
    m, tau = hyperprior_sites(spec)
    datasets = [{k: jnp.asarray(v) for k, v in s.items() if k in bounds} for s in phase1_samples]
    for name, samples in zip(names, datasets, strict=True):
        if not samples:
            raise ValueError(f"phase-1 samples of {name!r} contain none of the pooled parameters "
                             f"{', '.join(bounds)}")
    # datasets of one shape are one stacked computation: the program's size does not grow with the bubbles
    groups = grouped_log_weights(m, tau, datasets, bounds)
    ess = {}
    for members, lw in groups:
        group_ess = importance_ess(lw)  # (D,)
        ess |= {i: group_ess[j] for j, i in enumerate(members)}
    for i, name in enumerate(names):
        numpyro.deterministic(ess_site_name(name), ess[i])
    numpyro.factor(PHASE2_FACTOR, sum_dataset_terms(dataset_terms(groups)))


@partial(jax.jit, static_argnums=3)
def _terms_block(m, tau, data, box):
    """(chunk, n_datasets) phase-2 terms of every dataset at a chunk of ψ draws; ``box`` the bounds as items."""
    terms = dataset_terms(grouped_log_weights(m, tau, data, dict(box)))
    return jnp.stack([terms[i] for i in range(len(data))], axis=-1)


def dataset_log_likelihood(m_samples: Mapping[str, np.ndarray], tau_samples: Mapping[str, np.ndarray],
                           phase1_samples: Mapping[str, np.ndarray], bounds: Mapping[str, tuple[float, float]],
                           chunk: int = 256) -> np.ndarray:
    """Dataset i's own phase-2 term log L_i(ψ_s) at every phase-2 draw (its pointwise log likelihood).

    log L_i(ψ) = logsumexp_k (log p(θ_i^k | ψ) − log p0(θ_i^k)) − log N_i.

    Parameters
    ----------
    m_samples, tau_samples : mapping of str to array_like
        Pooled parameter name -> (S,) phase-2 draws of the population mean / spread (DPD units).
    phase1_samples : mapping of str to array_like
        Dataset i's (N_i,) phase-1 draws (DPD units), as phase 2 used them.
    bounds : mapping of str to (float, float)
        Prior ranges of the pooled parameters.
    chunk : int
        ψ draws per evaluation chunk (memory S × N_i otherwise).

    Returns
    -------
    numpy.ndarray
        (S,) float64 (dimensionless log density); −inf or NaN where L_i(ψ_s) is 0 or undefined.

    Raises
    ------
    ValueError
        If the dataset has none of the pooled parameters.
    """
    names = [k for k in m_samples if k in phase1_samples and k in bounds]
    if not names:
        raise ValueError("the dataset has none of the pooled parameters")
    return dataset_log_likelihoods(m_samples, tau_samples, [phase1_samples], bounds, chunk)[:, 0]


def dataset_log_likelihoods(m_samples: Mapping[str, np.ndarray], tau_samples: Mapping[str, np.ndarray],
                            phase1_samples: Sequence[Mapping[str, np.ndarray]],
                            bounds: Mapping[str, tuple[float, float]], chunk: int = 256) -> np.ndarray:
    """Every dataset's phase-2 term log L_i(ψ_s) at every phase-2 draw (phase 2's pointwise log likelihood).

    One compiled program over chunks of ψ draws for all datasets (stacked by shape, as phase 2 computes them),
    so the cost does not grow with one program call per dataset and chunk.

    Parameters
    ----------
    m_samples, tau_samples : mapping of str to array_like
        Pooled parameter name -> (S,) phase-2 draws of the population mean / spread (DPD units).
    phase1_samples : sequence of mapping of str to array_like
        Each dataset's (N_i,) phase-1 draws (DPD units), as phase 2 used them.
    bounds : mapping of str to (float, float)
        Prior ranges of the pooled parameters.
    chunk : int
        ψ draws per evaluation (memory chunk × Σ_i N_i).

    Returns
    -------
    numpy.ndarray
        (S, n_datasets) float64 (dimensionless); −inf or NaN where L_i(ψ_s) is 0 or undefined.

    Raises
    ------
    ValueError
        If a dataset has none of the pooled parameters.
    """
    names = [k for k in m_samples if k in bounds]
    sets = [{k: jnp.asarray(v) for k, v in s.items() if k in names} for s in phase1_samples]
    for i, s in enumerate(sets):
        if not s:
            raise ValueError(f"dataset {i} has none of the pooled parameters {', '.join(names)}")
    m_all = {k: np.asarray(m_samples[k]) for k in names}
    tau_all = {k: np.asarray(tau_samples[k]) for k in names}
    size = int(m_all[names[0]].shape[0])
    step = max(1, min(int(chunk), size))
    box = tuple((k, (float(lo), float(hi))) for k, (lo, hi) in bounds.items() if k in names)
    out = np.empty((size, len(sets)))
    for a in range(0, size, step):
        n = min(step, size - a)
        # the last chunk is padded to the chunk size: one compiled shape
        pick = np.minimum(np.arange(a, a + step), size - 1)
        values = _terms_block({k: v[pick] for k, v in m_all.items()}, {k: v[pick] for k, v in tau_all.items()}, sets,
                              box)
        out[a:a + n] = np.asarray(values)[:n]
    return out


def leave_one_out_log_weights(m_samples: Mapping[str, np.ndarray], tau_samples: Mapping[str, np.ndarray],
                              phase1_samples: Mapping[str, np.ndarray], bounds: Mapping[str, tuple[float, float]],
                              chunk: int = 256) -> np.ndarray:
    """Log importance weights that turn phase-2 draws ψ_s ~ p(ψ | D) into draws of p(ψ | D_{-i}).

    log w_s = −log L_i(ψ_s) + const, with log L_i(ψ) = logsumexp_k (log p(θ_i^k | ψ) − log p0(θ_i^k))
    − log N_i dataset i's own phase-2 term.

    Parameters
    ----------
    m_samples, tau_samples : mapping of str to array_like
        Pooled parameter name -> (S,) phase-2 draws of the population mean / spread.
    phase1_samples : mapping of str to array_like
        Dataset i's (N_i,) phase-1 draws (DPD units).
    bounds : mapping of str to (float, float)
        Prior ranges of the pooled parameters.
    chunk : int
        ψ draws per evaluation chunk (memory S × N_i otherwise).

    Returns
    -------
    numpy.ndarray
        (S,) normalised log weights (logsumexp = 0, float64); −inf where L_i(ψ_s) is 0 or undefined.

    Raises
    ------
    ValueError
        If the dataset has none of the pooled parameters or no draw gives it a finite likelihood.
    """
    try:
        out = -dataset_log_likelihood(m_samples, tau_samples, phase1_samples, bounds, chunk)
    except ValueError as exc:
        raise ValueError(f"leave_one_out_log_weights: {exc}") from None
    out[~np.isfinite(out)] = -np.inf  # L_i(ψ_s) = 0 or undefined: that draw gets no weight
    if np.all(np.isneginf(out)):
        raise ValueError("leave_one_out_log_weights: no phase-2 draw gives the dataset a finite likelihood")
    top = out.max()
    return out - (top + math.log(np.exp(out - top).sum()))  # float64 normalisation (jax's would be float32)
