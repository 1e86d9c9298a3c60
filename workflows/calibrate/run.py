"""Running a calibration plan: the staged TMCMC phases or the joint NUTS run per agent, then summaries.

Per agent the datasets are its loading curves and, in the acoustic workflow, its acoustic datasets
(:func:`bubblecal.data.acoustic_datasets`). Staged (``docs/inference.md`` section 4): phase 1 samples each
dataset under the workflow's uniform priors, phase 2 the population ψ = (m_k, τ_k)
(:func:`bubblecal.models.phase2_model`), phase 3 every dataset under the learned population prior
(``population=`` of the single-dataset models, p0 divided out). Joint: :func:`bubblecal.models.hierarchical_model`
(non-centred) sampled by NUTS. Phases are stored and reused through
:class:`~bubblecal.workflows.calibrate.PhaseStore`.
"""

from __future__ import annotations

import functools
import time
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bubblecal.workflows.calibrate.agent_worker import late_modules
from bubblecal.workflows.calibrate.config import CalibrationConfig, agent_seed, phase2_samples, phase_tmcmc_options
from bubblecal.workflows.calibrate.device import on_device
from bubblecal.workflows.calibrate.export import PHASE2_LOGLIK, phase2_log_likelihood, phase_exports
from bubblecal.workflows.calibrate.imports import preload
from bubblecal.workflows.calibrate.joint import run_joint
from bubblecal.workflows.calibrate.plan import AgentPlan, Plan
from bubblecal.workflows.calibrate.store import PhaseStore, bundle_hashes, config_hash, phase_hashes

__all__ = ["AgentResult", "run_agent", "run_agent_with_report", "run_calibration"]


@dataclass
class AgentResult:
    """Everything one agent's run produced (files under ``plan.out_dir``).

    Parameters
    ----------
    plan : AgentPlan
    staged : bubblecal.inference.phase_results.StagedResult or None
        Phases 1, 2, 3 (``sampler='tmcmc'``).
    joint : bubblecal.workflows.calibrate.joint.JointResult or None
        The joint NUTS draws, log likelihood, seconds and diagnostics (``sampler='nuts'``).
    loglik : dict of str to ndarray
        Phase name -> log likelihood of every draw.
    summary : pandas.DataFrame or None
        ``summary.csv`` (see :mod:`bubblecal.workflows.summary`).
    ess : pandas.DataFrame or None
        ``ess.csv``: phase-2 importance-sampling ESS per dataset.
    population_predictive : dict of str to ndarray or None
        Population-predictive draws θ_new of the pooled parameters (DPD units).
    seconds : dict of str to float
        Wall time [s] per phase, of the sampling and of the summaries.
    reused : list of str
        Phases read back from disk instead of run.
    figures : list of Path
    report : Path or None
    evidence : object or None
    pointwise : dict
        Phase name -> observed site -> (draw, ...) pointwise log likelihood (phase 2: one column per dataset).
    bands : dict
        Dataset name -> predictive medians and 90 % bands at the data and on a dense grid (filled by the
        summaries, :func:`bubblecal.workflows.summary.summarise_agent`; read by the figures).
    """

    plan: AgentPlan
    staged: object | None
    joint: object | None
    loglik: dict[str, np.ndarray]
    summary: object
    ess: object | None
    population_predictive: dict[str, np.ndarray] | None
    seconds: dict[str, float]
    reused: list[str]
    figures: list[Path] = field(default_factory=list)
    report: Path | None = None
    evidence: object | None = None
    pointwise: dict = field(default_factory=dict)
    bands: dict = field(default_factory=dict)


def _curve_arguments(ap: AgentPlan, pad: bool | int) -> list[tuple[tuple, dict]]:
    """(args, kwargs) of :func:`bubblecal.models.mechanical_model` for every curve of the agent.

    The surrogate goes in as a :class:`~bubblecal.models.TracedSurrogate`, so its weights are arguments of the
    compiled TMCMC programs and curves whose networks have one shape share them. ``pad`` True pads (masks) them to
    the longest one (one program); an integer b to the next multiple of b points (a program per length bucket);
    False keeps every curve's own length.
    """
    from bubblecal.models import TracedSurrogate, pad_curve

    surrogates = [TracedSurrogate.wrap(s) for s in ap.surrogates]

    def shape_key(s):
        # curves can share programs when setup and layer sizes agree (other surrogates: never)
        if not isinstance(s, TracedSurrogate):
            return id(s)
        return s.setup, tuple(np.shape(a) for a in (*s.weights, *s.biases))

    length: dict = {}
    for curve, sur in zip(ap.curves, surrogates, strict=True):
        key = shape_key(sur)
        length[key] = max(length.get(key, 0), len(curve.x))
    out = []
    for curve, sur in zip(ap.curves, surrogates, strict=True):
        x, y = np.asarray(curve.x), np.asarray(curve.y)
        if pad is True:  # every curve of a group gets a mask (all True on the longest): one argument structure
            x, y, mask = pad_curve(x, y, length[shape_key(sur)])
            out.append(((x, y, sur, ap.spec), {"mask": mask}))
        elif pad:
            x, y, mask = pad_curve(x, y, -(-len(x) // int(pad)) * int(pad))
            out.append(((x, y, sur, ap.spec), {"mask": mask}))
        else:
            out.append(((x, y, sur, ap.spec), {}))
    return out


#: Points per length bucket of measured bubbles on CPU cores (``_pad_curves``).
LENGTH_BUCKET = 8


def _pad_curves(config: CalibrationConfig) -> bool | int:
    """Padding of the curves (``_curve_arguments``): one length on the GPU (compiling costs more than padded points);
    on CPU cores length buckets for measured bubbles (a few programs, not one per length), none for the published
    study (the particles dominate)."""
    if config.device == "gpu":
        return True
    return LENGTH_BUCKET if config.data is not None else False


def _acoustic_arguments(ap: AgentPlan) -> list[tuple]:
    """Positional arguments of :func:`bubblecal.models.acoustic_model` for every acoustic dataset: the
    surrogate's quadratics at the dataset's diameters as a :class:`~bubblecal.models.acoustic.FrequencyTable`
    (arrays, so datasets with as many bubbles share the compiled programs)."""
    from bubblecal.models.acoustic import FrequencyTable

    return [(np.asarray(ds.diameter_um, dtype=float), np.asarray(ds.frequency_MHz, dtype=float),
             FrequencyTable.at(ap.f_res, ds.diameter_um), ap.spec) for ds in ap.acoustic]


def _dataset_objects(ap: AgentPlan, pad: bool = False):
    """The agent's datasets as :class:`bubblecal.inference.hierarchical.Dataset` (curves, then acoustic)."""
    from bubblecal.inference.hierarchical import Dataset
    from bubblecal.models import acoustic_model, mechanical_model

    out = []
    for curve, (args, kwargs) in zip(ap.curves, _curve_arguments(ap, pad), strict=True):
        out.append(Dataset(curve.name, mechanical_model, args, kwargs))
    for ds, args in zip(ap.acoustic, _acoustic_arguments(ap), strict=True):
        out.append(Dataset(ds.name, acoustic_model, args))
    return out


def run_agent(plan: Plan, ap: AgentPlan, *, progress: Callable[[str], None] | None = None,
              inject: Callable[[str], None] | None = None,
              stages: Callable[[int, Mapping], None] | None = None, report: bool = False) -> AgentResult:
    """Run one agent (staged TMCMC or joint NUTS), then its summaries; writes ``manifest.json`` throughout.

    Parameters
    ----------
    plan : Plan
        The validated run (:func:`~bubblecal.workflows.calibrate.make_plan`).
    ap : AgentPlan
        One of ``plan.agents``.
    progress : callable or None
        Receives one-line progress messages.
    inject : callable or None
        Called with the phase name before each phase runs (tests inject crashes through it).
    stages : callable or None
        ``stages(replica, row)``: each TMCMC stage of each phase (the ``progress`` reporter of
        :class:`~bubblecal.inference.TMCMC`; row = stage, beta, ess, acceptance, log_evidence, ...).
    report : bool
        Also draw the figures and write ``report.md`` when ``config.figures`` is on (while the phase files are
        still being written; on a GPU run with 8 or more cores, in figure processes side by side,
        :class:`~bubblecal.workflows.calibrate.FigureProcesses`; :func:`run_agent_with_report`).

    Returns
    -------
    AgentResult
        With ``summary``, ``ess`` and the population predictive filled unless ``config.summaries`` and
        ``config.figures`` are both off; ``figures`` and ``report`` with ``report``. Every phase file is
        complete and in ``manifest.json`` when it returns.

    Raises
    ------
    RuntimeError
        A phase failed (finished phases stay on disk and are reused on rerun).
    """
    drawers = _figure_drawers(plan.config) if report and plan.config.figures else None
    try:
        return _run_agent(plan, ap, progress, inject, stages, report, drawers)
    finally:
        if drawers is not None:
            drawers.close()


def _figure_drawers(config: CalibrationConfig):
    """Figure processes of a run that has them (:func:`~bubblecal.workflows.calibrate.figure_processes.
    drawing_processes`; started ahead, so their imports overlap the phases); None: the agent draws its figures."""
    from bubblecal.workflows.calibrate.figure_processes import FigureProcesses, drawing_processes

    n = drawing_processes(config.device)
    return FigureProcesses(n) if n else None


def _run_agent(plan: Plan, ap: AgentPlan, progress, inject, stages, report: bool, drawers) -> AgentResult:
    """The body of :func:`run_agent`; ``drawers``: the figure processes (or None)."""
    import jax

    from bubblecal.inference.hierarchical import run_staged

    config = plan.config
    say = progress or (lambda _m: None)
    ap.out_dir.mkdir(parents=True, exist_ok=True)
    run_info = {"config": config.as_dict(), "config_hash": config_hash(config.as_dict()), "agent": ap.agent,
                "priors": str(ap.priors_path), "bundle": str(plan.bundle_path),
                "synthetic_bundle": plan.synthetic_bundle}
    # phase files are written while the next phase samples (flushed before anything reads them)
    store = PhaseStore(ap.out_dir, netcdf=config.netcdf, force=config.force, run_info=run_info, say=say,
                       background=True)
    store.expected = phase_hashes(ap, config, bundle_hashes(plan.bundle))
    store.write_manifest()
    seconds: dict[str, float] = {}
    t_start = time.perf_counter()
    staged = joint = None
    key = jax.random.PRNGKey(agent_seed(config.seed, ap.agent))

    if config.sampler == "tmcmc":
        from bubblecal.models import POPULATION_SITE

        phase2_model_factory, phase3_factory, datasets = _phase_models(ap, config)
        store.exports.update(phase_exports(ap, datasets))

        def phase2_factory(samples, names):
            # phase 2's likelihood is a factor: its pointwise log likelihood per dataset is computed from the
            # phase-1 draws it was given
            store.pointwise_fns["phase2"] = lambda r: {PHASE2_LOGLIK: phase2_log_likelihood(r.samples, samples,
                                                                                            ap.spec)}
            return phase2_model_factory(samples, names)

        def load(name):
            result = store.load(name)
            if result is None:
                store.start_writers()  # a phase will run: the writers start while its programs load
                if drawers is not None:
                    drawers.start()
                if inject is not None:
                    inject(name)
            return result

        o1, o23 = phase_tmcmc_options(config)
        if stages is not None:  # after the phase hashes: a display is no setting of the run
            o1, o23 = {**o1, "progress": stages}, {**o23, "progress": stages}
        with on_device(config.device), warnings.catch_warnings():
            warnings.simplefilter("ignore", category=FutureWarning)
            reweight = None
            if config.phase3 == "exact":
                from bubblecal.models.staged import leave_one_out_log_weights, pooled_bounds

                bounds = pooled_bounds(ap.spec)

                def reweight(i, phase1_i, m_samples, tau_samples):
                    return leave_one_out_log_weights(m_samples, tau_samples, phase1_i, bounds)

            try:
                staged = run_staged(datasets, phase2_factory, phase3_factory, key, phase1_options=o1,
                                    phase2_options=o23, phase3_options=o23,
                                    phase2_max_samples=phase2_samples(config, len(datasets)), load=load,
                                    save=store.save, progress=say, phase3_reweight=reweight,
                                    phase3_tempered=(POPULATION_SITE,) if config.phase3_start == "phase1" else None)
            except BaseException:  # a failing phase still leaves the finished ones on disk and in the manifest
                store.flush()
                raise
            if staged.phase3_ess:
                say("phase 3 leave-one-out importance ESS: "
                    + ", ".join(f"{k} {v:.0f}" for k, v in staged.phase3_ess.items()))
        for r in [*staged.phase1, staged.phase2, *staged.phase3]:
            seconds[r.name] = r.seconds
    else:
        joint = run_joint(ap, config, key, store, say)
        seconds["joint_nuts"] = joint.seconds
    seconds["sampling_total"] = time.perf_counter() - t_start
    store.close_soon()  # every phase is saved: the writer processes end once their files are written

    # summaries, figures and report read the draws in memory: they run while the writers finish the phase files
    try:
        t0 = time.perf_counter()
        result = AgentResult(plan=ap, staged=staged, joint=joint, loglik=store.loglik, summary=None, ess=None,
                             population_predictive=None, seconds=seconds, reused=list(store.reused),
                             pointwise=store.pointwise)
        if config.summaries or config.figures:  # (figure processes come with config.figures)
            preload(late_modules(config.device))  # pandas (and matplotlib) complete, whoever started importing them
            if drawers is not None:  # the figures of the phases alone start now
                from bubblecal.workflows.figures import PHASE_FIGURES, figure_jobs

                drawers.submit(result, plan, figure_jobs(result, PHASE_FIGURES))
            from bubblecal.workflows.summary import summarise_agent

            summarise_agent(result, config)
        seconds["summaries"] = time.perf_counter() - t0
        if report and config.figures:
            from bubblecal.workflows.figures import agent_figures
            from bubblecal.workflows.report import write_report

            result.figures = agent_figures(result, plan, processes=drawers)
            result.report = write_report(result, plan)
    finally:
        store.flush()
    store.manifest["summary"] = {"wall_seconds": seconds, "reused": store.reused}
    store.write_manifest()
    return result


def _phase_models(ap: AgentPlan, config: CalibrationConfig):
    """(phase-2 model factory, phase-3 model factory, datasets) of the staged run."""
    from bubblecal.models import acoustic_model, mechanical_model, phase2_model

    datasets = _dataset_objects(ap, _pad_curves(config))
    curve_arguments = [(d.args, d.kwargs) for d in datasets[:len(ap.curves)]]
    acoustic_arguments = [d.args for d in datasets[len(ap.curves):]]
    n_curves = len(ap.curves)

    # partials, not lambdas: their arrays reach TMCMC as arguments, so the phase programs are
    # compiled once per model structure and shared by datasets (and agents) of that structure
    def phase2_factory(samples, names):
        return functools.partial(phase2_model, samples, ap.spec, names)

    def phase3_factory(i, m_samples, tau_samples):
        # the phase-3 prior log mean_s p(θ | ψ_s) costs S densities per particle: thin ψ to the
        # phase-2 sample size (deterministic, evenly spaced draws)
        n_psi = phase2_samples(config)
        size = len(next(iter(m_samples.values())))
        idx = np.linspace(0, size - 1, min(size, n_psi)).round().astype(int)
        pop = ({k: np.asarray(v)[idx] for k, v in m_samples.items()},
               {k: np.asarray(v)[idx] for k, v in tau_samples.items()})
        if i < n_curves:
            args, kwargs = curve_arguments[i]
            return functools.partial(mechanical_model, *args, **kwargs, population=pop)
        return functools.partial(acoustic_model, *acoustic_arguments[i - n_curves], population=pop)

    return phase2_factory, phase3_factory, datasets


def run_calibration(plan: Plan, *, progress: Callable[[str], None] | None = None,
                    inject: Callable[[str], None] | None = None) -> list[AgentResult]:
    """Run every agent of ``plan`` (see :func:`run_agent`), then its figures and ``report.md``.

    Parameters
    ----------
    plan : Plan
    progress, inject : callable or None
        As in :func:`run_agent`.

    Returns
    -------
    list of AgentResult
        One per agent, in ``plan.agents`` order.

    Raises
    ------
    RuntimeError
        A phase failed (see :func:`run_agent`).
    CalibrationError
        Another run holds the output folder's lock (:func:`~bubblecal.workflows.calibrate.run_lock`).
    """
    from bubblecal.workflows.calibrate.lock import run_lock

    with run_lock(Path(plan.config.out), say=progress):
        return [run_agent_with_report(plan, ap, progress=progress, inject=inject) for ap in plan.agents]


def run_agent_with_report(plan: Plan, ap: AgentPlan, *, progress: Callable[[str], None] | None = None,
                          inject: Callable[[str], None] | None = None,
                          stages: Callable[[int, Mapping], None] | None = None) -> AgentResult:
    """:func:`run_agent`, then the agent's figures and ``report.md`` when ``plan.config.figures`` is on.

    Parameters
    ----------
    plan, ap, progress, inject, stages
        As in :func:`run_agent`.

    Returns
    -------
    AgentResult
        With ``figures`` and ``report`` set when drawn.

    Raises
    ------
    RuntimeError
        A phase failed (see :func:`run_agent`).
    """
    return run_agent(plan, ap, progress=progress, inject=inject, stages=stages, report=True)
