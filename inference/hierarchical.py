"""Staged (Korali-style) hierarchical inference driven by TMCMC, and its comparison with a joint run.

The method is ``docs/inference.md`` section 4. Physics-free: the caller supplies NumPyro models
(``bubblecal.models`` builds them).

* Phase 1: every dataset's posterior under its own uniform prior — :class:`Dataset` entries.
* Phase 2: the hyperparameters ψ, from a model built out of the phase-1 samples
  (``phase2_factory(samples_per_dataset) -> model``); its deterministic sites ``is_ess_<name>`` hold
  the importance-sampling effective sample size of every dataset at each ψ draw.
* Phase 3: each dataset again, under the learned population prior
  (``phase3_factory(index, m_samples, tau_samples) -> model``); with ``phase3_tempered`` the run starts
  from the dataset's phase-1 posterior and tempers only the population-prior factor (same posterior and
  evidence, a fraction of the stages).

``load``/``save`` hooks reuse finished phases (resumable runs) and persist each phase as it ends.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import jax
import numpy as np

from bubblecal.inference._phase_batch import run_phases
from bubblecal.inference.phase_results import ESS_PREFIX, PhaseResult, StagedResult, ess_table, phase_draws
from bubblecal.inference.tmcmc import TMCMC

__all__ = ["Dataset", "PhaseResult", "StagedResult", "run_phase", "run_staged", "ess_table", "ESS_PREFIX"]

@dataclass(frozen=True)
class Dataset:
    """One dataset's phase-1 model: ``model(*args, **kwargs)`` under its uniform prior.

    Parameters
    ----------
    name : str
        Dataset name (unique; the phases are named ``phase1_<name>``, ``phase3_<name>``).
    model : callable
        NumPyro model.
    args : tuple
        Positional arguments of the model.
    kwargs : mapping
        Keyword arguments of the model.
    """

    name: str
    model: Callable
    args: tuple = ()
    kwargs: Mapping[str, Any] = field(default_factory=dict)


def run_phase(name: str, model: Callable, args: tuple, kwargs: Mapping, rng_key, tmcmc_options: Mapping,
              start: Callable[[int], Mapping] | None = None) -> PhaseResult:
    """Run TMCMC on one phase's model.

    Parameters
    ----------
    name : str
        Phase name.
    model : callable
        NumPyro model, run as ``model(*args, **kwargs)``.
    args : tuple
        Positional arguments of the model.
    kwargs : mapping
        Keyword arguments of the model.
    rng_key : jax.Array
        PRNG key of the run.
    tmcmc_options : mapping
        Keyword arguments of :class:`~bubblecal.inference.tmcmc.TMCMC`.
    start : callable or None
        ``start(num_particles) -> {"init_samples": ..., "init_log_evidence": ...}``, arguments of
        :meth:`~bubblecal.inference.tmcmc.TMCMC.run` for a run that starts from a base density's draws; None:
        exact prior draws.

    Returns
    -------
    PhaseResult

    Raises
    ------
    RuntimeError
        If TMCMC did not reach β = 1.
    """
    t0 = time.perf_counter()
    sampler = TMCMC(model, **dict(tmcmc_options))
    sampler.run(rng_key, *args, **(start(sampler.num_particles) if start is not None else {}), **dict(kwargs))
    result = _phase_result(name, sampler, time.perf_counter() - t0)
    _check_converged(result)
    return result


def _phase_result(name: str, sampler: TMCMC, seconds: float) -> PhaseResult:
    """The :class:`PhaseResult` of a finished sampler."""
    return PhaseResult(name=name, samples=sampler.get_samples(), log_evidence=float(sampler.log_evidence),
                       log_evidence_se=float(sampler.log_evidence_se), status=sampler.status, seconds=seconds,
                       sampler=sampler)


def _check_converged(result: PhaseResult) -> None:
    """RuntimeError for a phase whose TMCMC did not reach β = 1."""
    if result.status != "converged":
        raise RuntimeError(f"phase {result.name!r}: TMCMC ended with status {result.status!r} before reaching "
                           "beta = 1; increase max_stages or the number of particles")


def run_staged(
    datasets: Sequence[Dataset],
    phase2_factory: Callable[[list[dict[str, np.ndarray]], list[str]], Callable],
    phase3_factory: Callable[[int, dict[str, np.ndarray], dict[str, np.ndarray]], Callable],
    rng_key,
    *,
    phase1_options: Mapping | None = None,
    phase2_options: Mapping | None = None,
    phase3_options: Mapping | None = None,
    phase2_max_samples: int | None = None,
    phase3_reweight: Callable[[int, dict, dict, dict], np.ndarray] | None = None,
    phase3_tempered: Sequence[str] | None = None,
    load: Callable[[str], PhaseResult | None] | None = None,
    save: Callable[[PhaseResult], None] | None = None,
    progress: Callable[[str], None] | None = None,
    batch: bool = False,
    batch_size: int | None = None,
) -> StagedResult:
    """Run phases 1 → 2 → 3 with TMCMC (see the module docstring).

    Parameters
    ----------
    datasets : sequence of Dataset
        The phase-1 models (unique names).
    phase2_factory : callable
        ``phase2_factory(samples, names) -> model``: receives each dataset's phase-1 samples (thinned
        to ``phase2_max_samples`` draws) and returns the phase-2 model.
    phase3_factory : callable
        ``phase3_factory(i, m_samples, tau_samples) -> model`` (dicts parameter -> (S,) draws of ψ):
        dataset i's phase-3 model with the dataset's data bound.
    rng_key : jax.Array
        PRNG key (split into one key per phase).
    phase1_options, phase2_options, phase3_options : mapping or None
        :class:`~bubblecal.inference.tmcmc.TMCMC` keyword arguments of each phase (published:
        N = 50,000, target CoV 0.8 in phase 1, 0.6 in phases 2 and 3).
    phase2_max_samples : int or None
        Thin each phase-1 sample set to at most this many draws (deterministic, evenly spaced): phase 2
        costs Σ_i N_i population densities per ψ.
    phase3_reweight : callable or None
        ``phase3_reweight(i, phase1_samples_i, m_samples, tau_samples) -> (S,)`` normalised log
        weights of the phase-2 draws: phase 3 of dataset i then uses the draws resampled by those
        weights. With :func:`bubblecal.models.leave_one_out_log_weights` they are draws of
        p(ψ | D_{-i}), so Θ_i's posterior is the joint model's marginal rather than the published
        Korali phase 3, which counts D_i twice (importance ESS per dataset in
        ``StagedResult.phase3_ess``; the phase names stay ``phase3_<name>``, so a ``load`` that reuses
        phases must tell the two variants apart). None (default): the published phase 3.
    phase3_tempered : sequence of str or None
        The factor sites through which each phase-3 model adds its population prior (e.g.
        ``("population_prior",)``), where the model without them is the dataset's phase-1 model: phase 3 then
        starts from the dataset's phase-1 draws and tempers only those sites (``TMCMC(tempered=...)``, log
        evidence offset by phase 1's), the same posterior and evidence as tempering the likelihood and the
        factor together from the uniform prior, in fewer stages (``docs/inference.md`` section 4). None
        (default): phase 3 starts from the uniform prior, as Korali's.
    load : callable or None
        ``load(name) -> PhaseResult | None``: a stored result to reuse.
    save : callable or None
        ``save(result)``: persists each finished phase.
    progress : callable or None
        ``progress(message)``: reports.
    batch : bool
        Run the phase-1 datasets (and the phase-3 datasets) of one model structure (one model function,
        argument pytrees of equal structure and array shapes: the caller pads) in one compiled program each
        (:func:`~bubblecal.inference.tmcmc.run_batched`; the fused run, as ``compiled=True``); stored phases
        are reused, each finished one is saved and reported. Phase 2 is one run over all datasets either way.
    batch_size : int or None
        Runs per compiled program with ``batch`` (default: bounded by the particles, see ``run_batched``).

    Returns
    -------
    StagedResult

    Raises
    ------
    ValueError
        For no datasets or duplicate names.
    RuntimeError
        If a phase's TMCMC did not reach β = 1.
    """
    if not datasets:
        raise ValueError("run_staged needs at least one dataset")
    names = [d.name for d in datasets]
    if len(set(names)) != len(names):
        raise ValueError(f"dataset names must be unique, got {names}")
    say = progress or (lambda _msg: None)
    keys = jax.random.split(rng_key, 2 * len(datasets) + 1)

    def _fresh(name, model, args, kwargs, key, start, options):
        say(f"{name}: running TMCMC" + (" from its phase-1 draws" if start else ""))
        result = run_phase(name, model, args, kwargs, key, options or {}, start)
        if save is not None:
            save(result)
        say(f"{name}: log Z = {result.log_evidence:.3f}, {result.seconds:.1f} s")
        return result

    def _run_all(jobs, options, batched=batch):
        return run_phases(jobs, options, batch=batched, batch_size=batch_size, load=load, run_one=_fresh,
                          result_of=_phase_result, check=_check_converged, save=save, say=say)

    phase1 = _run_all([(f"phase1_{d.name}", d.model, d.args, d.kwargs, keys[i], None)
                       for i, d in enumerate(datasets)], phase1_options)
    thinned = [_thin(r.samples, phase2_max_samples) for r in phase1]
    phase2, = _run_all([("phase2", phase2_factory(thinned, names), (), {}, keys[len(datasets)], None)],
                       phase2_options, batched=False)
    m_samples = {k.removeprefix("m_"): v for k, v in phase2.samples.items() if k.startswith("m_")}
    tau_samples = {k.removeprefix("tau_"): v for k, v in phase2.samples.items() if k.startswith("tau_")}
    reweight_ess: dict[str, float] = {}

    def _population(i: int):
        if phase3_reweight is None:
            return m_samples, tau_samples
        lw = np.asarray(phase3_reweight(i, thinned[i], m_samples, tau_samples), dtype=np.float64)
        w = np.exp(lw - np.max(lw))
        w = w / w.sum()
        reweight_ess[names[i]] = float(1.0 / np.sum(w * w))
        # resample S draws (seeded by the phase's key): phase 3's population prior stays an equal-weight mean
        seed = int(np.asarray(jax.random.key_data(keys[len(datasets) + 1 + i])).ravel()[-1])
        idx = np.random.default_rng(seed).choice(w.size, size=w.size, p=w)
        return ({k: np.asarray(v)[idx] for k, v in m_samples.items()},
                {k: np.asarray(v)[idx] for k, v in tau_samples.items()})

    if phase3_tempered is not None:
        phase3_options = {**dict(phase3_options or {}), "tempered": tuple(phase3_tempered)}
    jobs3 = []
    for i, d in enumerate(datasets):
        m_i, tau_i = _population(i)
        start = None if phase3_tempered is None else functools.partial(_phase1_start, phase1[i])
        jobs3.append((f"phase3_{d.name}", phase3_factory(i, m_i, tau_i), (), {}, keys[len(datasets) + 1 + i],
                      start))
    phase3 = _run_all(jobs3, phase3_options)
    return StagedResult(phase1=phase1, phase2=phase2, phase3=phase3, phase3_ess=reweight_ess,
                        phase2_max_samples=phase2_max_samples)


def _phase1_start(phase1: PhaseResult, num: int) -> dict[str, Any]:
    """``TMCMC.run`` arguments that start a run from ``num`` of phase 1's equal-weight draws (evenly spaced, so
    repeated only where phase 1 holds fewer) with phase 1's log evidence."""
    size = phase_draws(phase1)
    idx = np.linspace(0, size - 1, num).round().astype(int)
    return {"init_samples": {k: np.asarray(v)[idx] for k, v in phase1.samples.items()},
            "init_log_evidence": float(phase1.log_evidence)}


def _thin(samples: Mapping[str, np.ndarray], max_samples: int | None) -> dict[str, np.ndarray]:
    """At most ``max_samples`` evenly spaced draws."""
    n = int(next(iter(samples.values())).shape[0])
    if max_samples is None or n <= max_samples:
        return dict(samples)
    index = np.linspace(0, n - 1, max_samples).round().astype(int)  # deterministic thinning keeps stratification
    return {k: np.asarray(v)[index] for k, v in samples.items()}
