"""State and diagnostics of a TMCMC run, its static settings and status codes.

The data types of the core (:mod:`bubblecal.inference.tmcmc.core`): a run carries a
:class:`TMCMCState`, each stage produces a :class:`StageInfo`, and :class:`TMCMCConfig` holds the settings
fixed at compile time.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from bubblecal.inference.tmcmc.moves import Move

Array = jax.Array

__all__ = [
    "STATUS_RUNNING", "STATUS_CONVERGED", "STATUS_MAX_STAGES", "STATUS_STALLED", "STATUS_NAMES", "TMCMCState",
    "StageInfo", "TMCMCConfig", "initial_state",
]

STATUS_RUNNING = 0
STATUS_CONVERGED = 1
STATUS_MAX_STAGES = 2
STATUS_STALLED = 3
#: Name of each status code (what :attr:`TMCMC.status <bubblecal.inference.tmcmc.TMCMC.status>` reports).
STATUS_NAMES = {
    STATUS_RUNNING: "running",
    STATUS_CONVERGED: "converged",
    STATUS_MAX_STAGES: "max_stages",
    STATUS_STALLED: "stalled",
}


class TMCMCState(NamedTuple):
    """State of a TMCMC run: the particle population at exponent ``beta``."""

    position: Array  # (N, d)
    log_prior: Array  # (N,)  log prior density in the space of ``position`` (incl. any Jacobian)
    log_likelihood: Array  # (N,)
    beta: Array  # ()
    log_evidence: Array  # ()  running total of the log Z increments
    move_params: Array  # (p,)  adapted move parameters (e.g. log proposal scale)
    stage: Array  # () int32, number of completed stages
    num_evaluations: Array  # () int32, likelihood evaluations so far (incl. the prior draws)


class StageInfo(NamedTuple):
    """Scalar diagnostics of one stage (stacked into arrays by :func:`~bubblecal.inference.tmcmc.core.run`)."""

    beta: Array  # exponent after the stage
    delta: Array  # its increment
    cov: Array  # achieved coefficient of variation of the incremental weights
    ess: Array  # effective sample size of the incremental weights (particles, not a fraction)
    log_z_increment: Array
    log_evidence: Array  # running total after the stage
    acceptance: Array  # mean acceptance of the move
    unique_fraction: Array  # distinct particles after resampling / N
    scale: Array  # proposal scale used (random walk: s with Σ = s² Σ_w; HMC: step size)
    max_log_likelihood: Array  # over the particles after the move
    num_nonfinite: Array  # particles with a non-finite log likelihood before resampling
    num_evaluations: Array  # likelihood evaluations in this stage
    status: Array  # STATUS_* after the stage


class TMCMCConfig(NamedTuple):
    """Static settings of the core (hashable; everything here is fixed at compile time).

    Parameters
    ----------
    target_cov : float
        Target coefficient of variation c* of the incremental weights (ESS/N ≈ 1/(1 + c*²)).
    resampling : {'systematic', 'multinomial'}
        Resampling scheme (Korali: multinomial).
    min_delta : float
        A stage with Δ below this (and β < 1) ends the run with status 'stalled'.
    chunk_size : int or None
        Evaluate the densities this many particles at a time (see :class:`Evaluator`).
    """

    target_cov: float = 0.8
    resampling: str = "systematic"
    min_delta: float = 1e-9
    chunk_size: int | None = None


def initial_state(position: Array, log_prior: Array, log_likelihood: Array, move: Move) -> TMCMCState:
    """State at β = 0 (log Z = 0) from prior draws whose densities are already known.

    Parameters
    ----------
    position : Array
        (N, d) exact prior draws in the flat sampling space.
    log_prior, log_likelihood : Array
        (N,) their log prior and log likelihood.
    move : Move
        The move (gives the initial :attr:`TMCMCState.move_params`).

    Returns
    -------
    TMCMCState
    """
    n, d = position.shape
    return TMCMCState(
        position=position,
        log_prior=log_prior,
        log_likelihood=log_likelihood,
        beta=jnp.zeros((), position.dtype),
        log_evidence=jnp.zeros((), position.dtype),
        move_params=jnp.asarray(move.init_params(d), position.dtype),
        stage=jnp.zeros((), jnp.int32),
        num_evaluations=jnp.asarray(n, jnp.int32),
    )


def _check_int(name, value, minimum):
    """``value`` as an int >= ``minimum``, else ValueError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value}")
    return int(value)


def _check_positive(name, value):
    """``value`` as a positive finite float, else ValueError naming ``name``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return v
