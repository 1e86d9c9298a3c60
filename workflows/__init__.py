"""bubblecal.workflows: the ``bubblecal`` command line and the pipelines behind it (knows every layer).

Pipelines: :mod:`~bubblecal.workflows.calibrate` (the main job: config, plan, phase store, run),
:mod:`~bubblecal.workflows.summary` (posterior tables, predictive checks), :mod:`~bubblecal.workflows.report`
(console table, ``report.md``), :mod:`~bubblecal.workflows.figures`, :mod:`~bubblecal.workflows.evidence`
(full vs reduced shell), :mod:`~bubblecal.workflows.confirm` (DPD re-simulation at the MAP),
:mod:`~bubblecal.workflows.sensitivity` (Sobol indices over a prior box),
:mod:`~bubblecal.workflows.acoustic_sweep` (ringdown sweeps -> acoustic surrogate),
:mod:`~bubblecal.workflows.domain` (prior box vs training box), :mod:`~bubblecal.workflows.plotting`.

Command line: :mod:`~bubblecal.workflows.cli` (the typer root) and one thin ``cli_<group>`` module per
command group or top-level command; :mod:`~bubblecal.workflows.console` (shared console, errors, tables).
Import each object from its module; nothing outside this layer imports it.
"""
