"""The ``bubblecal calibrate`` main job: staged hierarchy per agent on the shipped data, priors and surrogates.

Pipeline (``docs/inference.md`` sections 4 and 7)::

    config = CalibrationConfig(agents=("definity", "sonovue"), workflow="reduced-acoustic", out=Path("calibration"))
    plan = make_plan(config)          # validates EVERYTHING before any sampling (CalibrationError otherwise)
    results = run_calibration(plan)   # phases 1 -> 2 -> 3 per agent, summaries, figures, report.md

Modules: :mod:`~bubblecal.workflows.calibrate.config` (settings and defaults),
:mod:`~bubblecal.workflows.calibrate.plan` (validation and inputs), :mod:`~bubblecal.workflows.calibrate.store`
(phase files, manifest, config hashes), :mod:`~bubblecal.workflows.calibrate.run` (the samplers; the joint NUTS run in
:mod:`~bubblecal.workflows.calibrate.joint`),
:mod:`~bubblecal.workflows.calibrate.published` (the published study's inputs),
:mod:`~bubblecal.workflows.calibrate.user_data` (measured bubbles from tidy files: ``data=CURVES.csv``),
:mod:`~bubblecal.workflows.calibrate.device` (the JAX device, the host's cores and the helper processes they allow),
:mod:`~bubblecal.workflows.calibrate.figure_processes` (figures drawn side by side),
:mod:`~bubblecal.workflows.calibrate.lock` (one run per output folder),
:mod:`~bubblecal.workflows.calibrate.imports` (libraries imported in the background, one thread at a time),
:mod:`~bubblecal.workflows.calibrate.preflight` (the likelihood at prior draws),
:mod:`~bubblecal.workflows.calibrate.served` (which surrogate served each dataset, in words),
:mod:`~bubblecal.workflows.calibrate.parallel` (agents calibrated at once in worker processes, whose body is
:mod:`~bubblecal.workflows.calibrate.agent_worker`).

Measured bubbles: ``CalibrationConfig(data=Path("curves.csv"), acoustic_data=Path("resonance.csv"))`` runs one
hierarchy per agent label of the file (``out/<label>/<workflow>/``).

Output, under ``out/<agent>/<workflow>/``:

* ``phase1_<dataset>.nc``, ``phase2.nc``, ``phase3_<dataset>.nc`` (ArviZ NetCDF; ``.npz`` when
  ``netcdf=False``, e.g. on a machine without ArviZ), each written atomically (temp file + rename) as soon
  as the phase ends; ``joint_nuts.nc`` for NUTS;
* ``manifest.json``: the configuration, its hash and per phase the config hash, log Z, status, wall time.
  A phase whose file exists and whose hash matches is reused on rerun (``force=True`` reruns all); a damaged
  phase file is named and that phase is recomputed with the phases that depend on it. The
  hash of a phase covers its data, priors, surrogate, sampler settings, seed and the hashes of the
  phases it depends on;
* ``summary.csv`` (see :mod:`bubblecal.workflows.summary`), ``ess.csv``, ``figures/*.png``, ``report.md``.

Units: DPD inside; summaries add physical units (E [MPa] from k_a, κ [k_BT] from k_b, d0 [nm], CRPS in
nN for compression / nm for indentation / MHz for acoustics) through :mod:`bubblecal.data.units`.
MAP = the posterior draw with the largest log likelihood + log prior; every prior of the staged phases is
uniform (the phase-3 population prior is a likelihood factor), so this is the largest stored log likelihood.
"""

from bubblecal._lazy import by_module, lazy_exports
from bubblecal.workflows.calibrate.agent_worker import (
    LATE_MODULES,
    RUN_MODULES,
    AgentHeader,
    AgentOutcome,
    late_modules,
    outcome_of,
)
from bubblecal.workflows.calibrate.config import (
    DEFAULT_PHASE2_SAMPLES,
    DEFAULT_POPULATION,
    DEVICES,
    MIN_PARTICLES,
    MIN_PHASE2_SAMPLES,
    NETWORKS,
    PAPER_COV,
    PAPER_COV_SCALE,
    PAPER_POPULATION,
    PARTICLES_PER_DIMENSION,
    PHASE2_DRAW_BUDGET,
    PHASE3_STARTS,
    PHASE3_TARGETS,
    SAMPLERS,
    SURROGATE_CHOICES,
    WORKFLOWS,
    CalibrationConfig,
    CalibrationError,
    agent_seed,
    config_from_agents,
    min_population,
    phase2_samples,
    phase_tmcmc_options,
)
from bubblecal.workflows.calibrate.device import (
    HELPER_PROCESS_MIN_CPUS,
    HELPER_PROCESSES,
    check_device,
    helper_processes,
    on_device,
    usable_cores,
)
from bubblecal.workflows.calibrate.figure_processes import FigureProcesses, drawing_processes
from bubblecal.workflows.calibrate.imports import import_turn, library, preload, preload_soon
from bubblecal.workflows.calibrate.lock import LOCK_NAME, run_lock
from bubblecal.workflows.calibrate.parallel import (
    MAX_AUTO_JOBS,
    AgentProcesses,
    agent_groups,
    agent_jobs,
    gpu_memory_shared,
)
from bubblecal.workflows.calibrate.writer import PhaseWriter

#: Exported name -> defining module, imported on first access: the configuration, the device, the lock and the
#: worker processes load no JAX, so the CLI starts (and spawns its workers) before JAX is imported.
_LAZY = by_module({
    "bubblecal.workflows.calibrate.export": ("PHASE2_LOGLIK", "joint_export", "phase2_log_likelihood",
        "phase2_pareto_k", "phase_exports"),
    "bubblecal.workflows.calibrate.phase_files": ("PhaseFileError", "phase_format", "phase_inference_data",
        "phase_inference_parts", "read_phase", "read_pointwise", "write_phase"),
    "bubblecal.workflows.calibrate.plan": ("AgentPlan", "Plan", "make_plan", "resolve_bundle", "run_config",
        "run_plan"),
    "bubblecal.workflows.calibrate.run": ("AgentResult", "run_agent", "run_agent_with_report", "run_calibration"),
    "bubblecal.workflows.calibrate.served": ("acoustic_label", "served_lines", "surrogate_label"),
    "bubblecal.workflows.calibrate.store": ("PhaseStore", "array_hash", "bundle_hashes", "config_hash",
        "phase_dependencies", "phase_hashes"),
    "bubblecal.workflows.calibrate.user_data": ("PRIORS_FOR_ALL", "user_agent_plans"),
})

__all__ = [
    "WORKFLOWS", "SAMPLERS", "PHASE3_TARGETS", "PHASE3_STARTS", "DEVICES", "NETWORKS", "SURROGATE_CHOICES",
    "DEFAULT_POPULATION", "PAPER_POPULATION", "PAPER_COV",
    "PAPER_COV_SCALE", "PARTICLES_PER_DIMENSION", "MIN_PARTICLES", "DEFAULT_PHASE2_SAMPLES",
    "PHASE2_DRAW_BUDGET", "MIN_PHASE2_SAMPLES",
    "CalibrationError", "CalibrationConfig", "config_from_agents", "phase_tmcmc_options", "phase2_samples",
    "min_population", "check_device", "on_device", "usable_cores",
    "AgentPlan", "Plan", "make_plan", "run_config", "run_plan", "resolve_bundle", "LOCK_NAME", "run_lock",
    "PhaseStore", "PhaseFileError", "phase_dependencies",
    "write_phase", "phase_inference_data", "phase_inference_parts", "read_phase", "read_pointwise", "phase_format",
    "config_hash", "array_hash", "phase_hashes", "bundle_hashes",
    "AgentResult", "agent_seed", "run_agent", "run_agent_with_report", "run_calibration", "PRIORS_FOR_ALL",
    "user_agent_plans",
    "surrogate_label", "acoustic_label", "served_lines",
    "phase_exports", "joint_export", "phase2_log_likelihood", "phase2_pareto_k", "PHASE2_LOGLIK",
    "PhaseWriter", "FigureProcesses", "drawing_processes", "helper_processes", "HELPER_PROCESSES",
    "HELPER_PROCESS_MIN_CPUS",
    "AgentOutcome", "AgentProcesses", "agent_groups", "agent_jobs", "gpu_memory_shared", "outcome_of",
    "MAX_AUTO_JOBS", "preload", "preload_soon", "library", "import_turn", "late_modules", "LATE_MODULES",
    "RUN_MODULES", "AgentHeader",
]

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
