"""Compiling the programs of TMCMC runs ahead of the runs, several at a time.

A run compiles its programs one after the other as it first calls them (prior draws, evaluator, the stage
pieces, the exports' sites and pointwise log likelihood), each compilation largely sequential XLA work.
:func:`compile_ahead` lowers the programs of one or more runs in the calling thread (tracing a NumPyro
model is not thread-safe: its handler stack is global), then compiles them on a pool of threads (XLA releases
the GIL), so a host with k cores compiles up to k programs at once. jit keeps what was compiled: the runs then
call their programs without compiling, and their draws are the same as without the compilation ahead.

Covered: the host-driven random-walk stages (``compiled=False``, the default) with exact prior draws or
``init_samples``, a tempered model's prior split, and the exports' programs
(:meth:`~bubblecal.inference.tmcmc.TMCMC.get_samples`, :meth:`~bubblecal.inference.tmcmc.TMCMC.inference_parts`
with its default chunk). Other runs (a fused or batched run, a kernel move) compile as they run.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any, NamedTuple

import jax

from bubblecal.inference.tmcmc._programs import _model_programs, _on_device, _splittable, _stage_programs, flat_model
from bubblecal.inference.tmcmc.evaluator import _default_platform
from bubblecal.inference.tmcmc.executables import compile_fresh

__all__ = ["MAX_COMPILE_WORKERS", "RunSpec", "compile_ahead", "compile_lowered", "compile_workers"]


class RunSpec(NamedTuple):
    """A TMCMC run to compile ahead: ``sampler.run(rng_key, *args, init_samples=init_samples, **kwargs)``.

    Parameters
    ----------
    sampler : bubblecal.inference.tmcmc.TMCMC
        The sampler that will run (its model, particles, move, chunk, tempered sites).
    rng_key : jax.Array
        The run's PRNG key (its shape and type, not its value, matter).
    args : tuple
        Positional arguments of the model.
    kwargs : mapping
        Keyword arguments of the model.
    init_samples : mapping or None
        The run's ``init_samples`` (None: exact prior draws).
    """

    sampler: Any
    rng_key: Any
    args: tuple = ()
    kwargs: Mapping = {}
    init_samples: Mapping | None = None


#: Most compilations at once (each holds its own working memory while it compiles).
MAX_COMPILE_WORKERS = 16


def compile_workers() -> int:
    """Threads that compile at once: the cores this process may use (its CPU affinity where the platform has one),
    at most :data:`MAX_COMPILE_WORKERS`."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # no affinity on this platform
        cores = os.cpu_count() or 1
    return max(1, min(cores, MAX_COMPILE_WORKERS))


def compile_ahead(runs: Iterable[RunSpec], workers: int | None = None, exports: bool = True) -> int:
    """Compile the programs of ``runs`` (and of their exports) ahead, up to ``workers`` at a time.

    Programs found in the program store (:func:`~bubblecal.inference.tmcmc.enable_program_store`) are read
    from it instead: they are neither traced, lowered nor compiled. Those XLA compiled here are written to it (not
    those JAX read from its persistent compilation cache: :func:`bubblecal.inference.tmcmc.executables.compile_fresh`).

    Parameters
    ----------
    runs : iterable of RunSpec
        The runs whose programs to compile; runs of one model structure share programs (compiled once).
    workers : int or None
        Compilations at once; None: :func:`compile_workers`.
    exports : bool
        Also the programs of the runs' exports (sites of the draws, the pointwise log likelihood).

    Returns
    -------
    int
        Programs lowered and handed to the compiler (none for those held already or read from the store).

    Raises
    ------
    ValueError
        As :meth:`~bubblecal.inference.tmcmc.TMCMC.run` would for a model it cannot run (nothing is compiled).
    """
    calls, seen = [], set()
    for spec in runs:
        for program, args in _run_calls(spec, exports):
            key = (id(program), program.call_key(args))
            if key not in seen and not program.ready(*args):
                seen.add(key)
                calls.append((program, args))
    lowered = [program.lower(*args) for program, args in calls]
    for (program, args), (executable, fresh) in zip(calls, _compile_all(lowered, workers, compile_fresh), strict=True):
        program.keep(args, executable, store=fresh)
    return len(calls)


def compile_lowered(lowered: Sequence, workers: int | None = None) -> None:
    """Compile lowered programs (``jax.jit(f).lower(...)``), up to ``workers`` at a time.

    The executables land in jit's cache (and in the persistent compilation cache when it is on): calling the
    jitted functions with arguments of the lowered shapes then compiles nothing.

    Parameters
    ----------
    lowered : sequence of jax.stages.Lowered
        Programs lowered on the calling thread.
    workers : int or None
        Compilations at once; None: :func:`compile_workers`.
    """
    _compile_all(lowered, workers, lambda program: program.compile())


def _compile_all(lowered: Sequence, workers: int | None, compile_one) -> list:
    """``compile_one`` of each of ``lowered``, in order, up to ``workers`` at a time."""
    workers = compile_workers() if workers is None else max(1, int(workers))
    if workers == 1 or len(lowered) < 2:
        return [compile_one(program) for program in lowered]
    with ThreadPoolExecutor(max_workers=min(workers, len(lowered)), thread_name_prefix="compile") as pool:
        return list(pool.map(compile_one, lowered))


def _run_calls(spec: RunSpec, exports: bool) -> list:
    """The (program, argument shapes) of one run, as its host-driven random-walk stages call them."""
    sampler = spec.sampler
    move, cfg, n = sampler.move, sampler.config, sampler.num_particles
    if sampler.compiled or not _splittable(move):
        return []
    flat = flat_model(sampler.model, spec.args, spec.kwargs, space=sampler.space, rng_key=spec.rng_key,
                      tempered=sampler.tempered)
    data = _on_device(flat.data)
    model = _model_programs(flat, cfg.chunk_size)
    stages = _stage_programs(move, cfg)
    key = jax.eval_shape(lambda k: jax.random.split(k)[0], spec.rng_key)
    position = jax.ShapeDtypeStruct((n, flat.dim), flat.dtype)
    out = []
    if spec.init_samples is None:
        out.append((model.draws, (key, data, n)))
    lp, ll = model.evaluate.shapes(position, data)
    out += [(model.evaluate, (position, data)), (stages.initial_state, (position, lp, ll))]
    state = stages.initial_state.shapes(position, lp, ll)
    target_cov, min_delta = float(cfg.target_cov), float(cfg.min_delta)  # Python floats, as _split_stage passes
    seen = []
    while state not in seen:  # the first stage's state and the one every stage returns
        seen.append(state)
        plan, chol, log_s0, carry = stages.begin.shapes(key, state, target_cov)
        _, k_acc, proposal = stages.propose.shapes(plan.key_move, carry[0], chol, carry[3])
        out += [(stages.begin, (key, state, target_cov)),
                (stages.propose, (plan.key_move, carry[0], chol, carry[3])),
                (stages.accept, (k_acc, carry, proposal, lp, ll, plan.beta)),
                (stages.end, (state, plan, carry, log_s0, min_delta))]
        state, _ = stages.end.shapes(state, plan, carry, log_s0, min_delta)
    if sampler.tempered is not None:
        out.append((model.untemper, (position, lp, ll, data)))
    if exports:
        sites = model.sites.shapes(position, data)
        out.append((model.sites, (position, data)))
    if exports and flat.observed:  # a model without observed sites gets its pointwise values from its caller
        from bubblecal.inference.tmcmc.results import POINTWISE_CPU_CHUNK

        total = sampler.num_replicas * n
        size = min(POINTWISE_CPU_CHUNK, total) if _default_platform() == "cpu" else total
        chunk = {k: jax.ShapeDtypeStruct((size,) + v.shape[1:], v.dtype) for k, v in sites.items()}
        out.append((model.pointwise, (chunk, data)))
    return out
