"""TMCMC moves (the mutation kernel of a stage): the :class:`Move` interface and its implementations.

A move takes the resampled particles of a stage to the new tempered target p(x) L(x)^β
(``docs/inference.md`` section 5, step 5) and adapts its own parameters (a log scale or log step size,
carried in :attr:`~bubblecal.inference.tmcmc.TMCMCState.move_params` from stage to stage).

- :class:`RandomWalk`: random-walk Metropolis from N(x, s² Σ_w) with Σ_w the weighted particle
  covariance; every step is one (chunked) evaluation of all particles;
- :class:`KernelMove`: any NumPyro ``MCMCKernel`` run at the tempered potential, one short chain per
  particle (vmapped, or chunked with ``lax.map``); :func:`hmc_move` and :func:`nuts_move` build the
  two gradient moves from NumPyro's ``HMC``/``NUTS``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple, Protocol

import jax
import jax.numpy as jnp
from jax import lax
from numpyro.infer import HMC, NUTS

from bubblecal.inference.tmcmc.evaluator import Evaluator, chunked_vmap
from bubblecal.inference.tmcmc.tempering import safe_cholesky, tempered

Array = jax.Array

__all__ = ["Move", "MoveResult", "RandomWalk", "KernelMove", "hmc_move", "nuts_move"]


class MoveResult(NamedTuple):
    """What a move returns: the moved particles, their densities and the move's diagnostics."""

    position: Array  # (N, d) particles after the move
    log_prior: Array  # (N,)
    log_likelihood: Array  # (N,)
    acceptance: Array  # () mean acceptance
    num_evaluations: Array  # () int32, likelihood evaluations of single particles
    params: Array  # (p,) adapted move parameters for the next stage
    scale: Array  # () the scale actually used, for the stage table


class Move(Protocol):
    """Interface of a TMCMC move (structural: :class:`RandomWalk` and :class:`KernelMove` conform).

    A move is called inside the compiled stage, so ``__call__`` must be jittable; the move object
    itself is static (part of the compiled programs' cache keys, see :func:`clear_program_cache`).
    """

    @property
    def name(self) -> str:
        """Short label of the move (e.g. 'rw', 'hmc')."""

    @property
    def num_steps(self) -> int:
        """Transitions (MH steps or kernel steps) per particle and stage."""

    def init_params(self, dim: int) -> Array:
        """Initial adapted parameters (p,) for particles of dimension ``dim``."""

    def __call__(self, rng_key: Array, position: Array, log_prior: Array, log_likelihood: Array, beta: Array,
                 cov: Array, params: Array, evaluate: Evaluator) -> MoveResult:
        """Move the particles ``position`` (N, d) at exponent ``beta``.

        Parameters
        ----------
        rng_key : Array
            JAX PRNG key of the move.
        position, log_prior, log_likelihood : Array
            (N, d) resampled particles and their (N,) log prior / log likelihood.
        beta : Array
            The stage's new exponent.
        cov : Array
            (d, d) weighted particle covariance Σ_w of the stage.
        params : Array
            (p,) adapted move parameters from the previous stage.
        evaluate : Evaluator
            The densities of the model over the particles.

        Returns
        -------
        MoveResult
        """


class RandomWalk(NamedTuple):
    """Random-walk Metropolis from the resampled particles, proposal N(x, s² Σ_w).

    Parameters
    ----------
    num_steps : int
        MH steps per stage (default 10).
    init_scale2 : float
        Starting s² (Korali: 0.04).
    adapt : bool
        Move log s toward ``target_accept`` after every step from the population acceptance (carried
        across stages); False keeps s² at ``init_scale2`` (Korali: one step, s² = 0.04).
    target_accept : float
        Target mean acceptance of the adaptation.
    adapt_rate : float
        Gain of the adaptation: log s += adapt_rate · (acceptance − target_accept).
    name : str
        Label.

    Notes
    -----
    The stage's move is split into :meth:`start` / :meth:`propose` / :meth:`accept` / :meth:`result`
    so that a host-driven stage can compile these model-free pieces once and call the model's
    evaluator between them; :meth:`__call__` runs the same pieces fused in one ``fori_loop``.
    """

    num_steps: int = 10
    init_scale2: float = 0.04
    adapt: bool = True
    target_accept: float = 0.3
    adapt_rate: float = 1.5
    name: str = "rw"

    def init_params(self, dim: int) -> Array:
        """``[log s]`` with s² = ``init_scale2``."""
        return jnp.array([0.5 * math.log(self.init_scale2)])

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

    def __call__(self, rng_key, position, log_prior, log_likelihood, beta, cov, params, evaluate) -> MoveResult:
        """``num_steps`` MH steps of every particle (the :class:`Move` call)."""
        chol, log_s = self.start(cov, params)

        def body(i, carry):
            key, rest = carry
            key, k_acc, prop = self.propose(key, rest[0], chol, rest[3])
            lp_p, ll_p = evaluate(prop)
            return key, self.accept(k_acc, rest, prop, lp_p, ll_p, beta)

        init = (rng_key, (position, log_prior, log_likelihood, log_s, jnp.zeros((), position.dtype)))
        _, carry = lax.fori_loop(0, self.num_steps, body, init)
        return self.result(carry, log_s)


class KernelMove:
    """Mutation by a NumPyro ``MCMCKernel`` at the tempered potential −(log p(x) + β log L(x)).

    Every particle runs a short chain of ``num_steps`` transitions of the kernel built for the stage;
    the chains of all particles are one vmapped (or chunked ``lax.map``) computation inside the
    compiled stage. The inverse mass matrix is the stage's weighted particle covariance. Between
    stages the step size moves toward ``target_accept`` from the population's mean acceptance; for
    kernels whose state carries ``adapt_state.step_size`` (HMC, NUTS) it also moves between the
    transitions of a stage (all particles share it).

    Parameters
    ----------
    factory : callable
        ``factory(potential_fn, step_size, inverse_mass_matrix) -> MCMCKernel``. The kernel must accept
        a flat array as ``init_params``; if its state has ``accept_prob`` / ``num_steps`` fields (HMC,
        NUTS) they feed the acceptance and the evaluation count (leapfrog steps = gradient evaluations).
    num_steps : int
        Kernel transitions per particle and stage (>= 1).
    init_step_size : float or None
        Starting step size; None uses d^(-1/4) for particles of dimension d.
    target_accept : float
        Target mean acceptance, in (0, 1).
    adapt_step_size : bool
        Adapt the step size (within and between stages).
    adapt_rate : float
        Gain of the adaptation: log ε += adapt_rate · (acceptance − target_accept).
    chunk_size : int or None
        Particles per chunk of the vmapped chains (None: the evaluator's chunk size).
    name : str
        Label.

    Raises
    ------
    ValueError
        If ``num_steps`` < 1 or ``target_accept`` is outside (0, 1).
    """

    def __init__(
        self,
        factory: Callable,
        num_steps: int = 1,
        init_step_size: float | None = None,
        target_accept: float = 0.8,
        adapt_step_size: bool = True,
        adapt_rate: float = 2.0,
        chunk_size: int | None = None,
        name: str = "kernel",
    ):
        if num_steps < 1:
            raise ValueError(f"num_steps must be >= 1, got {num_steps}")
        if not 0.0 < target_accept < 1.0:
            raise ValueError(f"target_accept must be in (0, 1), got {target_accept}")
        self.factory = factory
        self.num_steps = int(num_steps)
        self.init_step_size = init_step_size
        self.target_accept = float(target_accept)
        self.adapt_step_size = adapt_step_size
        self.adapt_rate = float(adapt_rate)
        self.chunk_size = chunk_size
        self.name = name

    def init_params(self, dim: int) -> Array:
        """``[log ε]``: the starting step size, ``init_step_size`` or d^(-1/4)."""
        eps = self.init_step_size if self.init_step_size is not None else 1.0 / dim**0.25
        return jnp.array([math.log(eps)])

    def __call__(self, rng_key, position, log_prior, log_likelihood, beta, cov, params, evaluate) -> MoveResult:
        """``num_steps`` kernel transitions of every particle (the :class:`Move` call)."""
        n = position.shape[0]
        step_size = jnp.exp(params[0])
        one = evaluate.one

        def potential_fn(x):
            lp, ll = one(x)
            return -tempered(lp, ll, beta)

        # a little relative jitter keeps the mass matrix positive definite after heavy resampling
        cov = cov + 1e-6 * jnp.diag(jnp.diag(cov))
        kernel = self.factory(potential_fn, step_size, cov)
        field = getattr(kernel, "sample_field", "z")
        chunk = self.chunk_size if self.chunk_size is not None else evaluate.chunk_size
        keys = jax.random.split(rng_key, n)
        states = chunked_vmap(lambda a: kernel.init(a[0], 0, a[1], (), {}), chunk)((keys, position))
        sample = chunked_vmap(lambda st: kernel.sample(st, (), {}), chunk)
        tunable = hasattr(states, "adapt_state") and hasattr(states.adapt_state, "step_size")

        def body(_, carry):
            # one transition of every particle, then (HMC/NUTS) the step size of all particles moves
            # toward the target acceptance from the population's mean acceptance
            states, log_eps, acc, nev = carry
            states = sample(states)
            rate = jnp.mean(getattr(states, "accept_prob", jnp.full((n,), jnp.nan)))
            nev = nev + jnp.sum(jnp.asarray(getattr(states, "num_steps", jnp.ones((n,))), jnp.int32))
            if self.adapt_step_size and tunable:
                log_eps = log_eps + self.adapt_rate * (jnp.nan_to_num(rate) - self.target_accept)
                eps = jnp.broadcast_to(jnp.exp(log_eps), states.adapt_state.step_size.shape)
                states = states._replace(
                    adapt_state=states.adapt_state._replace(
                        step_size=eps.astype(states.adapt_state.step_size.dtype)
                    )
                )
            return states, log_eps, acc + rate, nev

        states, new_log_eps, acc, nev = lax.fori_loop(
            0,
            self.num_steps,
            body,
            (states, params[0], jnp.zeros((), position.dtype), jnp.asarray(n, jnp.int32)),
        )
        x = getattr(states, field)
        mean_acc = acc / self.num_steps
        if self.adapt_step_size and not tunable:
            new_log_eps = params[0] + self.adapt_rate * (jnp.nan_to_num(mean_acc) - self.target_accept)
        lp, ll = evaluate(x)
        return MoveResult(
            position=x,
            log_prior=lp,
            log_likelihood=ll,
            acceptance=mean_acc,
            num_evaluations=(nev + n).astype(jnp.int32),
            params=jnp.reshape(new_log_eps, (1,)),
            scale=step_size,
        )


def _gradient_move(kernel_cls, name: str, num_steps: int, init_step_size, target_accept: float,
                   dense_mass: bool, chunk_size, **kernel_options) -> KernelMove:
    """A NumPyro gradient kernel as a TMCMC move; the particle covariance is its (inverse) mass matrix."""

    def factory(potential_fn, step_size, cov):
        return kernel_cls(
            potential_fn=potential_fn,
            step_size=step_size,
            inverse_mass_matrix=cov if dense_mass else jnp.diag(cov),
            adapt_step_size=False,
            adapt_mass_matrix=False,
            dense_mass=dense_mass,
            **kernel_options,
        )

    return KernelMove(factory, num_steps, init_step_size, target_accept, chunk_size=chunk_size, name=name)


def hmc_move(
    num_steps: int = 3,
    trajectory_length: float = 1.5,
    init_step_size: float | None = None,
    target_accept: float = 0.8,
    dense_mass: bool = True,
    chunk_size: int | None = None,
) -> KernelMove:
    """NumPyro HMC as a TMCMC move, the particle covariance as its (inverse) mass matrix.

    Parameters
    ----------
    num_steps : int
        HMC transitions per particle and stage.
    trajectory_length : float
        Fixed trajectory length, in units of the particle covariance (the mass matrix whitens it).
    init_step_size : float or None
        Starting step size (None: d^(-1/4)).
    target_accept : float
        Target mean acceptance of the step-size adaptation.
    dense_mass : bool
        Dense inverse mass matrix (the full covariance) or its diagonal.
    chunk_size : int or None
        Particles per chunk of the vmapped chains.

    Returns
    -------
    KernelMove
    """
    return _gradient_move(HMC, "hmc", num_steps, init_step_size, target_accept, dense_mass, chunk_size,
                          trajectory_length=trajectory_length)


def nuts_move(
    num_steps: int = 2,
    max_tree_depth: int = 6,
    init_step_size: float | None = None,
    target_accept: float = 0.8,
    dense_mass: bool = True,
    chunk_size: int | None = None,
) -> KernelMove:
    """NumPyro NUTS as a TMCMC move, the particle covariance as its (inverse) mass matrix.

    Each particle builds its own tree; the vmapped computation runs to the deepest tree of the population.

    Parameters
    ----------
    num_steps : int
        NUTS transitions per particle and stage.
    max_tree_depth : int
        Maximum tree depth of NUTS.
    init_step_size : float or None
        Starting step size (None: d^(-1/4)).
    target_accept : float
        Target mean acceptance of the step-size adaptation.
    dense_mass : bool
        Dense inverse mass matrix (the full covariance) or its diagonal.
    chunk_size : int or None
        Particles per chunk of the vmapped chains.

    Returns
    -------
    KernelMove
    """
    return _gradient_move(NUTS, "nuts", num_steps, init_step_size, target_accept, dense_mass, chunk_size,
                          max_tree_depth=max_tree_depth)
