"""The plan of a calibration of measured bubbles: a tidy curves file (and a resonance file) -> one plan per agent.

``bubblecal calibrate --data CURVES.csv [--acoustic FREQS.csv]`` reads the tidy files
(:func:`bubblecal.data.read_bubble_curves`, :func:`bubblecal.data.read_resonance`; docs/data-formats.md, "Tidy
bubble files") and builds one :class:`~bubblecal.workflows.calibrate.AgentPlan` per agent label: every bubble is a
loading curve with the surrogate of its protocol bound to its diameter, every resonance row an acoustic dataset of
one bubble. Every problem — in the files, in the priors, a diameter outside the bundle's range, points beyond the
surrogate's loading box, a resonance diameter outside the acoustic law — is collected and raised at once, before
any sampling. Decisions (one hierarchy per agent and protocol, one acoustic dataset per resonance row, the
default priors): docs/decisions.md, "Calibrating measured bubbles".
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bubblecal.workflows.calibrate.config import CalibrationConfig, CalibrationError, priors_fit_problems

__all__ = ["PRIORS_FOR_ALL", "SAFE_NAME", "UserAgent", "user_agents", "user_agent_plans"]

#: Key of :attr:`CalibrationConfig.priors` whose file serves every agent without a file of its own.
PRIORS_FOR_ALL = "*"
#: Bubble ids and agent labels name output files and folders: letters, digits and ``. _ + -``.
SAFE_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]*$")


@dataclass(frozen=True)
class UserAgent:
    """One hierarchy of a tidy curves file: the bubbles of one agent label and protocol.

    Parameters
    ----------
    name : str
        The hierarchy's name: the agent label, or ``<label>-<protocol>`` for an agent measured by both protocols.
    label : str
        The agent label of the file.
    protocol : str
        'compression' or 'indentation'.
    bubbles : tuple of bubblecal.data.BubbleCurve
        Its bubbles, in file order.
    resonance_rows : tuple of int
        Indices of its rows in the resonance file.
    """

    name: str
    label: str
    protocol: str
    bubbles: tuple
    resonance_rows: tuple[int, ...] = ()


def _read_files(config: CalibrationConfig):
    """(curves, resonance or None), each file read and validated (CalibrationError listing every problem)."""
    from bubblecal.data import DataError, check_consistency, read_bubble_curves, read_resonance

    try:
        curves = read_bubble_curves(config.data)
        resonance = None if config.acoustic_data is None else read_resonance(config.acoustic_data)
        if resonance is not None:
            check_consistency(curves, resonance)
    except DataError as exc:
        raise CalibrationError(str(exc)) from None
    return curves, resonance


def user_agents(curves, resonance) -> tuple[list[UserAgent], list[str]]:
    """Split a validated curves file into hierarchies, and the problems of names and mixed agents.

    Parameters
    ----------
    curves : bubblecal.data.BubbleCurveSet
        The bubbles.
    resonance : bubblecal.data.ResonanceSet or None
        The resonance rows.

    Returns
    -------
    agents : list of UserAgent
        One per (agent label, protocol), in file order.
    problems : list of str
        Bubble ids or labels that cannot name a file, and resonance rows of an agent measured by both protocols
        (which hierarchy they join would be a guess).
    """
    problems = []
    for b in curves:
        if not SAFE_NAME.match(b.bubble):
            problems.append(f"{curves.path}: bubble {b.bubble!r} (line {b.lines[0]}, column 'bubble'): an id names "
                            "its output files; use letters, digits and . _ + - (starting with a letter or digit)")
    for label in curves.agents:
        if not SAFE_NAME.match(label):
            line = next(b.lines[0] for b in curves if b.agent == label)
            problems.append(f"{curves.path}: agent {label!r} (line {line}, column 'agent'): a label names the output "
                            "folder; use letters, digits and . _ + - (starting with a letter or digit)")
    groups = curves.by_agent_protocol()
    protocols: dict[str, list[str]] = {}
    for label, protocol in groups:
        protocols.setdefault(label, []).append(protocol)
    agents = []
    for (label, protocol), bubbles in groups.items():
        mixed = len(protocols[label]) > 1
        rows = () if resonance is None else tuple(k for k, a in enumerate(resonance.agent) if a == label)
        if mixed and rows and protocol == protocols[label][0]:
            problems.append(f"{resonance.path}: agent {label!r} has resonance rows (lines "
                            f"{', '.join(str(resonance.lines[k]) for k in rows)}) and bubbles of both protocols in "
                            f"{curves.path}, which are calibrated as two hierarchies; give the compression and the "
                            "indentation bubbles different agent labels and the resonance rows the label they "
                            "belong to")
        agents.append(UserAgent(name=f"{label}-{protocol}" if mixed else label, label=label, protocol=protocol,
                                bubbles=tuple(bubbles), resonance_rows=() if mixed else rows))
    return agents, problems


def _priors_source(config: CalibrationConfig, agent: UserAgent, workflow: str) -> tuple[str, str]:
    """(priors name or path, note for the report): the agent's own file, the file for all, or the shipped priors."""
    from bubblecal.data import PUBLISHED_AGENT_OF_PROTOCOL
    from bubblecal.priors import workflow_file_name

    for key in (agent.name, agent.label, PRIORS_FOR_ALL):
        if key in config.priors:
            return str(config.priors[key]), f"priors: {config.priors[key]}"
    published = PUBLISHED_AGENT_OF_PROTOCOL[agent.protocol]
    shipped = workflow_file_name(published, workflow)
    return shipped, (f"priors: the shipped {shipped} priors of {published}, the published {agent.protocol} agent "
                     f"(no --priors for {agent.label}; write an editable copy with `bubblecal priors template "
                     f"--agent {agent.label} --protocol {agent.protocol}`)")


def _agent_workflow(config: CalibrationConfig, agent: UserAgent) -> tuple[str, list[str]]:
    """The workflow of one hierarchy and notes: an acoustic run falls back to 'reduced' without resonance rows."""
    if config.workflow == "reduced-acoustic" and not agent.resonance_rows:
        where = f" in {config.acoustic_data}" if config.acoustic_data is not None else "; no --acoustic"
        return "reduced", [f"workflow: reduced (no resonance rows for {agent.label}{where})"]
    return config.workflow, []


def _loading_box_problems(bubble, surrogate, spec) -> list[str]:
    """Retained points beyond the surrogate's loading box at the bubble's diameter (named with file lines)."""
    from bubblecal.data import DEFAULT_UNITS
    from bubblecal.workflows.domain import PRIOR_BOX_RTOL

    lo, hi = surrogate.loading_range(bubble.diameter_um if surrogate.over_diameter else None)
    shift = spec.parameters["d0"].prior.hi if surrogate.setup == "compression" and "d0" in spec.parameters else 0.0
    top = hi * (1 + PRIOR_BOX_RTOL) + shift  # compression reaches the network at x - d0: the largest d0 is the kindest
    x = np.asarray(bubble.x)
    bad = [k for k in np.nonzero(bubble.retained)[0] if x[k] > top or x[k] < min(lo, 0.0)]
    if not bad:
        return []
    if bubble.protocol == "compression":
        conv, column, unit = DEFAULT_UNITS.dpd_to_nm, "displacement_nm", "nm"
    else:
        conv, column, unit = DEFAULT_UNITS.dpd_to_nN, "force_nN", "nN"
    values = ", ".join(f"{float(conv(x[k])):.4g}" for k in bad[:6]) + (" ..." if len(bad) > 6 else "")
    lines = ", ".join(str(bubble.lines[k]) for k in bad[:6]) + (" ..." if len(bad) > 6 else "")
    return [f"{bubble.path}: bubble {bubble.bubble!r} ({bubble.diameter_um:g} um), lines {lines}, column {column!r}: "
            f"{values} {unit} beyond the {bubble.protocol} surrogate's loading box at this diameter (retained points "
            f"up to {float(conv(top)):.4g} {unit}" + (", the largest d0 of the priors included" if shift else "")
            + "); set retained = 0 on those rows or use a bundle trained further"]


def _bubble_surrogates(agent: UserAgent, bundle, spec, network: str) -> tuple[list, list[str], list[str]]:
    """(surrogate per bubble, problems, domain warnings) of one hierarchy; ``network`` picks the network over the
    diameter ('fast' or 'accurate')."""
    from bubblecal.surrogates import OutOfDomainError
    from bubblecal.workflows.domain import prior_box_domain_warnings, tier_validation_warnings

    surrogates, problems, domain = [], [], []
    for b in agent.bubbles:
        try:
            # the network over the diameter even at a published diameter: one network for every bubble of a population
            # (and one compiled likelihood)
            sur = bundle.get(agent.protocol, b.diameter_um, prefer="over-diameter", network=network)
        except (KeyError, OutOfDomainError) as exc:
            msg = exc.args[0] if exc.args else str(exc)
            problems.append(f"{b.path}: bubble {b.bubble!r} (line {b.lines[0]}, column 'diameter_um'): "
                            f"{b.diameter_um:g} um: {msg}")
            continue
        surrogates.append(sur)
        problems += _loading_box_problems(b, sur, spec)
        domain += prior_box_domain_warnings(sur, spec, b.loading_curve().x)
        domain += tier_validation_warnings(b.protocol, b.diameter_um, f"bubble {b.bubble!r}")
    return surrogates, problems, domain


def _acoustic_datasets(agent: UserAgent, resonance, bundle, spec) -> tuple[list, object, list[str], list[str]]:
    """(one acoustic dataset per resonance row, the acoustic surrogate, problems, domain warnings) of one
    hierarchy."""
    from bubblecal.data import AcousticDataset
    from bubblecal.surrogates.acoustic import AcousticRangeError
    from bubblecal.workflows.domain import acoustic_ka_domain_warnings

    rows = agent.resonance_rows
    datasets = [AcousticDataset(name=f"{agent.name}_resonance_{n + 1}", agent=agent.label,
                                diameter_um=np.array([resonance.diameter_um[k]]),
                                frequency_MHz=np.array([resonance.frequency_MHz[k]]),
                                source=resonance.source[k] or f"{resonance.path}, line {resonance.lines[k]}")
                for n, k in enumerate(rows)]
    diameters = np.array([resonance.diameter_um[k] for k in rows])
    try:
        f_res = bundle.acoustic_for(spec.agent, diameters)
    except AcousticRangeError as exc:
        return datasets, None, [f"{resonance.path}: agent {agent.label!r}, lines "
                                f"{', '.join(str(resonance.lines[k]) for k in rows)}, column 'diameter_um': {exc}"], []
    return datasets, f_res, [], acoustic_ka_domain_warnings(f_res, spec, datasets, agent.label)


def user_agent_plans(config: CalibrationConfig, bundle, out: Path) -> list:
    """One :class:`~bubblecal.workflows.calibrate.AgentPlan` per hierarchy of the tidy files of ``config``.

    Parameters
    ----------
    config : CalibrationConfig
        ``data`` (tidy curves file), ``acoustic_data`` (tidy resonance file or None), ``priors`` (agent label,
        hierarchy name or :data:`PRIORS_FOR_ALL` -> priors name or TOML path) and ``workflow``.
    bundle : bubblecal.surrogates.Bundle
        The loaded surrogate bundle.
    out : Path
        The output root; a hierarchy writes ``out/<name>/<workflow>/``.

    Returns
    -------
    list of AgentPlan
        In file order; ``surrogate_agent`` names the published agent whose surrogates and acoustic law serve it,
        ``notes`` say which priors and workflow it got.

    Raises
    ------
    CalibrationError
        Listing every problem at once: the files' own (row, column, value, allowed range), ids or labels that
        cannot name a file, resonance rows of an agent with both protocols, unreadable priors or priors of another
        protocol or workflow, ``--priors`` keys that name no agent, a diameter outside the bundle's range, retained
        points beyond a surrogate's loading box, resonance diameters outside the acoustic law.
    """
    from bubblecal.priors import PriorError, load_priors
    from bubblecal.workflows.calibrate.plan import AgentPlan

    curves, resonance = _read_files(config)
    agents, problems = user_agents(curves, resonance)
    known = {a.name for a in agents} | {a.label for a in agents} | {PRIORS_FOR_ALL}
    problems += [f"--priors {key}={path}: no agent {key!r} in {curves.path} (agents: "
                 f"{', '.join(a.name for a in agents)})" for key, path in config.priors.items() if key not in known]
    plans = []
    for agent in agents:
        workflow, notes = _agent_workflow(config, agent)
        source, note = _priors_source(config, agent, workflow)
        try:
            spec = load_priors(source)
        except PriorError as exc:
            problems.append(f"agent {agent.name}: {exc}")
            continue
        bad = priors_fit_problems(spec, protocol=agent.protocol, workflow=workflow,
                                  who=f"the bubbles of agent {agent.name!r}")
        if bad:
            problems += bad
            continue
        surrogates, bad, domain = _bubble_surrogates(agent, bundle, spec, config.networks)
        problems += bad
        acoustic, f_res = [], None
        if spec.acoustic:  # priors_fit_problems matched it to the workflow
            acoustic, f_res, bad, warned = _acoustic_datasets(agent, resonance, bundle, spec)
            problems += bad
            domain += warned
        plans.append(AgentPlan(agent=agent.name, workflow=workflow, spec=spec, priors_path=Path(spec.path),
                               curves=[b.loading_curve() for b in agent.bubbles], surrogates=surrogates,
                               acoustic=acoustic, f_res=f_res, out_dir=Path(out) / agent.name / workflow,
                               domain_warnings=domain, surrogate_agent=spec.agent, notes=[note, *notes]))
    if problems:
        raise CalibrationError(f"{len(problems)} problem(s) before any sampling:\n" + "\n".join(f"  - {p}"
                                                                                                for p in problems))
    return plans
