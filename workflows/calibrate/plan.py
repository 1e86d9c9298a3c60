"""The plan of a calibration run: every input loaded and checked before any sampling.

:func:`make_plan` validates the whole :class:`~bubblecal.workflows.calibrate.CalibrationConfig` and loads
the priors, the loading curves with their surrogates and the acoustic datasets of each agent; any problem
raises one :class:`~bubblecal.workflows.calibrate.CalibrationError` naming the file, field or range.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from pathlib import Path

from bubblecal.data import AGENTS
from bubblecal.workflows.calibrate.config import (
    DEVICES,
    MIN_PARTICLES,
    NETWORKS,
    PARTICLES_PER_DIMENSION,
    PHASE3_STARTS,
    PHASE3_TARGETS,
    SAMPLERS,
    SURROGATE_CHOICES,
    WORKFLOWS,
    CalibrationConfig,
    CalibrationError,
    min_population,
)
from bubblecal.workflows.calibrate.device import check_device
from bubblecal.workflows.calibrate.preflight import preflight

__all__ = ["AgentPlan", "Plan", "resolve_bundle", "make_plan", "run_config", "run_plan"]


@dataclass
class AgentPlan:
    """What one agent's run needs: priors, curves with their surrogates, acoustic datasets, output folder.

    Parameters
    ----------
    agent : str
        'definity' or 'sonovue'; with measured bubbles (``--data``) the hierarchy's name (the agent label).
    workflow : str
        One of :data:`~bubblecal.workflows.calibrate.WORKFLOWS`.
    spec : bubblecal.priors.PriorSpec
        The agent's priors.
    priors_path : Path
        The priors TOML that ``spec`` was read from.
    curves : list of bubblecal.data.LoadingCurve
        Loading curves (DPD units).
    surrogates : list of bubblecal.surrogates.Surrogate
        One mechanical surrogate per curve, in the same order.
    acoustic : list of bubblecal.data.AcousticDataset
        Acoustic datasets (diameters in um, frequencies in MHz); empty without acoustics.
    f_res : bubblecal.surrogates.AcousticSurrogate or None
        The agent's acoustic surrogate: the f_res² quadratics in k_a fitted at every bubble's diameter, else
        the law over the diameter (:meth:`bubblecal.surrogates.Bundle.acoustic_for`).
    out_dir : Path
        ``out/<agent>/<workflow>``.
    domain_warnings : list of str
        Places where the prior box exceeds a surrogate's training box, or a bubble's diameter lies outside the
        range where the training curves were checked against the explicit tier (reported, not fatal).
    surrogate_agent : str
        The published agent whose surrogates and acoustic law serve this agent ('' = ``agent`` itself).
    notes : list of str
        Choices made for the user that the report states (e.g. which priors a measured agent got).
    """

    agent: str
    workflow: str
    spec: object
    priors_path: Path
    curves: list
    surrogates: list
    acoustic: list
    f_res: object
    out_dir: Path
    domain_warnings: list[str] = field(default_factory=list)
    surrogate_agent: str = ""
    notes: list[str] = field(default_factory=list)

    @property
    def acoustic_name(self) -> str:
        """The name of the acoustic surrogate this agent uses (its published agent)."""
        return self.surrogate_agent or self.agent

    @property
    def dataset_names(self) -> list[str]:
        """Curve names, then acoustic dataset names (the order of every phase list)."""
        return [c.name for c in self.curves] + [d.name for d in self.acoustic]

    def dims(self) -> dict[str, int]:
        """Sampled dimensions of each phase (phase 1 / 3: the largest dataset; phase 2: 2 per pooled parameter)."""
        spec = self.spec
        mech = len(spec.parameters) + 1
        ac = 2 if self.acoustic else 0
        return {"phase1": max(mech, ac), "phase2": 2 * len(spec.pooled_names), "phase3": max(mech, ac)}


@dataclass
class Plan:
    """A validated run: the configuration, the loaded surrogate bundle and one :class:`AgentPlan` per agent.

    Parameters
    ----------
    config : CalibrationConfig
    bundle : bubblecal.surrogates.Bundle
    bundle_path : Path
        The bundle directory.
    synthetic_bundle : bool
        The bundle holds closed-form development laws, not DPD surrogates (results are not physical).
    agents : list of AgentPlan
    """

    config: CalibrationConfig
    bundle: object
    bundle_path: Path
    synthetic_bundle: bool
    agents: list[AgentPlan]


def resolve_bundle(path: Path | None) -> Path:
    """The bundle directory to use: ``path`` or the shipped default.

    Parameters
    ----------
    path : Path or None
        A bundle directory (holding ``manifest.json``), or None for the shipped bundle.

    Returns
    -------
    Path

    Raises
    ------
    CalibrationError
        ``path`` is not a bundle, or no bundle ships with this installation (the message says how to write one).
    """
    from bubblecal.surrogates.bundle import NoDefaultBundleError, default_bundle_path

    if path is not None:
        path = Path(path)
        if not (path / "manifest.json").is_file():
            raise CalibrationError(f"--bundle {path}: no manifest.json there (not a surrogate bundle; write one "
                                   "with `bubblecal surrogates synthetic-bundle DIR`)")
        return path
    try:
        return default_bundle_path(must_exist=True)
    except NoDefaultBundleError as exc:
        raise CalibrationError(str(exc)) from None


def _check_choices(config: CalibrationConfig) -> None:
    """The settings that need no file: choices and ranges (CalibrationError otherwise)."""
    bad = [a for a in config.agents if a not in AGENTS]
    if config.data is not None:
        _check_data_mode(config)
    elif bad or not config.agents:
        raise CalibrationError(f"--agent must be one of {', '.join(AGENTS)} or all, got {', '.join(bad) or 'none'}")
    if config.workflow not in WORKFLOWS:
        raise CalibrationError(f"--workflow must be one of {', '.join(WORKFLOWS)}, got {config.workflow!r}")
    if config.sampler not in SAMPLERS:
        raise CalibrationError(f"--sampler must be one of {', '.join(SAMPLERS)}, got {config.sampler!r}")
    if config.networks not in NETWORKS:
        raise CalibrationError(f"--networks must be one of {', '.join(NETWORKS)}, got {config.networks!r}")
    if config.surrogates is not None and config.surrogates not in SURROGATE_CHOICES:
        raise CalibrationError(f"--surrogates must be one of {', '.join(SURROGATE_CHOICES)} or unset, got "
                               f"{config.surrogates!r}")
    if config.phase3 not in PHASE3_TARGETS:
        raise CalibrationError(f"--phase3 must be one of {', '.join(PHASE3_TARGETS)}, got {config.phase3!r}")
    if config.phase3_start not in PHASE3_STARTS:
        raise CalibrationError(f"--phase3-start must be one of {', '.join(PHASE3_STARTS)}, "
                               f"got {config.phase3_start!r}")
    if config.device not in DEVICES:
        raise CalibrationError(f"--device must be one of {', '.join(DEVICES)}, got {config.device!r}")
    check_device(config.device)  # the integer settings' ranges: CalibrationConfig, on construction
    if config.data is not None:
        return
    if config.acoustic_data is not None:
        raise CalibrationError("--acoustic FILE goes with --data CURVES.csv (the published study reads its own "
                               "acoustic table; --data-dir replaces it)")
    _check_curve_agents(config)
    if config.data_dir is not None and not Path(config.data_dir).is_dir():
        raise CalibrationError(f"--data-dir {config.data_dir}: not a directory")
    if config.data_dir is not None:
        _check_data_dir(Path(config.data_dir))


def _check_data_mode(config: CalibrationConfig) -> None:
    """The options that go with ``--data``: files that exist, none of the published study's selections."""
    clash = [name for name, on in (("--data-dir", config.data_dir is not None), ("--curve", bool(config.curves)),
                                   ("--agent", tuple(config.agents) != AGENTS)) if on]
    if clash:
        raise CalibrationError(f"{', '.join(clash)}: select(s) the published study's data; with --data CURVES.csv "
                               "the file says which bubbles and agents to calibrate")
    if config.surrogates == "per-diameter":
        raise CalibrationError("--surrogates per-diameter: the published study's files at its own diameters; with "
                               "--data CURVES.csv every bubble is served by the networks over the diameter "
                               "(--networks picks fast or accurate)")
    for flag, path in (("--data", config.data), ("--acoustic", config.acoustic_data)):
        if path is not None and not Path(path).is_file():
            raise CalibrationError(f"{flag} {path}: no such file")
    if config.acoustic_data is not None and config.workflow in ("reduced", "full"):
        raise CalibrationError(f"--acoustic {config.acoustic_data}: workflow {config.workflow!r} uses no resonance "
                               "data; use --workflow reduced-acoustic (the default with --acoustic)")


def _check_curve_agents(config: CalibrationConfig) -> None:
    """Every ``--curve`` is a known curve of one of the run's agents (else one message naming curve and agents)."""
    from bubblecal.data import REFERENCE_CURVES

    unknown = [c for c in config.curves if c not in REFERENCE_CURVES]
    if unknown:
        raise CalibrationError(f"--curve {', '.join(unknown)}: unknown; curves: {', '.join(REFERENCE_CURVES)}")
    other = [f"{c} (a {REFERENCE_CURVES[c][0]} curve)" for c in config.curves
             if REFERENCE_CURVES[c][0] not in config.agents]
    if other:
        raise CalibrationError(f"--curve {', '.join(other)}: not a curve of --agent {', '.join(config.agents)}; "
                               "give that agent, or its own curves")


def _check_data_dir(folder: Path) -> None:
    """Every file of a ``--data-dir`` folder is one the run reads (else one message naming the others)."""
    from bubblecal.data import REFERENCE_CURVES

    known = {f"{name}_dpd.csv" for name in REFERENCE_CURVES} | {"acoustic_observations_published.csv"}
    files = sorted(p.name for p in folder.iterdir() if p.is_file() and not p.name.startswith("."))
    unknown = [f for f in files if f not in known]
    if unknown or not files:
        lower = {k.lower(): k for k in known}
        hints = [f"{f} (did you mean {lower[f.lower()]}?)" if f.lower() in lower else f for f in unknown]
        what = (f"holds files this run would not read: {', '.join(hints)}" if unknown
                else "holds none of the files this run reads")
        raise CalibrationError(f"--data-dir {folder}: {what}; accepted names: {', '.join(sorted(known))}")


def _check_out(out: Path) -> None:
    """The output folder exists or can be made, and is writable (else one message naming it)."""
    existing = next((p for p in (out, *out.parents) if p.exists()), None)
    if out.exists() and not out.is_dir():
        raise CalibrationError(f"--out {out}: exists and is not a folder")
    if existing is not None and existing != out and not existing.is_dir():
        raise CalibrationError(f"--out {out}: {existing} is a file, so the folder cannot be made")
    if existing is not None and not os.access(existing, os.W_OK | os.X_OK):
        raise CalibrationError(f"--out {out}: {existing} is not writable (or on a read-only file system)")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CalibrationError(f"--out {out}: the folder cannot be made ({exc.strerror})") from None


def make_plan(config: CalibrationConfig, *, check_likelihoods: bool = True,
              agents: tuple[str, ...] | None = None) -> Plan:
    """Validate the whole configuration and load every input, before any sampling starts.

    Parameters
    ----------
    config : CalibrationConfig
    check_likelihoods : bool
        Evaluate every dataset's log likelihood at a few prior draws (the preflight); off to only rebuild the
        inputs of a finished run.
    agents : tuple of str or None
        Keep only these agents (labels) of the run, in run order, after every agent's inputs were checked (a
        worker process of :mod:`~bubblecal.workflows.calibrate.parallel` plans its own); None: all.

    Returns
    -------
    Plan

    Raises
    ------
    CalibrationError
        One clear message naming the file, field or range: a bad choice or range, a missing device, an
        unreadable bundle, priors or data file, priors for another agent or workflow, a curve without a
        surrogate, missing acoustic data or surrogate, a population too small for a phase, an output
        folder that cannot be made or written, or a dataset whose log likelihood is not finite at a few prior
        draws (:func:`~bubblecal.workflows.calibrate.preflight.preflight`).
    ValueError
        ``agents`` names an agent the run does not plan.
    """
    from bubblecal.surrogates import SurrogateFormatError, load_bundle
    from bubblecal.surrogates.acoustic import AcousticFormatError
    from bubblecal.surrogates.synthetic_bundle import is_synthetic_bundle

    only = None if agents is None else tuple(agents)
    _check_choices(config)
    _check_out(Path(config.out))
    bundle_path = resolve_bundle(config.bundle)
    try:
        bundle = load_bundle(bundle_path)
    except (SurrogateFormatError, AcousticFormatError, FileNotFoundError, KeyError, ValueError) as exc:
        raise CalibrationError(f"surrogate bundle {bundle_path}: {exc}") from None

    if config.data is not None:
        from bubblecal.workflows.calibrate.user_data import user_agent_plans

        agents = user_agent_plans(config, bundle, Path(config.out))
    else:
        from bubblecal.workflows.calibrate.published import published_agent_plans

        agents = published_agent_plans(config, bundle, bundle_path)
    if only is not None:
        unknown = sorted(set(only) - {ap.agent for ap in agents})
        if unknown:
            raise ValueError(f"make_plan(agents=...): the run plans no agent {', '.join(unknown)}")
        agents = [ap for ap in agents if ap.agent in only]
    for ap in agents:
        _check_population(config, ap)
    plan = Plan(config=config, bundle=bundle, bundle_path=bundle_path,
                synthetic_bundle=is_synthetic_bundle(bundle), agents=agents)
    if check_likelihoods:
        preflight(plan)
    return plan


def run_config(run_dir: Path) -> tuple[CalibrationConfig, dict]:
    """The configuration of a finished run folder, read from its ``manifest.json``.

    Parameters
    ----------
    run_dir : Path
        A run folder OUT/<agent>/<workflow> holding ``manifest.json``.

    Returns
    -------
    tuple of (CalibrationConfig, dict)
        The run's configuration (:meth:`CalibrationConfig.from_dict`: a manifest without ``surrogates`` reads as
        the per-diameter files it ran on) and the manifest's ``run`` entry.

    Raises
    ------
    CalibrationError
        If the manifest is missing or unreadable.
    """
    import json

    path = Path(run_dir) / "manifest.json"
    try:
        run = json.loads(path.read_text())["run"]
        return CalibrationConfig.from_dict(run["config"]), run
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise CalibrationError(f"{path}: not a calibration manifest ({type(exc).__name__}: {exc})") from None


def run_plan(run_dir: Path) -> AgentPlan:
    """The agent plan of a finished run folder, rebuilt from its ``manifest.json``: the same curves (published or
    the user's, with their names), surrogates, priors and acoustic data as the run had.

    Parameters
    ----------
    run_dir : Path
        A run folder OUT/<agent>/<workflow> holding ``manifest.json``.

    Returns
    -------
    AgentPlan
        The plan of the run's agent (label) whose output folder is ``run_dir``; its surrogates are the kind the
        run recorded (:func:`run_config`), never the current default.

    Raises
    ------
    CalibrationError
        If the manifest is missing or unreadable, an input it names (data, priors, bundle) cannot be loaded any
        more, or no agent of the rebuilt plan writes to ``run_dir``.
    """
    run_dir = Path(run_dir)
    config, run = run_config(run_dir)
    # the folder may have moved since the run: its layout OUT/<agent>/<workflow> gives the output root
    plan = make_plan(dataclasses.replace(config, out=run_dir.parent.parent), check_likelihoods=False)
    for ap in plan.agents:
        if ap.agent == run.get("agent") and Path(ap.out_dir).resolve() == run_dir.resolve():
            return ap
    raise CalibrationError(f"{run_dir / 'manifest.json'}: the run's configuration plans no agent "
                           f"{run.get('agent')!r} with its output in {run_dir}")


def _check_population(config: CalibrationConfig, ap: AgentPlan) -> None:
    """TMCMC's N is large enough for every phase of the agent (CalibrationError naming phase and need)."""
    n = config.num_particles
    if config.sampler != "tmcmc":
        return
    for phase, dim in ap.dims().items():
        need = min_population(dim)
        if n < need:
            raise CalibrationError(f"--population {n} is too small: {ap.agent} {phase} samples {dim} parameters "
                                   f"and needs N >= {need} ({PARTICLES_PER_DIMENSION} per dimension, at least "
                                   f"{MIN_PARTICLES})")
