"""The per-dataset phases of a staged hierarchy: reused, run one by one, or batched.

Private helper of :func:`bubblecal.inference.hierarchical.run_staged`: the phases already stored are reused;
the phases that run one by one have their programs compiled together first (several at a time,
:func:`bubblecal.inference.tmcmc.compile_ahead`); with ``batch=True`` the others are grouped by model structure
(:func:`bubblecal.inference.tmcmc.batch_groups`) and each group of two or more runs through
:func:`bubblecal.inference.tmcmc.run_batched`; a lone dataset (or a group whose models turn out not to share one
program) runs one by one as without ``batch``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

from bubblecal.inference.tmcmc import TMCMC, BatchStructureError, RunSpec, batch_groups, compile_ahead, run_batched


def run_phases(jobs: Sequence[tuple], options: Mapping | None, *, batch: bool, batch_size: int | None,
               load: Callable[[str], object | None] | None, run_one: Callable[..., object],
               result_of: Callable[[str, object, float], object], check: Callable[[object], None],
               save: Callable[[object], None] | None, say: Callable[[str], None]) -> list:
    """Run the phase ``jobs`` (``(name, model, args, kwargs, key)``) not stored yet, one by one or batched.

    Parameters
    ----------
    jobs : sequence of tuple
        ``(phase name, model, args, kwargs, PRNG key, start)`` per dataset; ``start`` (None, or a run that starts
        from given draws: see :func:`~bubblecal.inference.hierarchical.run_phase`) runs one by one.
    options : mapping or None
        Keyword arguments of :class:`~bubblecal.inference.tmcmc.TMCMC`.
    batch : bool
        Batch the jobs of one model structure (else run each with ``run_one``).
    batch_size : int or None
        Runs per compiled program call (see :func:`~bubblecal.inference.tmcmc.run_batched`).
    load : callable or None
        ``load(name) -> PhaseResult | None``: a stored result to reuse.
    run_one : callable
        ``run_one(name, model, args, kwargs, key, start, options) -> PhaseResult``: one phase on its own (saved
        and reported there).
    result_of : callable
        ``result_of(name, sampler, seconds) -> PhaseResult`` of a finished sampler.
    check : callable
        ``check(result)``: raises RuntimeError for a phase that did not converge.
    save : callable or None
        ``save(result)``: persists a finished phase (each as soon as its batch has ended).
    say : callable
        Receives the progress messages.

    Returns
    -------
    list of PhaseResult
        In the order of ``jobs``.

    Raises
    ------
    RuntimeError
        If a phase's TMCMC did not reach β = 1 (after its group ran; its converged members are saved).
    """
    options = dict(options or {})
    results: list = [load(job[0]) if load is not None else None for job in jobs]
    for job, cached in zip(jobs, results, strict=True):
        if cached is not None:
            say(f"{job[0]}: reused (log Z = {cached.log_evidence:.3f})")
    alone = [j for j, r in enumerate(results) if r is None and (not batch or jobs[j][5] is not None)]
    _compile_ahead([jobs[j] for j in alone], options)
    for j in alone:  # in order, one by one
        results[j] = run_one(*jobs[j], options)
    pending = [j for j, r in enumerate(results) if r is None]
    groups = batch_groups([jobs[j][1] for j in pending], [jobs[j][2] for j in pending],
                          [jobs[j][3] for j in pending])
    for group in groups:
        members = [pending[g] for g in group]
        if len(members) > 1:
            try:
                _run_group(jobs, members, options, batch_size, results, result_of, check, save, say)
                continue
            except BatchStructureError as exc:
                say(f"{jobs[members[0]][0]} and {len(members) - 1} more: not batched ({exc}); running TMCMC")
        for j in members:
            results[j] = run_one(*jobs[j], options)
    return results


def _compile_ahead(jobs: Sequence[tuple], options: Mapping) -> None:
    """Compile the programs of the one-by-one ``jobs`` (and of their exports) together, several at a time
    (:func:`~bubblecal.inference.tmcmc.compile_ahead`): their runs then compile nothing."""
    specs = []
    for _name, model, args, kwargs, key, start in jobs:
        sampler = TMCMC(model, **options)
        init = start(sampler.num_particles)["init_samples"] if start is not None else None
        specs.append(RunSpec(sampler, key, args, kwargs, init))
    compile_ahead(specs)


def _run_group(jobs, members, options, batch_size, results, result_of, check, save, say) -> None:
    """One group of one structure through :func:`run_batched`; fills ``results`` and saves each as it ends."""
    failed = []
    for j in members:
        say(f"{jobs[j][0]}: running TMCMC (batch of {len(members)})")

    def done(i, sampler):
        j = members[i]
        name = jobs[j][0]
        seconds = float(sum(res["seconds"] for res in sampler._results))
        result = results[j] = result_of(name, sampler, seconds)
        if result.status != "converged":
            failed.append(result)
            return
        if save is not None:
            save(result)
        say(f"{name}: log Z = {result.log_evidence:.3f}, {result.seconds:.1f} s (share of a batch of "
            f"{len(members)})")

    run_batched([jobs[j][1] for j in members], [jobs[j][2] for j in members], [jobs[j][3] for j in members],
                [jobs[j][4] for j in members], batch_size=batch_size, callback=done, **options)
    if failed:
        check(failed[0])
