"""Pure-JAX importance sums of phase 2 of the staged hierarchy (``docs/inference.md`` section 4).

Every dataset's phase-1 draws θ_i^k, weighted by the population density over their uniform prior,
log w_k = log p(θ_i^k | ψ) − log p0(θ_i^k), give the phase-2 likelihood
log L(ψ) = Σ_i [logsumexp_k log w_k − log N_i] and each dataset's importance ESS. Plain functions of arrays
(jit/vmap-ready); :func:`grouped_log_weights` stacks the datasets of one shape so that a compiled phase 2 does
not grow with their number.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import jax
import jax.numpy as jnp
from jax.scipy.special import logsumexp

from bubblecal.models.population import log_truncnorm

__all__ = ["importance_log_weights", "grouped_log_weights", "staged_log_likelihood", "dataset_terms",
           "sum_dataset_terms", "importance_ess"]


def _uniform_log_p0(theta_k, lo, hi):
    """Log density of Uniform(lo, hi) at ``theta_k``."""
    inside = (theta_k >= lo) & (theta_k <= hi)
    return jnp.where(inside, -math.log(hi - lo), -jnp.inf)


def importance_log_weights(m: Mapping[str, jax.Array], tau: Mapping[str, jax.Array],
                           samples: Mapping[str, jax.Array], bounds: Mapping[str, tuple[float, float]],
                           log_p0=None, names: Sequence[str] | None = None):
    """Importance log weights log w_k = log p(θ^k | ψ) − log p0(θ^k) of one dataset's phase-1 samples.

    Parameters
    ----------
    m, tau : mapping of str to array_like
        Pooled parameter name -> population mean / spread of batch shape B (scalars for one ψ).
    samples : mapping of str to array_like
        Parameter name -> (N,) phase-1 posterior draws (DPD units).
    bounds : mapping of str to (float, float)
        Prior range of each pooled parameter.
    log_p0 : array_like or None
        (N,) phase-1 prior log density *of the pooled components*; default the uniform prior on
        ``bounds`` (the non-pooled components of θ — noise, free unpooled parameters — cancel between
        p(θ | ψ) p0(rest) and p0(θ)).
    names : sequence of str or None
        Pooled parameters; default the keys of ``m`` present in ``samples``.

    Returns
    -------
    Array
        Shape B + (N,).

    Raises
    ------
    ValueError
        If the dataset has none of the pooled parameters.
    """
    names = [k for k in m if k in samples] if names is None else list(names)
    if not names:
        raise ValueError("importance_log_weights: the dataset has none of the pooled parameters")
    lp = 0.0
    lp0 = 0.0
    for k in names:
        lo, hi = bounds[k]
        mk = jnp.asarray(m[k])
        tk = jnp.asarray(tau[k])
        th = jnp.asarray(samples[k])
        lp = lp + log_truncnorm(th, mk[..., None], tk[..., None], lo, hi)
        lp0 = lp0 + _uniform_log_p0(th, lo, hi)
    if log_p0 is not None:
        lp0 = jnp.asarray(log_p0)
    return lp - lp0


def grouped_log_weights(m: Mapping[str, jax.Array], tau: Mapping[str, jax.Array],
                        datasets: Sequence[Mapping[str, jax.Array]], bounds: Mapping[str, tuple[float, float]],
                        log_p0: Sequence[jax.Array | None] | None = None) -> list[tuple[list[int], jax.Array]]:
    """:func:`importance_log_weights` of many datasets, those of one shape stacked into one array.

    Datasets that share their pooled parameters and their number of draws (and take the uniform p0) are stacked
    on a new axis, so a compiled phase 2 holds one computation per such group however many datasets there are
    (one per dataset would make its compilation grow with the bubbles).

    Parameters
    ----------
    m, tau : mapping of str to array_like
        Pooled parameter name -> population mean / spread of batch shape B.
    datasets : sequence of mapping of str to array_like
        ``datasets[i]`` maps parameter names to dataset i's (N_i,) phase-1 draws.
    bounds : mapping of str to (float, float)
        Prior range of each pooled parameter.
    log_p0 : sequence of (array_like or None) or None
        ``log_p0[i]`` overrides the uniform phase-1 prior of dataset i (that dataset then forms its own group).

    Returns
    -------
    list of (list of int, Array)
        (indices of the datasets in ``datasets``, their log weights of shape B + (D, N)), groups in the order of
        their first dataset.

    Raises
    ------
    ValueError
        If a dataset has none of the pooled parameters.
    """
    groups: dict[tuple, list[int]] = {}
    for i, samples in enumerate(datasets):
        names = tuple(k for k in m if k in samples)
        if not names:
            raise ValueError(f"dataset {i} has none of the pooled parameters {', '.join(m)}")
        own = log_p0 is not None and log_p0[i] is not None
        n = int(jnp.shape(samples[names[0]])[0])
        groups.setdefault((names, n, i if own else -1), []).append(i)
    out = []
    for (names, _, own), members in groups.items():
        stacked = {k: jnp.stack([jnp.asarray(datasets[i][k]) for i in members]) for k in names}  # (D, N)
        # ψ gains one axis for the datasets; importance_log_weights adds the one of the draws
        m_d = {k: jnp.asarray(m[k])[..., None] for k in names}
        tau_d = {k: jnp.asarray(tau[k])[..., None] for k in names}
        group_p0 = jnp.asarray(log_p0[own])[None] if own >= 0 else None
        out.append((members, importance_log_weights(m_d, tau_d, stacked, bounds, group_p0, names=names)))
    return out


def staged_log_likelihood(m: Mapping[str, jax.Array], tau: Mapping[str, jax.Array],
                          datasets: Sequence[Mapping[str, jax.Array]], bounds: Mapping[str, tuple[float, float]],
                          log_p0: Sequence[jax.Array | None] | None = None):
    """Phase-2 log likelihood log L(ψ) = Σ_i [logsumexp_k (log p(θ_i^k | ψ) − log p0(θ_i^k)) − log N_i].

    Parameters
    ----------
    m, tau : mapping of str to array_like
        Pooled parameter name -> population mean / spread of batch shape B (scalars for one ψ).
    datasets : sequence of mapping of str to array_like
        ``datasets[i]`` maps parameter names to the (N_i,) phase-1 posterior samples of dataset i.
    bounds : mapping of str to (float, float)
        Prior range of each pooled parameter.
    log_p0 : sequence of (array_like or None) or None
        ``log_p0[i]`` overrides the uniform phase-1 prior of dataset i (see :func:`importance_log_weights`).

    Returns
    -------
    Array
        Shape B.
    """
    return sum_dataset_terms(dataset_terms(grouped_log_weights(m, tau, datasets, bounds, log_p0)))


def dataset_terms(groups: Sequence[tuple[Sequence[int], jax.Array]]) -> dict[int, jax.Array]:
    """Each dataset's term logsumexp_k log w_k − log N_i of log L(ψ), from :func:`grouped_log_weights`.

    Parameters
    ----------
    groups : sequence of (indices, log weights B + (D, N))

    Returns
    -------
    dict of int to Array
        Dataset index -> term of batch shape B.
    """
    terms = {}
    for members, lw in groups:
        t = logsumexp(lw, axis=-1) - math.log(lw.shape[-1])  # B + (D,)
        for j, i in enumerate(members):
            terms[i] = t[..., j]
    return terms


def sum_dataset_terms(terms: Mapping[int, jax.Array]):
    """Σ_i of the dataset terms in dataset order (the order of the sum fixes its round-off).

    Parameters
    ----------
    terms : mapping of int to Array
        Dataset index -> term of batch shape B (:func:`dataset_terms`).

    Returns
    -------
    Array
        log L(ψ) of batch shape B.
    """
    total = 0.0
    for i in sorted(terms):
        total = total + terms[i]
    return total


def importance_ess(log_weights, axis: int = -1):
    """Importance-sampling effective sample size (Σ w)² / Σ w² from log weights.

    Parameters
    ----------
    log_weights : array_like
        Unnormalised log weights.
    axis : int
        Axis of the samples.

    Returns
    -------
    Array
        ESS in draws (0 where every weight is 0).
    """
    lw = jnp.asarray(log_weights)
    a = logsumexp(lw, axis=axis)
    b = logsumexp(2.0 * lw, axis=axis)
    ess = jnp.exp(2.0 * a - b)
    return jnp.where(jnp.isfinite(ess), ess, 0.0)
