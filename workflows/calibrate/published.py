"""The published study's inputs: the shipped (or replaced) curves, acoustic table, priors and surrogates per agent.

:func:`published_agent_plans` builds the :class:`~bubblecal.workflows.calibrate.AgentPlan` of Definity and
SonoVue for ``bubblecal calibrate`` without ``--data``; measured bubbles go through
:mod:`bubblecal.workflows.calibrate.user_data`.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from bubblecal.workflows.calibrate.config import CalibrationConfig, CalibrationError, priors_fit_problems
from bubblecal.workflows.calibrate.plan import AgentPlan

__all__ = ["published_agent_plans"]

def _workflow_priors_name(agent: str, workflow: str) -> str:
    """The shipped priors name of ``agent`` and ``workflow``."""
    from bubblecal.priors import workflow_file_name

    return workflow_file_name(agent, workflow)


def _load_curves(agent: str, data_dir: Path | None) -> list:
    """The agent's reference curves, each replaced by ``data_dir/<name>_dpd.csv`` where that file exists."""
    from bubblecal.data import REFERENCE_CURVES, DataError, load_curve, load_reference

    curves = []
    for name, (ag, kind, nominal, measured, _cite) in REFERENCE_CURVES.items():
        if ag != agent:
            continue
        path = None if data_dir is None else Path(data_dir) / f"{name}_dpd.csv"
        if path is not None and path.is_file():
            try:
                curve = load_curve(path, kind, "dpd", name=name, agent=agent, diameter_um=nominal, source=str(path))
            except DataError as exc:
                raise CalibrationError(str(exc)) from None
            curve = dataclasses.replace(curve, bubble_diameter_um=measured)
        else:
            curve = load_reference(agent, nominal)
        curves.append(curve)
    return curves


def _load_acoustic(agent: str, data_dir: Path | None) -> list:
    """The agent's acoustic datasets, from ``data_dir/acoustic_observations_published.csv`` where it exists."""
    from bubblecal.data import DataError, acoustic_datasets, load_acoustic_table

    path = None if data_dir is None else Path(data_dir) / "acoustic_observations_published.csv"
    if path is not None and path.is_file():
        try:
            rows = load_acoustic_table(path)
        except DataError as exc:
            raise CalibrationError(str(exc)) from None
        return acoustic_datasets(agent, rows)
    return acoustic_datasets(agent)


def published_agent_plans(config: CalibrationConfig, bundle, bundle_path: Path) -> list[AgentPlan]:
    """One plan per published agent of ``config.agents``: the shipped curves (or ``--data-dir`` replacements),
    acoustic table, priors and the surrogates the config picks.

    With :attr:`~CalibrationConfig.resolved_surrogates` 'over-diameter' the curves get the bundle's networks over
    the diameter (role ``config.networks``) and the acoustic datasets its laws continuous in the diameter; with
    'per-diameter' the files fitted at the published diameters. Either falls back to the other kind where the
    bundle has no file of the chosen one covering a diameter (a bundle without networks over the diameter runs
    on its per-diameter files).

    Parameters
    ----------
    config : CalibrationConfig
        ``agents``, ``workflow``, ``priors`` (agent -> file), ``data_dir``, ``curves``, ``surrogates`` and
        ``networks``.
    bundle : bubblecal.surrogates.Bundle
        The loaded surrogate bundle.
    bundle_path : Path
        Its directory (named in messages).

    Returns
    -------
    list of AgentPlan
        One per agent, in ``config.agents`` order.

    Raises
    ------
    CalibrationError
        Unreadable priors or data files, priors of another agent or workflow, a curve without a surrogate,
        missing acoustic data or acoustic surrogate.
    """
    from bubblecal.priors import PriorError, load_priors

    agents = []
    for agent in config.agents:
        source = config.priors.get(agent, _workflow_priors_name(agent, config.workflow))
        try:
            spec = load_priors(source)
        except PriorError as exc:
            raise CalibrationError(str(exc)) from None
        if spec.agent != agent:
            raise CalibrationError(f"{spec.path}: field workflow.agent is {spec.agent!r}, expected {agent!r}")
        curves = _select_curves(_load_curves(agent, config.data_dir), config.curves, agent)
        problems = priors_fit_problems(spec, protocol=curves[0].kind, workflow=config.workflow,
                                       who=f"the {agent} curves")
        if problems:
            raise CalibrationError("\n".join(problems))
        surrogates, domain = _curve_surrogates(curves, bundle, spec, agent, config)
        acoustic, f_res = [], None
        if spec.acoustic:
            acoustic, f_res = _acoustic_inputs(agent, config, bundle, bundle_path, spec, domain)
        ap = AgentPlan(agent=agent, workflow=config.workflow, spec=spec, priors_path=Path(spec.path), curves=curves,
                       surrogates=surrogates, acoustic=acoustic, f_res=f_res,
                       out_dir=Path(config.out) / agent / config.workflow, domain_warnings=domain)
        agents.append(ap)
    return agents


def _select_curves(curves: list, names: tuple[str, ...], agent: str) -> list:
    """The curves named by ``--curve`` (all when ``names`` is empty)."""
    if not names:
        return curves
    curves = [c for c in curves if c.name in names]
    if not curves:
        raise CalibrationError(f"--curve: none of {', '.join(names)} belongs to {agent}")
    return curves


def _curve_surrogates(curves: list, bundle, spec, agent: str,
                      config: CalibrationConfig) -> tuple[list, list[str]]:
    """(surrogate per curve, domain warnings of the prior box vs each surrogate's training box); the config's
    choice of surrogates and network (:meth:`CalibrationConfig.surrogate_lookup`)."""
    from bubblecal.workflows.domain import prior_box_domain_warnings

    surrogates, domain = [], []
    for curve in curves:
        try:
            sur = bundle.get(curve.kind, curve.diameter_um, **config.surrogate_lookup())
        except KeyError as exc:
            raise CalibrationError(f"{exc.args[0]}; the {agent} curve {curve.name} needs it") from None
        surrogates.append(sur)
        domain += prior_box_domain_warnings(sur, spec, curve.x)
    return surrogates, domain


def _acoustic_inputs(agent: str, config: CalibrationConfig, bundle, bundle_path: Path, spec,
                     domain: list[str]) -> tuple[list, object]:
    """(acoustic datasets, acoustic surrogate); appends a message to ``domain`` where the fitted k_a range
    of a diameter does not contain the k_a prior."""
    from bubblecal.surrogates.acoustic import AcousticRangeError
    from bubblecal.workflows.domain import acoustic_ka_domain_warnings

    acoustic = _load_acoustic(agent, config.data_dir)
    if not acoustic:
        raise CalibrationError(f"no acoustic observations of {agent} (workflow {config.workflow})")
    diameters = np.concatenate([np.atleast_1d(np.asarray(ds.diameter_um, dtype=float)) for ds in acoustic])
    try:  # the chosen kind where it covers every bubble, else the other
        f_res = bundle.acoustic_for(agent, diameters, prefer=config.resolved_surrogates)
    except AcousticRangeError as exc:
        raise CalibrationError(f"{exc}; workflow {config.workflow} needs it for the {agent} acoustic data") from None
    for ds in acoustic:
        try:
            domain += acoustic_ka_domain_warnings(f_res, spec, [ds], agent)
        except AcousticRangeError as exc:
            raise CalibrationError(f"bundle {bundle_path}: {exc}; acoustic dataset {ds.name} needs it") from None
    return acoustic, f_res
