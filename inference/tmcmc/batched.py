"""K independent TMCMC temperings of K datasets of one model structure, in one compiled program.

Datasets of one structure (one model function, argument pytrees of equal structure with arrays of equal shapes:
curves padded to one length with a mask, networks of one size) already share the compiled programs of a run,
because their arrays are traced arguments (:mod:`bubblecal.inference.tmcmc._programs`). :func:`run_batched`
goes one step further: the fused run (:func:`bubblecal.inference.tmcmc.core.run`, a ``lax.while_loop`` over
stages) is ``jax.vmap``-ed over the datasets, whose array arguments are stacked on a new leading axis (arrays
that are the same for every dataset, e.g. the network weights of one surrogate, are passed once). A dataset
that has reached β = 1 stays frozen while the others continue, so every dataset gets the population that a
single fused run (``TMCMC(..., compiled=True).run(key, ...)``) with its key gives, to float round-off.

What it saves is the per-program cost that does not grow with the particles: one program call per batch
instead of one per dataset (and, for host-driven runs, per stage and MH step). It pays where a run is bound by
dispatch and launch latency (the GPU at moderate N); where the likelihood evaluations saturate the device (a
few CPU cores) the work is the same either way, and the batch then waits for its slowest dataset.

Memory grows with (datasets in a batch) x N x (points of a curve): ``batch_size`` bounds it; by default a batch
holds at most :data:`MAX_BATCH_PARTICLES` particles in all.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Sequence
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from bubblecal.inference.tmcmc._flat_model import FlatModel, _is_data, _unpartial
from bubblecal.inference.tmcmc._keys import _aval_key, _static_key
from bubblecal.inference.tmcmc._programs import _batched_programs
from bubblecal.inference.tmcmc.progress import stage_reporter
from bubblecal.inference.tmcmc.sampler import TMCMC
from bubblecal.inference.tmcmc.state import STATUS_NAMES

__all__ = ["run_batched", "batch_groups", "structure_key", "BatchStructureError", "MAX_BATCH_PARTICLES"]

#: Default bound of a batch: datasets x replicas x particles of one program call.
MAX_BATCH_PARTICLES = 2**18

# what FlatModel.signature holds, in order (for the message naming the first difference)
_SIGNATURE_PARTS = ("model function", "sampling space", "argument pytree structure", "fixed (non-array) arguments",
                    "array argument shapes/dtypes", "latent site shapes", "latent site bijections",
                    "latent site scales", "latent event dimensions", "deterministic sites")


class BatchStructureError(ValueError):
    """Datasets given to one batched TMCMC run do not share one model structure (the message names the first
    dataset that differs and what differs)."""


def structure_key(model: Callable, args: tuple = (), kwargs: dict | None = None) -> tuple:
    """Hashable key of a model's structure: datasets of equal keys can run in one batch.

    Parameters
    ----------
    model : callable
        NumPyro model (a ``functools.partial`` is unwrapped: its bound arguments count as arguments).
    args : tuple
        Positional arguments of the model.
    kwargs : dict or None
        Keyword arguments of the model.

    Returns
    -------
    tuple
        (model function, argument pytree structure, per leaf: shape and dtype of a numeric array, or the
        value, else identity, of anything else).
    """
    model, args, kwargs = _unpartial(model, tuple(args), dict(kwargs or {}))
    leaves, treedef = jax.tree_util.tree_flatten((args, kwargs))
    return (model, treedef, tuple(("array", _aval_key(v)) if _is_data(v) else _static_key(v) for v in leaves))


def batch_groups(models: Sequence[Callable], args_list: Sequence[tuple],
                 kwargs_list: Sequence[dict | None] | None = None) -> list[list[int]]:
    """Indices of the datasets grouped by :func:`structure_key` (groups and members in first-seen order).

    Parameters
    ----------
    models : sequence of callable
        One NumPyro model per dataset.
    args_list : sequence of tuple
        Positional arguments of each model.
    kwargs_list : sequence of (dict or None) or None
        Keyword arguments of each model (None: none).

    Returns
    -------
    list of list of int
        Each group's dataset indices.
    """
    kwargs_list = [None] * len(models) if kwargs_list is None else kwargs_list
    groups: dict = {}
    for i, (m, a, k) in enumerate(zip(models, args_list, kwargs_list, strict=True)):
        groups.setdefault(structure_key(m, a, k), []).append(i)
    return list(groups.values())


def _same_leaf(a, b) -> bool:
    """Whether two data leaves are one array (the same object, or equal shapes, dtypes and values)."""
    if a is b:
        return True
    if np.shape(a) != np.shape(b) or np.asarray(a).dtype != np.asarray(b).dtype:
        return False
    return bool(np.array_equal(np.asarray(a), np.asarray(b)))


def _check_structures(flats: list[FlatModel]) -> None:
    """Raise :class:`BatchStructureError` unless every model has the first one's signature."""
    first = flats[0]
    if not first.data and len(flats) > 1:
        raise BatchStructureError(
            f"model {first.label!r} needs the concrete values of its arrays (its arguments cannot be traced), "
            "so its datasets cannot share one program: run them one by one with TMCMC.run")
    for i, flat in enumerate(flats[1:], start=1):
        if flat.signature == first.signature:
            continue
        part = next(name for name, a, b in zip(_SIGNATURE_PARTS, first.signature, flat.signature, strict=True)
                    if a != b)
        raise BatchStructureError(
            f"dataset {i} (model {flat.label!r}) differs from dataset 0 (model {first.label!r}) in its {part}; "
            "a batch needs one model function and argument pytrees of equal structure and array shapes "
            "(pad curves to one length with a mask), else run the groups of batch_groups() separately")


def _chunks(num: int, max_size: int) -> list[range]:
    """``range(num)`` in near-equal consecutive chunks of at most ``max_size``."""
    n_chunks = math.ceil(num / max_size)
    size = math.ceil(num / n_chunks)
    return [range(a, min(a + size, num)) for a in range(0, num, size)]


def run_batched(model: Callable | Sequence[Callable], args_list: Sequence[tuple],
                kwargs_list: Sequence[dict | None] | None, keys, *, batch_size: int | None = None,
                callback: Callable[[int, TMCMC], None] | None = None, **tmcmc_options) -> list[TMCMC]:
    """Run one TMCMC per dataset, the datasets of one model structure batched in one compiled program.

    Dataset ``i`` gets the result of ``TMCMC(model_i, compiled=True, **tmcmc_options).run(keys[i],
    *args_list[i], **kwargs_list[i])`` (to float round-off): samples, log evidence and its standard error over
    replicas, stage table, status, :meth:`~TMCMC.to_inference_data`, :meth:`~TMCMC.prior_log_likelihood`.

    Parameters
    ----------
    model : callable or sequence of callable
        One NumPyro model for every dataset, or one per dataset (e.g. ``functools.partial`` objects of one
        function with each dataset's arrays bound).
    args_list : sequence of tuple
        Positional arguments of each dataset's model (K entries).
    kwargs_list : sequence of (dict or None) or None
        Keyword arguments of each dataset's model (None: none).
    keys : sequence of jax.Array or jax.Array
        One PRNG key per dataset (as given to ``TMCMC.run``).
    batch_size : int or None
        Runs (dataset x replica) per program call; None: as many as keep runs x ``num_particles`` at most
        :data:`MAX_BATCH_PARTICLES`. The runs are split into near-equal chunks, the last padded with copies
        (one compiled program per chunk size).
    callback : callable or None
        ``callback(i, sampler)``: called for each dataset as soon as its batch has ended (e.g. to save it).
    **tmcmc_options
        Keyword arguments of :class:`TMCMC` (``num_particles``, ``target_cov``, ``num_replicas``, ``move``,
        ``chunk_size``, ``progress``, ...). ``compiled`` is accepted and has no effect: a batch is always the
        fused run. Stage rows reach a ``progress`` reporter when their batch has ended; every row's ``seconds``
        is its share of the batch's wall time (the batch's time divided among its runs, then among the stages).

    Returns
    -------
    list of TMCMC
        One finished sampler per dataset, in input order.

    Raises
    ------
    BatchStructureError
        If the datasets do not share one model structure (a ValueError).
    ValueError
        For mismatched list lengths, an invalid setting, or a dataset whose prior draws all have a non-finite
        log likelihood or log prior (the message names the dataset).
    """
    num = len(args_list)
    if num == 0:
        raise ValueError("run_batched needs at least one dataset")
    models = [model] * num if callable(model) else list(model)
    kwargs_list = [None] * num if kwargs_list is None else list(kwargs_list)
    keys = list(keys)
    for name, seq in (("models", models), ("kwargs_list", kwargs_list), ("keys", keys)):
        if len(seq) != num:
            raise ValueError(f"run_batched: {len(seq)} {name} for {num} datasets (args_list)")
    if batch_size is not None and (isinstance(batch_size, bool) or not isinstance(batch_size, int)
                                   or batch_size < 1):
        raise ValueError(f"batch_size must be an integer >= 1 or None, got {batch_size!r}")
    samplers = [TMCMC(m, **tmcmc_options) for m in models]
    first = samplers[0]
    flats = [FlatModel(m, a, k or {}, space=first.space, rng_key=key)
             for m, a, k, key in zip(models, args_list, kwargs_list, keys, strict=True)]
    _check_structures(flats)
    n, reps = first.num_particles, first.num_replicas
    # a leaf that is one array in every dataset (the weights of a shared network) is passed once
    axes = tuple(None if all(_same_leaf(f.data[j], flats[0].data[j]) for f in flats[1:]) else 0
                 for j in range(len(flats[0].data)))
    shared = tuple(jnp.asarray(v) for v in flats[0].data)
    device_data = [tuple(shared[j] if a is None else jnp.asarray(v) for j, (a, v) in enumerate(zip(axes, f.data,
                                                                                                strict=True)))
                   for f in flats]
    programs = _batched_programs(flats[0], first.move, first.config, first.max_stages, axes)

    runs = []  # (dataset, replica, draw key, run key): the keys of TMCMC.run's replicas
    for i, key in enumerate(keys):
        for r, replica_key in enumerate(jax.random.split(key, reps)):
            k_draw, k_run = jax.random.split(replica_key)
            runs.append((i, r, k_draw, k_run))
    chunks = _chunks(len(runs), batch_size or max(1, MAX_BATCH_PARTICLES // n))
    size = len(chunks[0])
    results: list[list] = [[None] * reps for _ in range(num)]
    for chunk in chunks:
        members = [runs[j] for j in chunk]
        padded = members + [members[-1]] * (size - len(members))  # one program shape for every chunk
        data = tuple(shared[j] if a is None else jnp.stack([device_data[m[0]][j] for m in padded])
                     for j, a in enumerate(axes))
        t0 = time.perf_counter()
        states = programs.init(jnp.stack([m[2] for m in padded]), data, n)
        finite = np.asarray(jnp.any(jnp.isfinite(states.log_likelihood) & jnp.isfinite(states.log_prior), axis=1))
        t_init = (time.perf_counter() - t0) / len(members)
        for b, (i, *_rest) in enumerate(members):
            if not finite[b]:
                raise ValueError(
                    f"TMCMC: all {n} prior draws of dataset {i} (model {flats[i].label!r}) have a non-finite log "
                    "likelihood or log prior (every particle is -inf): check the observed data, the likelihood's "
                    "support and any numpyro.factor terms")
        initial_ll = np.asarray(states.log_likelihood)
        t0 = time.perf_counter()
        states, infos, status = jax.device_get(programs.run(jnp.stack([m[3] for m in padded]), states, data))
        t_run = (time.perf_counter() - t0) / len(members)
        for b, (i, r, _k1, _k2) in enumerate(members):
            state = jax.tree_util.tree_map(lambda a, b=b: jnp.asarray(a[b]), states)
            rows = [first._initial_row(_Initial(initial_ll[b]), t_init)]
            results[i][r] = _replica_result(first, flats[i].label, r, state, rows,
                                            jax.tree_util.tree_map(lambda a, b=b: a[b], infos), int(status[b]), t_run)
        done = sorted({m[0] for m in members if all(res is not None for res in results[m[0]])})
        for i in done:
            _finish(samplers[i], flats[i], device_data[i], args_list[i], kwargs_list[i], results[i])
            if callback is not None:
                callback(i, samplers[i])
    return samplers


class _Initial(NamedTuple):
    """What the stage table's row 0 reads of a run's initial state."""

    log_likelihood: np.ndarray
    log_evidence: float = 0.0  # batched runs start from exact prior draws


def _replica_result(sampler: TMCMC, label: str, replica: int, state, rows: list, infos, status: int,
                    t_run: float) -> dict:
    """One replica's result dict (as ``TMCMC._run_replicas`` makes it, after row 0 ``rows``), warning when it
    did not converge."""
    stages = int(state.stage)
    for k in range(stages):
        rows.append(sampler._row(k + 1, jax.tree_util.tree_map(lambda a, k=k: a[k], infos), t_run / max(stages, 1)))
    status_name = STATUS_NAMES[status]
    if status_name != "converged":
        warnings.warn(
            f"TMCMC of model {label!r} (replica {replica}) stopped with status {status_name!r} at "
            f"beta={rows[-1]['beta']:.6g} after {stages} stages (max_stages={sampler.max_stages}, last "
            f"delta={rows[-1]['delta']:.3g}, min_delta={sampler.min_delta:g}); partial results are kept "
            "(log evidence covers only beta reached)", RuntimeWarning, stacklevel=4)
    return {"state": state, "stages": rows, "status": status_name, "log_evidence": float(state.log_evidence),
            "seconds": float(sum(row["seconds"] for row in rows))}


def _finish(sampler: TMCMC, flat: FlatModel, data: tuple, args: tuple, kwargs: dict | None, results: list) -> None:
    """Give ``sampler`` the state a finished ``TMCMC.run`` leaves, and replay its stage rows to its reporter."""
    sampler._flat = flat
    sampler._data = data
    sampler._model_args = (tuple(args), dict(kwargs or {}))
    sampler._samples_cache = None
    sampler._results = results
    report, close = stage_reporter(sampler.progress, f"TMCMC {flat.label}", sampler.num_replicas)
    try:
        for r, res in enumerate(results):
            for row in res["stages"]:
                report(r, row)
    finally:
        close()
