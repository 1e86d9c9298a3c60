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

__all__ = ["Evaluator", "chunked_vmap", "CPU_CHUNK_SIZE", "resolve_chunk_size"]

#: Particles per evaluation chunk that ``chunk_size='auto'`` uses on a CPU: the chunk's intermediate arrays
#: (network activations, the phase-3 mixture over ψ draws) then stay in the processor's caches, which makes a
#: population of thousands 2-3x cheaper to evaluate than one vmap over all of it (benchmarks/RESULTS.md).
CPU_CHUNK_SIZE = 512


def _default_platform() -> str:
    """Platform of the device JAX places new arrays and programs on (``jax.default_device`` respected)."""
    device = jax.config.jax_default_device
    if device is None:
        return jax.default_backend()
    return device if isinstance(device, str) else device.platform


def resolve_chunk_size(chunk_size: int | str | None, num_particles: int) -> int | None:
    """The particles per evaluation chunk a run uses.

    Parameters
    ----------
    chunk_size : int, 'auto' or None
        An explicit chunk; None (all particles in one vmap); or 'auto': on a CPU and a population larger than
        twice :data:`CPU_CHUNK_SIZE`, the largest chunk of at most :data:`CPU_CHUNK_SIZE` and at least half of it
        that divides the population (else :data:`CPU_CHUNK_SIZE`), else None (a GPU wants all particles at once).
    num_particles : int
        Particles of the population.

    Returns
    -------
    int or None

    Raises
    ------
    ValueError
        For a string other than 'auto'.
    """
    if isinstance(chunk_size, str):
        if chunk_size != "auto":
            raise ValueError(f"chunk_size must be a positive integer, None or 'auto', got {chunk_size!r}")
        if _default_platform() != "cpu" or num_particles <= 2 * CPU_CHUNK_SIZE:
            return None
        return _dividing_chunk(num_particles, CPU_CHUNK_SIZE)
    return chunk_size


def _dividing_chunk(n: int, cap: int) -> int:
    """The largest chunk in [cap / 2, cap] that divides ``n`` (else ``cap``): ``lax.map`` then traces and compiles
    one chunk body, not a second one for a remainder."""
    for size in range(cap, cap // 2 - 1, -1):
        if n % size == 0:
            return size
    return cap


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
    log_terms_fn : callable or None
        ``x -> (log p(x), log L(x))`` of one flat vector, both densities from one pass through the model; when
        given, :meth:`one` uses it (the model is traced once per program, not once per density), else the two
        functions above.

    Notes
    -----
    Calling the evaluator, ``evaluate(position) -> (log_prior (N,), log_likelihood (N,))``, is what the
    random-walk move needs; gradient moves (:class:`~bubblecal.inference.tmcmc.moves.KernelMove`) use
    :meth:`one` for the per-particle densities and :attr:`chunk_size` for their own chunking.
    """

    log_prior_fn: Callable[[Array], Array]
    log_likelihood_fn: Callable[[Array], Array]
    chunk_size: int | None = None
    log_terms_fn: Callable[[Array], tuple[Array, Array]] | None = None

    def one(self, x: Array) -> tuple[Array, Array]:
        """(log prior, log likelihood) of one flat vector ``x`` (d,), as arrays."""
        if self.log_terms_fn is not None:
            lp, ll = self.log_terms_fn(x)
            return jnp.asarray(lp), jnp.asarray(ll)
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
