"""TMCMC as a ``numpyro.infer.MCMC`` kernel: swap ``MCMC(NUTS(model))`` for ``MCMC(TMCMCKernel(model))``.

::

    mcmc = MCMC(TMCMCKernel(model, num_particles=2000), num_warmup=0, num_samples=2000)
    mcmc.run(jax.random.PRNGKey(0), *model_args)
    mcmc.get_samples(), mcmc.print_summary(), az.from_numpyro(mcmc)
    mcmc.last_state.log_evidence                  # log Z of the tempering (one value per chain)

Like NumPyro's ensemble kernels (``AIES``, ``ESS``) the kernel state holds a whole population. ``init``
runs the complete tempering from the prior to β = 1 with the front end
(:class:`~bubblecal.inference.tmcmc.sampler.TMCMC`, so the same compiled programs, stage table, status
and warnings); the ``sample`` calls then hand out its final particles one per draw, in a random order.
What the MCMC settings mean for it (``docs/inference.md`` section 5):

- ``num_samples``: draws from the final population; up to ``num_particles`` they are distinct
  particles of that population (``num_samples = num_particles`` returns all of it). Each further
  block of ``num_particles`` draws comes from the population after one more move at the final
  exponent (the run's move with its adaptation frozen and the population covariance as Σ_w), which
  leaves the posterior invariant;
- ``num_warmup``: accepted and free: warmup iterations draw nothing (the tempering is the warmup);
- ``num_chains``: independent temperings, chain c being ``TMCMC(...).run(key_c)``; chain methods
  'sequential' and 'vectorized' (and 'parallel' when it falls back to 'sequential' on one device).

With one chain and the same key, the population is exactly that of ``TMCMC(model, ...).run(key)``.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jax.flatten_util import ravel_pytree
from numpyro.infer.mcmc import MCMCKernel
from numpyro.util import is_prng_key

from bubblecal.inference.tmcmc._programs import _evaluator
from bubblecal.inference.tmcmc.moves import KernelMove, RandomWalk
from bubblecal.inference.tmcmc.sampler import TMCMC
from bubblecal.inference.tmcmc.tempering import weighted_moments

Array = jax.Array

__all__ = ["TMCMCKernel", "TMCMCKernelState"]


class TMCMCKernelState(NamedTuple):
    """State of :class:`TMCMCKernel`: the current draw and the final TMCMC population behind it.

    With several vectorized chains every field has a leading chain axis.
    """

    z: dict  # the current draw: {latent site: value in the sampling space} (unconstrained by default)
    potential_energy: Array  # () −(log prior + log L) of the draw, in the sampling space
    population: Array  # (N, d) flat particles at ``beta``
    log_prior: Array  # (N,)
    log_likelihood: Array  # (N,)
    order: Array  # (N,) int32, the random order in which the current population is handed out
    beta: Array  # () exponent reached by the tempering (1 unless the run stalled or hit the stage cap)
    log_evidence: Array  # () log Z of the tempering
    move_params: Array  # (p,) the move's adapted parameters at the end of the tempering
    acceptance: Array  # () mean acceptance of the latest move at the final exponent (NaN before one)
    num_evaluations: Array  # () int32, likelihood evaluations (tempering and later moves)
    iteration: Array  # () int32, ``sample`` calls so far (warmup included)
    rng_key: Array  # key of the later moves and orders


def _frozen(move):
    """The move with its adaptation off: a fixed kernel leaves the target invariant exactly."""
    if isinstance(move, RandomWalk):
        return move._replace(adapt=False)
    if isinstance(move, KernelMove):
        frozen = copy.copy(move)
        frozen.adapt_step_size = False
        return frozen
    return move


class TMCMCKernel(MCMCKernel):
    """TMCMC of a NumPyro model as a ``numpyro.infer.MCMC`` kernel (see the module docstring).

    Parameters
    ----------
    model : callable
        NumPyro model function (continuous latent sites, any supports), as for ``NUTS(model)``.
    num_particles : int
        N, the population size of the tempering (the front end's default when None).
    **tmcmc_options
        Any other setting of :class:`~bubblecal.inference.tmcmc.sampler.TMCMC` (``target_cov``,
        ``cov_scale``, ``num_mcmc_steps``, ``preset``, ``move``, ``max_stages``, ``chunk_size``,
        ``space``, ``min_delta``, ``compiled``), except ``num_replicas``: independent runs are chains.

    Raises
    ------
    ValueError
        For ``num_replicas`` and for any setting the front end rejects (the message names it).

    Notes
    -----
    After ``MCMC.run``: ``mcmc.last_state.log_evidence`` (one value per chain), ``mcmc.last_state.beta``
    and :attr:`tmcmc`, the front end of the latest tempering (``stage_info``, ``status``,
    ``log_evidence``; with several chains, the last one's). The draws' ``n_eff`` and ``r_hat`` in
    ``print_summary`` treat the population as a chain in random order: they count particles, not the
    independent information the tempering kept (see the stage table's ``ess`` and ``unique_fraction``).
    """

    def __init__(self, model: Callable, num_particles: int | None = None, **tmcmc_options):
        if "num_replicas" in tmcmc_options:
            raise ValueError(
                "TMCMCKernel runs one tempering per chain: pass num_chains to MCMC instead of num_replicas"
            )
        if num_particles is not None:
            tmcmc_options["num_particles"] = num_particles
        self._model = model
        #: the front end that runs each tempering (it validates every setting here)
        self.tmcmc = TMCMC(model, **tmcmc_options)
        self._num_warmup = 0
        self._flat = None
        self._data: tuple = ()
        self._sample_fn = None  # MCMC re-runs init while this is None (set once a tempering ran)

    @property
    def model(self) -> Callable:
        """The NumPyro model (ArviZ reads it for the observed data and the log likelihood)."""
        return self._model

    @property
    def sample_field(self) -> str:
        """'z': the latent values of a draw in the sampling space (constrained by :meth:`postprocess_fn`)."""
        return "z"

    @property
    def default_fields(self) -> tuple:
        """Fields MCMC collects: the draw and its potential energy (ArviZ's 'lp' = −potential energy)."""
        return ("z", "potential_energy")

    def get_diagnostics_str(self, state: TMCMCKernelState) -> str:
        """Progress-bar text: the exponent, log Z and the acceptance of the latest move at that exponent."""
        beta = float(np.mean(np.asarray(state.beta)))
        log_z = float(np.mean(np.asarray(state.log_evidence)))
        acc = float(np.mean(np.asarray(state.acceptance)))
        acc_txt = "" if math.isnan(acc) else f", acc. prob={acc:.2f}"
        return f"beta={beta:.3g}, log Z={log_z:.3f}{acc_txt}"

    # -- init: the whole tempering -------------------------------------------------------------

    def init(self, rng_key, num_warmup, init_params=None, model_args=(), model_kwargs=None) -> TMCMCKernelState:
        """Run the tempering to β = 1 (one per chain key) and return the state of the first draw.

        Parameters
        ----------
        rng_key : jax.Array
            One PRNG key, or a batch of keys (``chain_method='vectorized'``), one tempering each.
        num_warmup : int
            Warmup iterations MCMC will run before collecting; they draw nothing.
        init_params : None
            Must be None: TMCMC starts from exact prior draws.
        model_args : tuple
            Positional arguments of the model.
        model_kwargs : dict or None
            Keyword arguments of the model.

        Returns
        -------
        TMCMCKernelState

        Raises
        ------
        ValueError
            For ``init_params``, for a traced key (``chain_method='parallel'`` over several devices:
            the tempering runs on the host), and from the front end (a model with a discrete or no
            latent site, every prior draw with a non-finite log likelihood).
        """
        if init_params is not None:
            raise ValueError("TMCMCKernel starts from exact prior draws: init_params must be None")
        if isinstance(rng_key, jax.core.Tracer):
            raise ValueError(
                "TMCMCKernel runs its tempering on the host and cannot run under pmap/vmap: use "
                "chain_method='sequential' or 'vectorized' for several chains"
            )
        self._num_warmup = int(num_warmup)
        model_kwargs = dict(model_kwargs or {})
        if is_prng_key(rng_key):
            state = self._temper(rng_key, model_args, model_kwargs)
        else:
            states = [self._temper(key, model_args, model_kwargs) for key in rng_key]
            state = jax.tree_util.tree_map(lambda *v: jnp.stack(v), *states)
        self._sample_fn = self.sample
        return state

    def _temper(self, rng_key, model_args, model_kwargs) -> TMCMCKernelState:
        """One tempering with ``rng_key`` (the front end's run) and the state that hands out its particles."""
        tm = self.tmcmc.run(rng_key, *model_args, **model_kwargs)
        self._flat, self._data = tm._flat, tm._data
        final = tm.state
        # the run used rng_key itself (parity with the front end); the draws' order takes a derived key
        k_order, k_state = jax.random.split(jax.random.fold_in(rng_key, 1))
        order = jax.random.permutation(k_order, tm.num_particles).astype(jnp.int32)
        dtype = final.position.dtype
        state = TMCMCKernelState(
            z={},
            potential_energy=jnp.zeros((), dtype),
            population=final.position,
            log_prior=final.log_prior,
            log_likelihood=final.log_likelihood,
            order=order,
            beta=final.beta,
            log_evidence=final.log_evidence,
            move_params=final.move_params,
            acceptance=jnp.full((), jnp.nan, dtype),
            num_evaluations=final.num_evaluations,
            iteration=jnp.zeros((), jnp.int32),
            rng_key=k_state,
        )
        return self._emit(state, jnp.zeros((), jnp.int32))

    # -- sample: hand out particles; a move at the final exponent between blocks ----------------

    def _emit(self, state: TMCMCKernelState, k) -> TMCMCKernelState:
        """The state whose draw is the ``k``-th particle in the current order."""
        i = state.order[k]
        return state._replace(
            z=self._flat._unravel(state.population[i]),
            potential_energy=-(state.log_prior[i] + state.log_likelihood[i]),
        )

    def _move(self, state: TMCMCKernelState) -> TMCMCKernelState:
        """One more move of the whole population at the exponent reached, then a new random order."""
        key, k_move, k_order = jax.random.split(state.rng_key, 3)
        n = state.population.shape[0]
        _, cov = weighted_moments(state.population, jnp.full((n,), -math.log(n), state.population.dtype))
        evaluate = _evaluator(self._flat, self._data, self.tmcmc.config.chunk_size)
        res = _frozen(self.tmcmc.move)(
            k_move, state.population, state.log_prior, state.log_likelihood, state.beta, cov,
            state.move_params, evaluate,
        )
        return state._replace(
            population=res.position.astype(state.population.dtype),
            log_prior=res.log_prior.astype(state.log_prior.dtype),
            log_likelihood=res.log_likelihood.astype(state.log_likelihood.dtype),
            order=jax.random.permutation(k_order, n).astype(jnp.int32),
            acceptance=jnp.asarray(res.acceptance, state.acceptance.dtype),
            num_evaluations=(state.num_evaluations + res.num_evaluations).astype(jnp.int32),
            rng_key=key,
        )

    def sample(self, state: TMCMCKernelState, model_args, model_kwargs) -> TMCMCKernelState:
        """The next draw: the next particle of the population (see the module docstring).

        Parameters
        ----------
        state : TMCMCKernelState
            Current state (a leading chain axis with vectorized chains).
        model_args, model_kwargs
            Ignored: the model's arrays were bound by :meth:`init`.

        Returns
        -------
        TMCMCKernelState
        """
        batched = jnp.ndim(state.iteration) == 1
        # every chain is at the same iteration, so one scalar decides whether a move runs (under vmap a
        # batched predicate would run the move at every draw)
        t = state.iteration[0] if batched else state.iteration
        n = state.order.shape[-1]
        j = t - self._num_warmup  # index of this draw; negative during warmup
        k = jnp.where(j >= 0, j % n, 0).astype(jnp.int32)
        move = jax.vmap(self._move) if batched else self._move
        state = lax.cond((j > 0) & (k == 0), move, lambda s: s, state)
        state = state._replace(iteration=state.iteration + 1)
        if batched:
            return jax.vmap(self._emit, in_axes=(0, None))(state, k)
        return self._emit(state, k)

    def postprocess_fn(self, model_args, model_kwargs) -> Callable:
        """``z -> {site: constrained value}`` with the deterministic sites, as NUTS returns them.

        Parameters
        ----------
        model_args, model_kwargs
            Ignored: the model's arrays were bound by :meth:`init`.

        Returns
        -------
        callable
        """
        flat, data = self._flat, self._data
        if flat is None:
            raise ValueError("TMCMCKernel.postprocess_fn needs a tempering: call init (MCMC.run) first")

        def constrain(z):
            # ravel_pytree orders a dict's keys as the flat model's unravel does
            return flat.sites(ravel_pytree(z)[0], data)

        return constrain
