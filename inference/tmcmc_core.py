"""Pure TMCMC core (transitional MCMC, Ching & Chen 2007, and the Korali variant), BlackJAX-style.

Everything here works on flat particle arrays ``position`` of shape ``(N, d)`` given two functions of
one flat vector: ``log_prior_fn(x)`` and ``log_likelihood_fn(x)``.  Nothing here knows NumPyro; the
front end in :mod:`bubblecal.inference.tmcmc` builds the two functions from a model.

The pieces are pure and jittable:

- :func:`init` evaluates the prior draws and returns a :class:`TMCMCState` (β = 0, log Z = 0);
- :func:`step` runs one stage (next exponent by bisection on the CoV of the incremental weights,
  evidence increment, resampling, weighted covariance, move at the new exponent) and returns the new
  state and a :class:`StageInfo` record of scalars;
- :func:`run` compiles the whole run into one ``lax.while_loop`` over stages and returns the final
  state plus the per-stage records stacked into arrays of length ``max_stages``.

A *move* (the mutation kernel) is any object with ``init_params(dim) -> Array`` (the adapted move
parameters, e.g. the random-walk scale, carried in the state) and
``__call__(rng_key, position, log_prior, log_likelihood, beta, cov, params, evaluate) -> MoveResult``.
:class:`RandomWalk` ships here; NumPyro HMC/NUTS moves are in :mod:`bubblecal.inference.moves`.

Conventions: a particle whose log likelihood is not finite gets weight exactly 0 (it never makes log Z
NaN); proposals with a non-finite prior or likelihood are rejected.  ``num_evaluations`` counts
likelihood evaluations of single particles (a gradient evaluation counts as one).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
from jax import lax

Array = jax.Array

STATUS_RUNNING = 0
STATUS_CONVERGED = 1
STATUS_MAX_STAGES = 2
STATUS_STALLED = 3
STATUS_NAMES = {
    STATUS_RUNNING: "running",
    STATUS_CONVERGED: "converged",
    STATUS_MAX_STAGES: "max_stages",
    STATUS_STALLED: "stalled",
}

_BISECTION_ITERS = 60


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
    """Scalar diagnostics of one stage (stacked into arrays by :func:`run`)."""

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


class MoveResult(NamedTuple):
    position: Array
    log_prior: Array
    log_likelihood: Array
    acceptance: Array  # () mean acceptance
    num_evaluations: Array  # () int32
    params: Array  # adapted move parameters for the next stage
    scale: Array  # () the scale actually used, for the stage table


# ---------------------------------------------------------------------------------------------
# Evaluation (chunked)
# ---------------------------------------------------------------------------------------------


def make_evaluator(
    log_prior_fn: Callable[[Array], Array],
    log_likelihood_fn: Callable[[Array], Array],
    chunk_size: int | None = None,
) -> Callable[[Array], tuple[Array, Array]]:
    """Return ``evaluate(position) -> (log_prior, log_likelihood)`` over a ``(N, d)`` array.

    With ``chunk_size`` the particles are evaluated ``chunk_size`` at a time (``lax.map`` over chunks
    of a vmapped evaluation), so memory scales with the chunk, not with N.
    """

    def one(x):
        return jnp.asarray(log_prior_fn(x)), jnp.asarray(log_likelihood_fn(x))

    def evaluate(position):
        n = position.shape[0]
        if chunk_size is None or chunk_size >= n:
            return jax.vmap(one)(position)
        return lax.map(one, position, batch_size=int(chunk_size))

    # moves that need per-particle densities (gradient moves) find them here
    evaluate.one = one
    evaluate.log_prior_fn = log_prior_fn
    evaluate.log_likelihood_fn = log_likelihood_fn
    evaluate.chunk_size = chunk_size
    return evaluate


def chunked_vmap(fn: Callable, chunk_size: int | None) -> Callable:
    """vmap ``fn`` over the leading axis of its (pytree) argument, ``chunk_size`` at a time."""

    def mapped(xs):
        n = jax.tree_util.tree_leaves(xs)[0].shape[0]
        if chunk_size is None or chunk_size >= n:
            return jax.vmap(fn)(xs)
        return lax.map(fn, xs, batch_size=int(chunk_size))

    return mapped


def tempered(log_prior: Array, log_likelihood: Array, beta: Array) -> Array:
    """log prior + β log L, −∞ wherever either term is not finite (so such proposals are rejected)."""
    ok = jnp.isfinite(log_prior) & jnp.isfinite(log_likelihood)
    return jnp.where(ok, log_prior + beta * jnp.where(ok, log_likelihood, 0.0), -jnp.inf)


# ---------------------------------------------------------------------------------------------
# Exponent, weights, resampling, covariance
# ---------------------------------------------------------------------------------------------


def weights_cov(delta: Array, log_likelihood: Array) -> Array:
    """CoV (std with ddof 1 over mean) of w_i = exp(Δ·L_i) over the particles with finite L."""
    finite = jnp.isfinite(log_likelihood)
    n = jnp.maximum(finite.sum(), 2)
    ll = jnp.where(finite, log_likelihood, 0.0)
    llmax = jnp.max(jnp.where(finite, log_likelihood, -jnp.inf))
    w = jnp.where(finite, jnp.exp(delta * (ll - llmax)), 0.0)
    mean = w.sum() / n
    var = jnp.where(finite, (w - mean) ** 2, 0.0).sum() / (n - 1)
    return jnp.sqrt(var) / mean


def solve_delta(log_likelihood: Array, beta: Array, target_cov: float) -> tuple[Array, Array]:
    """Increment Δ in [0, 1 − β] with CoV(exp(Δ L)) = target (bracketed bisection); (Δ, achieved CoV).

    CoV grows monotonically with Δ, so if the full step 1 − β stays under the target it is taken.
    The bisection runs in log Δ over [1e-30·(1−β) .. 1−β] so tiny increments keep relative precision.
    """
    dmax = 1.0 - beta

    def body(_, bounds):
        lo, hi = bounds
        mid = 0.5 * (lo + hi)
        too_big = weights_cov(jnp.exp(mid), log_likelihood) > target_cov
        return jnp.where(too_big, lo, mid), jnp.where(too_big, mid, hi)

    # lo stays on the side CoV ≤ target, so Δ never overshoots the target
    log_dmax = jnp.log(dmax)
    lo, _ = lax.fori_loop(0, _BISECTION_ITERS, body, (log_dmax - 69.0, log_dmax))  # 69 ≈ log 1e30
    delta = jnp.where(weights_cov(dmax, log_likelihood) <= target_cov, dmax, jnp.exp(lo))
    return delta, weights_cov(delta, log_likelihood)


def normalised_log_weights(delta: Array, log_likelihood: Array) -> tuple[Array, Array]:
    """(log ŵ normalised, log Z increment = logsumexp(Δ L) − log N); non-finite L gets weight 0."""
    n = log_likelihood.shape[0]
    logw = jnp.where(jnp.isfinite(log_likelihood), delta * log_likelihood, -jnp.inf)
    lse = jax.scipy.special.logsumexp(logw)
    return logw - lse, lse - math.log(n)


def resample(rng_key: Array, log_weights: Array, method: str) -> Array:
    """N indices drawn from normalised weights: 'multinomial' (Korali) or 'systematic'."""
    n = log_weights.shape[0]
    w = jnp.exp(log_weights)
    cdf = jnp.cumsum(w)
    cdf = cdf / cdf[-1]
    if method == "multinomial":
        u = jax.random.uniform(rng_key, (n,), dtype=cdf.dtype)
    elif method == "systematic":
        u = (jax.random.uniform(rng_key, (), dtype=cdf.dtype) + jnp.arange(n, dtype=cdf.dtype)) / n
    else:  # pragma: no cover - validated by the front end
        raise ValueError(f"unknown resampling method {method!r}")
    idx = jnp.searchsorted(cdf, u, side="right")
    # never select a zero-weight particle because of round-off at the top of the cdf
    return jnp.minimum(idx, n - 1)


def weighted_moments(position: Array, log_weights: Array) -> tuple[Array, Array]:
    """Weighted mean and covariance Σ_i ŵ_i (x_i − μ)(x_i − μ)ᵀ (Korali's, no ddof correction)."""
    w = jnp.exp(log_weights)
    mean = w @ position
    centred = position - mean
    cov = (centred * w[:, None]).T @ centred
    return mean, 0.5 * (cov + cov.T)


def safe_cholesky(cov: Array) -> Array:
    """Cholesky factor of ``cov`` with a relative jitter; falls back to the diagonal if it fails."""
    d = cov.shape[0]
    diag = jnp.clip(jnp.diag(cov), 1e-30)
    eps = 1e-10 if cov.dtype == jnp.float64 else 1e-6
    chol = jnp.linalg.cholesky(cov + eps * jnp.diag(diag) + 1e-30 * jnp.eye(d, dtype=cov.dtype))
    return jnp.where(jnp.all(jnp.isfinite(chol)), chol, jnp.diag(jnp.sqrt(diag)))


# ---------------------------------------------------------------------------------------------
# Random-walk Metropolis move (fused: every step is one chunked evaluation of all particles)
# ---------------------------------------------------------------------------------------------


class RandomWalk(NamedTuple):
    """Random-walk Metropolis from the resampled particles, proposal N(x, s² Σ_w).

    ``num_steps`` MH steps per stage.  With ``adapt=True`` the log scale moves toward
    ``target_accept`` after every step from the population acceptance (carried across stages); with
    ``adapt=False`` s² stays at ``init_scale2`` (Korali: one step, s² = 0.04).
    """

    num_steps: int = 10
    init_scale2: float = 0.04
    adapt: bool = True
    target_accept: float = 0.3
    adapt_rate: float = 1.5
    name: str = "rw"

    def init_params(self, dim: int) -> Array:
        return jnp.array([0.5 * math.log(self.init_scale2)])

    # The stage's move is split into start / propose / accept / result so that a host-driven stage
    # (bubblecal.inference.tmcmc) can compile these model-free pieces once and call the model's
    # evaluator between them; __call__ runs the same pieces fused in one fori_loop.

    def start(self, cov: Array, params: Array) -> tuple[Array, Array]:
        """(Cholesky factor of the weighted covariance Σ_w, log s) at the start of a stage."""
        return safe_cholesky(cov), params[0]

    def propose(self, key: Array, x: Array, chol: Array, log_s: Array) -> tuple[Array, Array, Array]:
        """(next key, acceptance key, proposal x + s z Lᵀ with z ~ N(0, I)) for one MH step."""
        key, k_prop, k_acc = jax.random.split(key, 3)
        z = jax.random.normal(k_prop, x.shape, dtype=x.dtype)
        return key, k_acc, x + jnp.exp(log_s) * (z @ chol.T)

    def accept(self, k_acc: Array, carry: tuple, prop: Array, lp_p: Array, ll_p: Array, beta: Array) -> tuple:
        """Metropolis accept/reject of ``prop`` at exponent β; ``carry`` = (x, lp, ll, log s, Σ acceptance)."""
        x, lp, ll, log_s, acc_sum = carry
        log_alpha = tempered(lp_p, ll_p, beta) - tempered(lp, ll, beta)
        log_alpha = jnp.where(jnp.isnan(log_alpha), -jnp.inf, log_alpha)
        accept = jnp.log(jax.random.uniform(k_acc, (x.shape[0],), dtype=x.dtype)) < log_alpha
        x = jnp.where(accept[:, None], prop, x)
        lp = jnp.where(accept, lp_p, lp)
        ll = jnp.where(accept, ll_p, ll)
        rate = accept.mean()
        if self.adapt:
            log_s = log_s + self.adapt_rate * (rate - self.target_accept)
        return x, lp, ll, log_s, acc_sum + rate

    def result(self, carry: tuple, log_s0: Array) -> MoveResult:
        """The :class:`MoveResult` after ``num_steps`` steps (``log_s0``: the scale the stage started with)."""
        x, lp, ll, log_s_new, acc_sum = carry
        return MoveResult(
            position=x,
            log_prior=lp,
            log_likelihood=ll,
            acceptance=acc_sum / self.num_steps,
            num_evaluations=jnp.asarray(x.shape[0] * self.num_steps, jnp.int32),
            params=jnp.reshape(log_s_new, (1,)),
            scale=jnp.exp(log_s0),
        )

    def __call__(self, rng_key, position, log_prior, log_likelihood, beta, cov, params, evaluate):
        chol, log_s = self.start(cov, params)

        def body(i, carry):
            key, rest = carry
            key, k_acc, prop = self.propose(key, rest[0], chol, rest[3])
            lp_p, ll_p = evaluate(prop)
            return key, self.accept(k_acc, rest, prop, lp_p, ll_p, beta)

        init = (rng_key, (position, log_prior, log_likelihood, log_s, jnp.zeros((), position.dtype)))
        _, carry = lax.fori_loop(0, self.num_steps, body, init)
        return self.result(carry, log_s)


# ---------------------------------------------------------------------------------------------
# init / step / run
# ---------------------------------------------------------------------------------------------


class TMCMCConfig(NamedTuple):
    """Static settings of the core (hashable; everything here is fixed at compile time)."""

    target_cov: float = 0.8
    resampling: str = "systematic"
    min_delta: float = 1e-9
    chunk_size: int | None = None


def initial_state(position: Array, log_prior: Array, log_likelihood: Array, move: Any) -> TMCMCState:
    """State at β = 0 (log Z = 0) from the prior draws ``position`` (N, d) and their densities."""
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


def init(
    position: Array,
    log_prior_fn: Callable,
    log_likelihood_fn: Callable,
    move: Any,
    chunk_size: int | None = None,
) -> TMCMCState:
    """Initial state from exact prior draws ``position`` (N, d): β = 0, log Z = 0."""
    position = jnp.asarray(position)
    lp, ll = make_evaluator(log_prior_fn, log_likelihood_fn, chunk_size)(position)
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
    """First half of a stage (no likelihood evaluation): next exponent, log Z increment, resampling, Σ_w."""
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
    """Second half of a stage: the new state after the move ``res`` and the stage's :class:`StageInfo`."""
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
    move: Any,
    config: TMCMCConfig = TMCMCConfig(),
) -> tuple[TMCMCState, StageInfo]:
    """One TMCMC stage: exponent, evidence increment, resampling, covariance, move at the new β."""
    evaluate = make_evaluator(log_prior_fn, log_likelihood_fn, config.chunk_size)
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
    f = jnp.full((max_stages,), jnp.nan, dtype)
    i = jnp.zeros((max_stages,), jnp.int32)
    return StageInfo(f, f, f, f, f, f, f, f, f, f, i, i, i)


def run(
    rng_key: Array,
    state: TMCMCState,
    log_prior_fn: Callable,
    log_likelihood_fn: Callable,
    move: Any,
    config: TMCMCConfig = TMCMCConfig(),
    max_stages: int = 200,
) -> tuple[TMCMCState, StageInfo, Array]:
    """The whole run as one ``lax.while_loop`` (jit it; β is traced, nothing returns to the host).

    Returns ``(final_state, infos, status)`` where ``infos`` holds arrays of length ``max_stages``
    (rows past ``final_state.stage`` are NaN/0) and ``status`` is one of the ``STATUS_*`` codes.
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
    move: Any | None = None,
    config: TMCMCConfig = TMCMCConfig(),
    max_stages: int = 200,
) -> TMCMCAlgorithm:
    """Bind the densities, move and settings: ``alg.init(position)``, ``alg.step(key, state)``, ``alg.run(key, state)``."""
    move = RandomWalk() if move is None else move

    def _init(position):
        return init(position, log_prior_fn, log_likelihood_fn, move, config.chunk_size)

    def _step(rng_key, state):
        return step(rng_key, state, log_prior_fn, log_likelihood_fn, move, config)

    def _run(rng_key, state):
        return run(rng_key, state, log_prior_fn, log_likelihood_fn, move, config, max_stages)

    return TMCMCAlgorithm(_init, _step, _run)
