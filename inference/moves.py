"""Pluggable TMCMC moves: any NumPyro ``MCMCKernel`` run at the tempered potential.

``KernelMove(factory)`` runs, for every particle, a short chain of ``num_steps`` transitions of the
kernel built by ``factory(potential_fn, step_size, inverse_mass_matrix)``, where
``potential_fn(x) = −(log prior(x) + β log L(x))`` at the stage's exponent.  The chains of all particles
are one vmapped (or chunked ``lax.map``) computation inside the compiled stage.  Between stages the
step size is adapted toward ``target_accept`` from the population's mean acceptance, and the inverse
mass matrix is the weighted particle covariance of the stage.  For kernels whose state carries
``adapt_state.step_size`` (HMC, NUTS) the step size is also adapted between the ``num_steps``
transitions inside a stage (all particles share it; it is carried to the next stage).

:func:`hmc_move` and :func:`nuts_move` build the two gradient moves from NumPyro's ``HMC``/``NUTS``;
the random-walk move is :class:`bubblecal.inference.tmcmc_core.RandomWalk`.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import jax
import jax.numpy as jnp
from jax import lax
from numpyro.infer import HMC, NUTS

from bubblecal.inference.tmcmc_core import MoveResult, chunked_vmap, tempered


class KernelMove:
    """Mutation by a NumPyro ``MCMCKernel`` at the tempered potential (see the module docstring).

    ``factory(potential_fn, step_size, inverse_mass_matrix) -> MCMCKernel``.  The kernel must accept
    a flat array as ``init_params``; if its state has ``accept_prob`` / ``num_steps`` fields (HMC,
    NUTS) they feed the acceptance and the evaluation count (leapfrog steps = gradient evaluations).
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

    def init_params(self, dim: int):
        eps = self.init_step_size if self.init_step_size is not None else 1.0 / dim**0.25
        return jnp.array([math.log(eps)])

    def __call__(self, rng_key, position, log_prior, log_likelihood, beta, cov, params, evaluate):
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
    """NumPyro HMC (fixed trajectory length in units of the particle covariance) as a TMCMC move."""
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
    """NumPyro NUTS as a TMCMC move (per-particle trees; the vmapped tree runs to the deepest one)."""
    return _gradient_move(NUTS, "nuts", num_steps, init_step_size, target_accept, dense_mass, chunk_size,
                          max_tree_depth=max_tree_depth)
