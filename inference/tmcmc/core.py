"""Pure TMCMC core (transitional MCMC, Ching & Chen 2007, and the Korali variant), BlackJAX-style.

Everything here works on flat particle arrays ``position`` of shape ``(N, d)`` given two functions of
one flat vector, ``log_prior_fn(x)`` and ``log_likelihood_fn(x)``; nothing here knows NumPyro (the
front end :class:`~bubblecal.inference.tmcmc.TMCMC` builds the two functions from a model). The
algorithm is ``docs/inference.md`` section 5. The pieces are pure and jittable:

- :func:`init` evaluates the prior draws and returns a :class:`TMCMCState` (β = 0, log Z = 0);
- :func:`step` runs one stage (next exponent by bisection on the CoV of the incremental weights,
  evidence increment, resampling, weighted covariance, move at the new exponent) and returns the new
  state and a :class:`StageInfo` record of scalars; it is :func:`prepare_stage`, the move, then
  :func:`finish_stage`;
- :func:`run` compiles the whole run into one ``lax.while_loop`` over stages and returns the final
  state plus the per-stage records stacked into arrays of length ``max_stages``.

The state and diagnostics types live in :mod:`bubblecal.inference.tmcmc.state`, the tempering
arithmetic in :mod:`bubblecal.inference.tmcmc.tempering`; the move is any
:class:`~bubblecal.inference.tmcmc.moves.Move`. Conventions: a particle whose log
likelihood is not finite gets weight exactly 0 (it never makes log Z NaN); proposals with a non-finite
prior or likelihood are rejected; ``num_evaluations`` counts likelihood evaluations of single particles
(a gradient evaluation counts as one).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax import lax

from bubblecal.inference.tmcmc.evaluator import Evaluator
from bubblecal.inference.tmcmc.moves import Move, MoveResult, RandomWalk
from bubblecal.inference.tmcmc.state import (
    STATUS_CONVERGED,
    STATUS_MAX_STAGES,
    STATUS_RUNNING,
    STATUS_STALLED,
    StageInfo,
    TMCMCConfig,
    TMCMCState,
    initial_state,
)
from bubblecal.inference.tmcmc.tempering import (
    normalised_log_weights,
    resample,
    solve_delta,
    weighted_moments,
)

Array = jax.Array

__all__ = ["StagePlan", "TMCMCAlgorithm", "init", "prepare_stage", "finish_stage", "step", "run", "tmcmc"]

def init(
    position: Array,
    log_prior_fn: Callable,
    log_likelihood_fn: Callable,
    move: Move,
    chunk_size: int | None = None,
) -> TMCMCState:
    """Initial state from exact prior draws: evaluates their densities; β = 0, log Z = 0.

    Parameters
    ----------
    position : Array
        (N, d) exact prior draws in the flat sampling space.
    log_prior_fn, log_likelihood_fn : callable
        Log prior (Jacobian included) and log likelihood of one flat vector (d,).
    move : Move
        The move (gives the initial move parameters).
    chunk_size : int or None
        Particles per evaluation chunk.

    Returns
    -------
    TMCMCState
    """
    position = jnp.asarray(position)
    lp, ll = Evaluator(log_prior_fn, log_likelihood_fn, chunk_size)(position)
    return initial_state(position, lp, ll, move)


class StagePlan(NamedTuple):
    """What a stage fixes before its move (:func:`prepare_stage`): exponent, weights, resampled particles."""

    key_move: Array  # key of the move
    position: Array  # (N, d) resampled particles
    log_prior: Array  # (N,)
    log_likelihood: Array  # (N,)
    beta: Array  # new exponent
    delta: Array  # its increment
    cov: Array  # achieved CoV of the incremental weights
    ess: Array
    log_z_increment: Array
    unique_fraction: Array
    weighted_cov: Array  # (d, d) weighted particle covariance Σ_w
    num_nonfinite: Array


def prepare_stage(rng_key: Array, state: TMCMCState, config: TMCMCConfig = TMCMCConfig()) -> StagePlan:
    """First half of a stage, without likelihood evaluations: exponent, log Z increment, resampling, Σ_w.

    Parameters
    ----------
    rng_key : Array
        PRNG key of the stage (split into the resampling key and :attr:`StagePlan.key_move`).
    state : TMCMCState
        State before the stage.
    config : TMCMCConfig
        Target CoV and resampling scheme.

    Returns
    -------
    StagePlan
    """
    n = state.position.shape[0]
    ll = state.log_likelihood
    num_nonfinite = jnp.sum(~jnp.isfinite(ll)).astype(jnp.int32)

    delta, cov = solve_delta(ll, state.beta, config.target_cov)
    full_step = delta >= 1.0 - state.beta
    beta = jnp.where(full_step, 1.0, jnp.minimum(state.beta + delta, 1.0)).astype(state.beta.dtype)
    delta = beta - state.beta

    log_w, log_z_inc = normalised_log_weights(delta, ll)
    ess = 1.0 / jnp.sum(jnp.exp(2.0 * log_w))

    k_res, k_move = jax.random.split(rng_key)
    idx = resample(k_res, log_w, config.resampling)
    unique_fraction = jnp.zeros(n, jnp.int32).at[idx].set(1).sum() / n
    _, wcov = weighted_moments(state.position, log_w)
    return StagePlan(
        key_move=k_move,
        position=state.position[idx],
        log_prior=state.log_prior[idx],
        log_likelihood=ll[idx],
        beta=beta,
        delta=delta,
        cov=cov,
        ess=ess,
        log_z_increment=log_z_inc,
        unique_fraction=unique_fraction,
        weighted_cov=wcov,
        num_nonfinite=num_nonfinite,
    )


def finish_stage(
    state: TMCMCState, plan: StagePlan, res: MoveResult, config: TMCMCConfig = TMCMCConfig()
) -> tuple[TMCMCState, StageInfo]:
    """Second half of a stage: the state after the move and the stage's diagnostics.

    Parameters
    ----------
    state : TMCMCState
        State before the stage.
    plan : StagePlan
        The stage's first half (:func:`prepare_stage`).
    res : MoveResult
        The move's result.
    config : TMCMCConfig
        Gives ``min_delta`` (the stall test).

    Returns
    -------
    state : TMCMCState
        State after the stage.
    info : StageInfo
        The stage's diagnostics, with its status code.
    """
    beta, delta = plan.beta, plan.delta
    log_evidence = state.log_evidence + plan.log_z_increment
    stalled = (delta < config.min_delta) & (beta < 1.0)
    status = jnp.where(
        beta >= 1.0, STATUS_CONVERGED, jnp.where(stalled, STATUS_STALLED, STATUS_RUNNING)
    ).astype(jnp.int32)
    new_state = TMCMCState(
        position=res.position,
        log_prior=res.log_prior,
        log_likelihood=res.log_likelihood,
        beta=beta,
        log_evidence=log_evidence,
        move_params=res.params.astype(state.move_params.dtype),
        stage=state.stage + 1,
        num_evaluations=state.num_evaluations + res.num_evaluations,
    )
    finite_ll = jnp.where(jnp.isfinite(res.log_likelihood), res.log_likelihood, -jnp.inf)
    info = StageInfo(
        beta=beta,
        delta=delta,
        cov=plan.cov,
        ess=plan.ess,
        log_z_increment=plan.log_z_increment,
        log_evidence=log_evidence,
        acceptance=res.acceptance,
        unique_fraction=plan.unique_fraction.astype(state.position.dtype),
        scale=res.scale,
        max_log_likelihood=jnp.max(finite_ll),
        num_nonfinite=plan.num_nonfinite,
        num_evaluations=res.num_evaluations,
        status=status,
    )
    return new_state, info


def step(
    rng_key: Array,
    state: TMCMCState,
    log_prior_fn: Callable,
    log_likelihood_fn: Callable,
    move: Move,
    config: TMCMCConfig = TMCMCConfig(),
) -> tuple[TMCMCState, StageInfo]:
    """One TMCMC stage: exponent, evidence increment, resampling, covariance, move at the new β.

    Parameters
    ----------
    rng_key : Array
        PRNG key of the stage.
    state : TMCMCState
        State before the stage.
    log_prior_fn, log_likelihood_fn : callable
        Log prior and log likelihood of one flat vector (d,).
    move : Move
        The mutation kernel.
    config : TMCMCConfig
        Static settings.

    Returns
    -------
    state : TMCMCState
    info : StageInfo
    """
    evaluate = Evaluator(log_prior_fn, log_likelihood_fn, config.chunk_size)
    plan = prepare_stage(rng_key, state, config)
    res = move(
        plan.key_move,
        plan.position,
        plan.log_prior,
        plan.log_likelihood,
        plan.beta,
        plan.weighted_cov,
        state.move_params,
        evaluate,
    )
    return finish_stage(state, plan, res, config)


def _empty_infos(max_stages: int, dtype) -> StageInfo:
    """Stage records of a whole run before it starts (NaN floats, zero ints)."""
    f = jnp.full((max_stages,), jnp.nan, dtype)
    i = jnp.zeros((max_stages,), jnp.int32)
    return StageInfo(f, f, f, f, f, f, f, f, f, f, i, i, i)


def run(
    rng_key: Array,
    state: TMCMCState,
    log_prior_fn: Callable,
    log_likelihood_fn: Callable,
    move: Move,
    config: TMCMCConfig = TMCMCConfig(),
    max_stages: int = 200,
) -> tuple[TMCMCState, StageInfo, Array]:
    """The whole run as one ``lax.while_loop`` (jit it; β is traced, nothing returns to the host).

    Parameters
    ----------
    rng_key : Array
        PRNG key of the run (split once per stage).
    state : TMCMCState
        Initial state (:func:`init`).
    log_prior_fn, log_likelihood_fn : callable
        Log prior and log likelihood of one flat vector (d,).
    move : Move
        The mutation kernel.
    config : TMCMCConfig
        Static settings.
    max_stages : int
        Stage cap.

    Returns
    -------
    final_state : TMCMCState
    infos : StageInfo
        Arrays of length ``max_stages``; rows past ``final_state.stage`` are NaN (floats) or 0 (ints).
    status : Array
        One of the ``STATUS_*`` codes (converged, max_stages or stalled).
    """
    infos0 = _empty_infos(max_stages, state.position.dtype)

    def cond(carry):
        _, st, _, status = carry
        return (status == STATUS_RUNNING) & (st.stage < max_stages)

    def body(carry):
        key, st, infos, _ = carry
        key, sub = jax.random.split(key)
        new, info = step(sub, st, log_prior_fn, log_likelihood_fn, move, config)
        infos = jax.tree_util.tree_map(lambda a, v: a.at[st.stage].set(v.astype(a.dtype)), infos, info)
        return key, new, infos, info.status

    _, final, infos, status = lax.while_loop(
        cond, body, (rng_key, state, infos0, jnp.asarray(STATUS_RUNNING, jnp.int32))
    )
    status = jnp.where(status == STATUS_RUNNING, STATUS_MAX_STAGES, status)
    return final, infos, status


class TMCMCAlgorithm(NamedTuple):
    """``init``/``step``/``run`` closed over the two log densities (like a BlackJAX SamplingAlgorithm)."""

    init: Callable
    step: Callable
    run: Callable


def tmcmc(
    log_prior_fn: Callable,
    log_likelihood_fn: Callable,
    move: Move | None = None,
    config: TMCMCConfig = TMCMCConfig(),
    max_stages: int = 200,
) -> TMCMCAlgorithm:
    """Bind the densities, move and settings into ``init`` / ``step`` / ``run`` of the core.

    Parameters
    ----------
    log_prior_fn, log_likelihood_fn : callable
        Log prior and log likelihood of one flat vector (d,).
    move : Move or None
        The mutation kernel (default :class:`RandomWalk` with its defaults).
    config : TMCMCConfig
        Static settings.
    max_stages : int
        Stage cap of ``run``.

    Returns
    -------
    TMCMCAlgorithm
        ``alg.init(position)``, ``alg.step(key, state)``, ``alg.run(key, state)``.
    """
    move = RandomWalk() if move is None else move

    def _init(position):
        return init(position, log_prior_fn, log_likelihood_fn, move, config.chunk_size)

    def _step(rng_key, state):
        return step(rng_key, state, log_prior_fn, log_likelihood_fn, move, config)

    def _run(rng_key, state):
        return run(rng_key, state, log_prior_fn, log_likelihood_fn, move, config, max_stages)

    return TMCMCAlgorithm(_init, _step, _run)
