"""The log likelihood of a model at a few exact prior draws: the cheap check a sampler's first stage relies on.

Each draw is one eager trace of the model (the latent sites drawn from their priors, the observed sites
scored at those values), so no whole program is compiled for it (only its operations, once per shape: pad
curves to one length, :func:`~bubblecal.models.pad_curve`, to share them): a quick check of any model. The
calibration's preflight (:mod:`bubblecal.workflows.calibrate.preflight`) evaluates its draws with phase 1's
compiled programs instead, which the run needs anyway.
"""

from __future__ import annotations

from collections.abc import Callable

import jax.numpy as jnp
import numpy as np
from numpyro import handlers

__all__ = ["prior_draw_log_likelihoods"]


def prior_draw_log_likelihoods(model: Callable, args: tuple = (), kwargs: dict | None = None, num_draws: int = 4,
                               seed: int = 0) -> np.ndarray:
    """Total log likelihood (every observed site) of ``model`` at ``num_draws`` prior draws.

    Parameters
    ----------
    model : callable
        A NumPyro model whose observed sites carry data (e.g. :func:`~bubblecal.models.mechanical_model`).
    args, kwargs : tuple, dict
        The model's arguments.
    num_draws : int
        Prior draws (draw k is traced with seed ``seed + k``).
    seed : int
        Seed of the first draw.

    Returns
    -------
    numpy.ndarray
        Shape (num_draws,): the summed log density of the observed sites at each draw (masked points add
        nothing); NaN or ±inf where the likelihood is not finite.
    """
    kwargs = kwargs or {}
    out = np.empty(num_draws)
    for k in range(num_draws):
        out[k] = _one_draw(model, args, kwargs, seed + k)
    return out


def _one_draw(model: Callable, args: tuple, kwargs: dict, seed: int) -> float:
    """Summed log density of the observed sites of one prior draw (traced with ``seed``)."""
    trace = handlers.trace(handlers.seed(model, rng_seed=seed)).get_trace(*args, **kwargs)
    total = 0.0
    for site in trace.values():
        if site["type"] != "sample" or not site["is_observed"]:
            continue
        log_prob = site["fn"].log_prob(site["value"])
        if site.get("mask") is not None:
            log_prob = jnp.where(site["mask"], log_prob, 0.0)
        total += float(jnp.sum(log_prob))
    return total

