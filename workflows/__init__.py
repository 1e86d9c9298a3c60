"""bubblecal.workflows: the ``bubblecal`` command line and the pipelines behind it (knows every layer).

Pipelines: :mod:`~bubblecal.workflows.calibrate` (the main job: config, plan, phase store, run),
:mod:`~bubblecal.workflows.summary` (posterior tables, predictive checks; their bands and CRPS on threads in
:mod:`~bubblecal.workflows.summary_stats`; their JAX evaluations on host data, one compiled program each, in
:mod:`~bubblecal.workflows.host_programs`), :mod:`~bubblecal.workflows.report`
(console table, ``report.md``), :mod:`~bubblecal.workflows.figures` (with
:mod:`~bubblecal.workflows.figures_fits` and :mod:`~bubblecal.workflows.figures_population`),
:mod:`~bubblecal.workflows.evidence`
(full vs reduced shell), :mod:`~bubblecal.workflows.confirm` (DPD re-simulation at the MAP),
:mod:`~bubblecal.workflows.sensitivity` (Sobol indices over a prior box),
:mod:`~bubblecal.workflows.acoustic_sweep` (ringdown sweeps -> acoustic surrogate),
:mod:`~bubblecal.workflows.domain` (prior box vs training box), :mod:`~bubblecal.workflows.plotting`.

Command line: :mod:`~bubblecal.workflows.cli` (the typer root) and one thin ``cli_<group>`` module per
command group or top-level command; :mod:`~bubblecal.workflows.console` (shared console, errors, tables).
Nothing outside this layer imports it.  The pipelines' entry points are exported here for notebooks and
scripts (``from bubblecal.workflows import CalibrationConfig, make_plan, run_calibration``, ``run_evidence``,
``confirm_run``, ``surrogate_sensitivity``); they are imported on first access, so that the command line starts
without loading JAX.  The closed sets of option values are enums in :mod:`~bubblecal.workflows.choices`.
"""

from bubblecal._lazy import lazy_exports

__all__ = ["CalibrationConfig", "CalibrationError", "config_from_agents", "make_plan", "run_calibration",
           "run_agent", "read_phase", "run_evidence", "kass_raftery", "confirm_run", "find_runs",
           "surrogate_sensitivity", "averaging_range", "app", "main"]

_LAZY = {
    "CalibrationConfig": "bubblecal.workflows.calibrate",
    "CalibrationError": "bubblecal.workflows.calibrate",
    "config_from_agents": "bubblecal.workflows.calibrate",
    "make_plan": "bubblecal.workflows.calibrate",
    "run_calibration": "bubblecal.workflows.calibrate",
    "run_agent": "bubblecal.workflows.calibrate",
    "read_phase": "bubblecal.workflows.calibrate",
    "run_evidence": "bubblecal.workflows.evidence",
    "kass_raftery": "bubblecal.workflows.evidence",
    "confirm_run": "bubblecal.workflows.confirm",
    "find_runs": "bubblecal.workflows.confirm",
    "surrogate_sensitivity": "bubblecal.workflows.sensitivity",
    "averaging_range": "bubblecal.workflows.sensitivity",
    "app": "bubblecal.workflows.cli",
    "main": "bubblecal.workflows.cli",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
