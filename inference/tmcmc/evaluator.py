"""Evaluation of the two log densities over a particle population, whole or in chunks.

An :class:`Evaluator` is built inside the traced (jitted) programs of a TMCMC run, from densities that
close over the model's traced data; it is a static object closed over by those programs, never a jit
argument, so it needs no pytree registration and adds nothing to the programs' cache keys.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp
from jax import lax

Array = jax.Array

__all__ = ["Evaluator", "chunked_vmap"]


@dataclass(frozen=True)
class Evaluator:
    """``(log prior, log likelihood)`` of every particle of an ``(N, d)`` population.

    Parameters
    ----------
    log_prior_fn : callable
        ``x -> log p(x)`` of one flat vector ``x`` (d,), in the sampling space (Jacobian included).
    log_likelihood_fn : callable
        ``x -> log L(x)`` of one flat vector.
    chunk_size : int or None
        Evaluate this many particles at a time (``lax.map`` over chunks of a vmapped evaluation), so
        memory scales with the chunk rather than with N; None evaluates all particles in one vmap.

    Notes
    -----
    Calling the evaluator, ``evaluate(position) -> (log_prior (N,), log_likelihood (N,))``, is what the
    random-walk move needs; gradient moves (:class:`~bubblecal.inference.tmcmc.moves.KernelMove`) use
    :meth:`one` for the per-particle densities and :attr:`chunk_size` for their own chunking.
    """

    log_prior_fn: Callable[[Array], Array]
    log_likelihood_fn: Callable[[Array], Array]
    chunk_size: int | None = None

    def one(self, x: Array) -> tuple[Array, Array]:
        """(log prior, log likelihood) of one flat vector ``x`` (d,), as arrays."""
        return jnp.asarray(self.log_prior_fn(x)), jnp.asarray(self.log_likelihood_fn(x))

    def __call__(self, position: Array) -> tuple[Array, Array]:
        """(log prior (N,), log likelihood (N,)) of the particles ``position`` (N, d)."""
        n = position.shape[0]
        if self.chunk_size is None or self.chunk_size >= n:
            return jax.vmap(self.one)(position)
        return lax.map(self.one, position, batch_size=int(self.chunk_size))


def chunked_vmap(fn: Callable, chunk_size: int | None) -> Callable:
    """vmap ``fn`` over the leading axis of its (pytree) argument, ``chunk_size`` elements at a time.

    Parameters
    ----------
    fn : callable
        Function of one element (a pytree of arrays without the leading axis).
    chunk_size : int or None
        Elements per ``lax.map`` batch; None (or a chunk at least as large as the axis) vmaps all at once.

    Returns
    -------
    callable
        The mapped function of the stacked argument.
    """

    def mapped(xs):
        n = jax.tree_util.tree_leaves(xs)[0].shape[0]
        if chunk_size is None or chunk_size >= n:
            return jax.vmap(fn)(xs)
        return lax.map(fn, xs, batch_size=int(chunk_size))

    return mapped
