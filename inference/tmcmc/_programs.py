"""Compiled TMCMC programs, cached per process (private to :mod:`bubblecal.inference.tmcmc`).

A phase of a staged hierarchy is a new TMCMC run of a new model; if every run built its own jitted
closures, every run would trace and compile everything again. Programs are therefore built once per
key and kept here (least recently used entries beyond ``_PROGRAM_CACHE_SIZE`` are dropped):

- ``("stage", type(move), move, resampling)``: the model-free pieces of a random-walk stage
  (:class:`_StagePrograms`), shared by every model, dataset and CoV target;
- ``("model", FlatModel.signature, chunk_size)``: the model's own programs (:class:`_ModelPrograms`);
  its arrays are traced arguments, so datasets of one structure share them;
- ``("fused", FlatModel.signature, type(move), move key, config, max_stages)``: init, stage and whole
  run with a move that needs the model inside (:class:`_FusedPrograms`);
- ``("batched", FlatModel.signature, type(move), move key, config, max_stages, data axes)``: init and whole
  run vmapped over datasets of one structure (:class:`_BatchedPrograms`, :mod:`bubblecal.inference.tmcmc.batched`).

Under each key, jit keeps one executable per argument shape (N, d, data shapes). The flat models themselves are
kept per model and argument objects (:func:`flat_model`).
"""

from __future__ import annotations

import collections
import functools
from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from bubblecal.inference.tmcmc import core
from bubblecal.inference.tmcmc._flat_model import FlatModel
from bubblecal.inference.tmcmc._keys import _static_key
from bubblecal.inference.tmcmc.evaluator import Evaluator, chunked_vmap
from bubblecal.inference.tmcmc.executables import Program
from bubblecal.inference.tmcmc.moves import RandomWalk
from bubblecal.inference.tmcmc.state import TMCMCConfig, initial_state

_PROGRAM_CACHE_SIZE = 64
_program_cache: collections.OrderedDict = collections.OrderedDict()


def _cached_programs(key, build: Callable):
    """``build()`` once per ``key`` (least recently used entries beyond the cache size are dropped)."""
    if key in _program_cache:
        _program_cache.move_to_end(key)
        return _program_cache[key]
    value = _program_cache[key] = build()
    while len(_program_cache) > _PROGRAM_CACHE_SIZE:
        _program_cache.popitem(last=False)
    return value


def clear_program_cache() -> None:
    """Forget every cached compiled TMCMC program (the next runs trace and compile again)."""
    _program_cache.clear()
    _flat_cache.clear()


_FLAT_CACHE_SIZE = 32
_flat_cache: collections.OrderedDict = collections.OrderedDict()


def flat_model(model: Callable, args, kwargs, *, space: str, rng_key, tempered=None) -> FlatModel:
    """The :class:`FlatModel` of ``model(*args, **kwargs)``, built once per model and argument objects.

    A run compiled ahead and the run itself, or the likelihood preflight and phase 1, pass the same objects and
    share one flat model (building one traces the model). The cache keeps the argument objects themselves, so
    a hit is the same objects, never equal ones; the probe key only seeds that trace, so it is no part of the key.
    """
    leaves, treedef = jax.tree_util.tree_flatten((tuple(args), dict(kwargs or {})))
    key = (model, space, None if tempered is None else tuple(tempered), treedef, tuple(id(v) for v in leaves),
           bool(jax.config.jax_enable_x64))
    hit = _flat_cache.get(key)
    if hit is not None and all(a is b for a, b in zip(hit[0], leaves, strict=True)):
        _flat_cache.move_to_end(key)
        return hit[1]
    flat = FlatModel(model, args, kwargs, space=space, rng_key=rng_key, tempered=tempered)
    _flat_cache[key] = (leaves, flat)
    while len(_flat_cache) > _FLAT_CACHE_SIZE:
        _flat_cache.popitem(last=False)
    return flat


class _StagePrograms(NamedTuple):
    """Jitted model-free pieces of a random-walk stage (see :func:`_split_stage`)."""

    initial_state: Callable  # (position, log_prior, log_likelihood) -> TMCMCState
    begin: Callable  # (key, state, target CoV) -> (StagePlan, chol, log s, move carry)
    propose: Callable  # (key, x, chol, log s) -> (key, acceptance key, proposal)
    accept: Callable  # (acceptance key, carry, proposal, lp, ll, beta) -> carry
    end: Callable  # (state, plan, carry, log s at the start, min Δ) -> (state, StageInfo)


class _ModelPrograms(NamedTuple):
    """Jitted programs of one model structure; the model's arrays (``FlatModel.data``) are arguments."""

    draws: Callable  # (key, data, num) -> (num, d) exact prior draws in the flat space
    evaluate: Callable  # (position, data) -> (log prior, log L) of (N, d) particles
    sites: Callable  # (position, data) -> {site: (N, ...) constrained values and deterministic sites}
    pointwise: Callable  # (draws, data) -> {observed site: (n, obs...) log likelihood} of constrained draws
    flatten: Callable  # ({latent site: (n, ...) constrained values}) -> (n, d) flat positions
    untemper: Callable  # (position, log base, log tempered, data) -> the model's (log prior, log likelihood)


class _FusedPrograms(NamedTuple):
    """Jitted init / stage / whole run with the move fused in (moves that need the model inside)."""

    init: Callable  # (key, data, num) -> TMCMCState
    step: Callable  # (key, state, data) -> (state, StageInfo)
    run: Callable  # (key, state, data) -> (state, infos, status)


def _splittable(move) -> bool:
    """True for moves whose stage can run as model-free pieces around the evaluator (the random walk)."""
    return isinstance(move, RandomWalk)


def _stage_programs(move: RandomWalk, config: TMCMCConfig) -> _StagePrograms:
    """The stage pieces of ``move`` with ``config``'s resampling, shared by every model, dataset and CoV
    target: the numeric settings (target CoV, minimum Δ) are traced arguments of each call."""

    def build():
        def settings(target_cov, min_delta):
            return TMCMCConfig(target_cov=target_cov, resampling=config.resampling, min_delta=min_delta)

        def begin(key, state, target_cov):
            plan = core.prepare_stage(key, state, settings(target_cov, 0.0))
            chol, log_s = move.start(plan.weighted_cov, state.move_params)
            carry = (plan.position, plan.log_prior, plan.log_likelihood, log_s, jnp.zeros((), plan.position.dtype))
            return plan, chol, log_s, carry

        def end(state, plan, carry, log_s0, min_delta):
            return core.finish_stage(state, plan, move.result(carry, log_s0), settings(1.0, min_delta))

        # each function's closure (the move, the resampling) is its stored identity
        return _StagePrograms(
            initial_state=start_program(move),
            begin=Program(begin, identity=begin),
            propose=Program(move.propose, identity=move.propose),
            accept=Program(move.accept, identity=move.accept),
            end=Program(end, identity=end),
        )

    # the type is part of the key: NamedTuples of equal fields compare equal across classes
    return _cached_programs(("stage", type(move), move, config.resampling), build)


def _densities(flat: FlatModel, data) -> tuple[Callable, Callable]:
    """(log prior, log likelihood) of one flat vector of ``flat``'s structure with ``data`` as its arrays."""
    return functools.partial(flat.log_prior, data=data), functools.partial(flat.log_likelihood, data=data)


def _evaluator(flat: FlatModel, data, chunk_size: int | None) -> Evaluator:
    """The population evaluator of ``flat``'s structure, both densities from one pass through the model."""
    return Evaluator(*_densities(flat, data), chunk_size, functools.partial(flat.log_terms, data=data))


def _model_programs(flat: FlatModel, chunk_size: int | None) -> _ModelPrograms:
    """Prior draws, evaluator and sites of ``flat``'s structure; ``flat`` (the first model seen with
    this signature) serves as the template, every later model of equal signature passes its own data."""

    def build():
        def evaluate(position, data):
            return _evaluator(flat, data, chunk_size)(position)

        def sites(position, data):
            return chunked_vmap(functools.partial(flat.sites, data=data), chunk_size)(position)

        def pointwise(draws, data):
            from numpyro.infer import log_likelihood

            args, kwargs = flat.arguments(data)
            return log_likelihood(flat.model, draws, *args, parallel=True, **kwargs)

        def untemper(position, base, tempered, data):
            # the prior alone costs little to compile: the likelihood's arrays are unused and dropped
            prior = chunked_vmap(functools.partial(flat.model_log_prior, data=data), chunk_size)(position)
            return prior, base - prior + tempered

        def identity(role):  # the model's part of a stored program's key: the in-process key, by value
            return ("model", role, flat.signature, chunk_size)

        return _ModelPrograms(
            draws=Program(lambda key, data, num: flat.prior_draws(key, num, data), identity("draws"),
                          static_argnums=(2,)),
            evaluate=Program(evaluate, identity("evaluate")),
            sites=Program(sites, identity("sites")),
            pointwise=Program(pointwise, identity("pointwise")),
            flatten=jax.jit(jax.vmap(flat.flatten)),
            untemper=Program(untemper, identity("untemper")),
        )

    return _cached_programs(("model", flat.signature, chunk_size), build)


def start_positions(programs: _ModelPrograms, flat: FlatModel, samples, num: int):
    """The (num, d) flat positions of the constrained draws ``samples`` ({site: (num, ...)}) of ``flat``'s latents.

    Raises
    ------
    ValueError
        If a latent site is missing or holds another number of draws or another shape per draw.
    """
    missing = [k for k in flat.latent if k not in samples]
    if missing:
        raise ValueError(f"init_samples lacks the latent sites {missing} of model {flat.label!r}")
    values = {}
    for k in flat.latent:
        v = np.asarray(samples[k], dtype=flat.dtype)
        if v.shape != (num, *flat.latent_shapes[k]):
            raise ValueError(f"init_samples[{k!r}] of model {flat.label!r} must have shape "
                             f"{(num, *flat.latent_shapes[k])} (num_particles draws), got {v.shape}")
        values[k] = jax.device_put(v)
    return programs.flatten(values)


def start_program(move: Any) -> Callable:
    """Jitted ``(position, log prior, log likelihood) -> TMCMCState`` at β = 0 with ``move``'s initial parameters."""
    def build():
        def start(position, lp, ll):
            return initial_state(position, lp, ll, move)

        return Program(start, identity=start)

    return _cached_programs(("start", type(move), _static_key(move)), build)


def offset_evidence(init_fn: Callable, log_evidence: float) -> Callable:
    """``init_fn`` whose initial state starts the log evidence at ``log_evidence`` (the base's normaliser)."""

    def init(key):
        state = init_fn(key)
        value = np.asarray(log_evidence, dtype=np.dtype(state.log_evidence.dtype))
        return state._replace(log_evidence=jax.device_put(value))

    return init


def _fused_programs(flat: FlatModel, move: Any, config: TMCMCConfig, max_stages: int) -> _FusedPrograms:
    """Init, stage and whole run with ``move`` fused in, for ``flat``'s structure (data as arguments)."""

    def build():
        return _FusedPrograms(
            init=jax.jit(
                lambda key, data, num: core.init(
                    flat.prior_draws(key, num, data), *_densities(flat, data), move, config.chunk_size
                ),
                static_argnums=2,
            ),
            step=jax.jit(lambda key, state, data: core.step(key, state, *_densities(flat, data), move, config)),
            run=jax.jit(
                lambda key, state, data: core.run(key, state, *_densities(flat, data), move, config, max_stages)
            ),
        )

    key = ("fused", flat.signature, type(move), _static_key(move), config, max_stages)
    return _cached_programs(key, build)


class _BatchedPrograms(NamedTuple):
    """Jitted init and whole run vmapped over B runs; data leaves with axis 0 carry a leading B axis."""

    init: Callable  # (keys (B,), data, num) -> TMCMCState with a leading B axis
    run: Callable  # (keys (B,), states, data) -> (states, infos, status), each with a leading B axis


def _batched_programs(flat: FlatModel, move: Any, config: TMCMCConfig, max_stages: int,
                      axes: tuple) -> _BatchedPrograms:
    """The fused init and run of ``flat``'s structure vmapped over runs (``axes``: 0 for a data leaf stacked
    over the runs, None for one shared by all)."""

    def build():
        def init_one(key, data, num):
            return core.init(flat.prior_draws(key, num, data), *_densities(flat, data), move, config.chunk_size)

        def run_one(key, state, data):
            return core.run(key, state, *_densities(flat, data), move, config, max_stages)

        def init(keys, data, num):
            return jax.vmap(functools.partial(init_one, num=num), in_axes=(0, axes))(keys, data)

        return _BatchedPrograms(init=jax.jit(init, static_argnums=2),
                                run=jax.jit(jax.vmap(run_one, in_axes=(0, 0, axes))))

    key = ("batched", flat.signature, type(move), _static_key(move), config, max_stages, axes)
    return _cached_programs(key, build)


def _split_stage(stages: _StagePrograms, evaluate: Callable, move: RandomWalk, config: TMCMCConfig, key, state):
    """One stage as host-driven pieces: the arithmetic and random numbers of :func:`core.step` with a
    :class:`RandomWalk`, but only ``evaluate`` (jitted, ``(N, d) -> (log prior, log L)``) is specific to
    the model.  Returns ``(state, info)``.  (Not bitwise equal to the fused step: XLA fuses the
    proposal into the fused step's likelihood, which moves log L by float round-off, ~1e-6 relative.)"""
    # Python floats reach jit as traced weakly typed scalars (the dtype of the particles), not constants
    plan, chol, log_s0, carry = stages.begin(key, state, float(config.target_cov))
    key = plan.key_move
    for _ in range(move.num_steps):
        key, k_acc, prop = stages.propose(key, carry[0], chol, carry[3])
        lp_p, ll_p = evaluate(prop)
        carry = stages.accept(k_acc, carry, prop, lp_p, ll_p, plan.beta)
    return stages.end(state, plan, carry, log_s0, float(config.min_delta))


def _on_device(data) -> tuple:
    """The model's arrays on the default device, as ``jnp.asarray`` gives them (float64 as float32 without x64);
    host arrays go through ``jax.device_put``, which unlike ``jnp.asarray`` compiles no program per shape."""
    return tuple(jax.device_put(v) if isinstance(v, np.ndarray) else jnp.asarray(v) for v in data)
