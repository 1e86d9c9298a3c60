"""Settings of a calibration run: the choices, the population sizes and :class:`CalibrationConfig`.

The ``bubblecal calibrate`` command reads its defaults from :class:`CalibrationConfig`, so a default is
written once, here. TMCMC settings follow ``docs/inference.md`` section 5.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from bubblecal.data import AGENTS

__all__ = ["WORKFLOWS", "SAMPLERS", "PHASE3_TARGETS", "PHASE3_STARTS", "DEVICES", "NETWORKS", "SURROGATE_CHOICES",
           "DEFAULT_POPULATION", "PAPER_POPULATION", "PAPER_COV", "PAPER_COV_SCALE", "PARTICLES_PER_DIMENSION",
           "MIN_PARTICLES", "DEFAULT_PHASE2_SAMPLES", "PHASE2_DRAW_BUDGET", "MIN_PHASE2_SAMPLES", "CalibrationError",
           "CalibrationConfig", "config_from_agents", "phase_tmcmc_options", "phase2_samples", "min_population",
           "agent_seed", "priors_fit_problems"]

#: Workflows: each names one priors TOML per agent (``priors/<agent>_<workflow>.toml``).
WORKFLOWS = ("reduced-acoustic", "reduced", "full")
#: 'tmcmc': the staged hierarchy (phases 1 -> 2 -> 3); 'nuts': the joint model.
SAMPLERS = ("tmcmc", "nuts")
#: Phase 3 of the staged hierarchy: the published (Korali) target or the joint model's marginal.
PHASE3_TARGETS = ("published", "exact")
#: Where phase 3 starts: the dataset's phase-1 draws (only the population prior tempered) or the uniform prior (Korali).
PHASE3_STARTS = ("phase1", "prior")
#: JAX devices.
DEVICES = ("cpu", "gpu")
#: Networks over the diameter a bundle may hold per protocol: 'fast' (smaller, for many bubbles on CPU cores)
#: and 'accurate' (the sweep's best); docs/decisions.md, "Fast networks over the diameter".
NETWORKS = ("fast", "accurate")
#: Surrogates of the published study: the bundle's networks and acoustic laws over the diameter, or the files fitted
#: at each published diameter (the paper's); docs/decisions.md, "The published study on the networks over ...".
SURROGATE_CHOICES = ("over-diameter", "per-diameter")
#: Default TMCMC particles per phase: small enough for both agents on a few CPU cores (compile-dominated
#: at this size; measurements in ``benchmarks/RESULTS.md``).
DEFAULT_POPULATION = 2000
#: The published settings (``--paper``): N = 50,000 per phase, target CoV 0.8 (phase 1) / 0.6 (phases 2, 3),
#: covariance scaling s² = 0.04 (``docs/inference.md`` section 5).
PAPER_POPULATION = 50_000
PAPER_COV = (0.8, 0.6)
PAPER_COV_SCALE = 0.04
#: Particles per sampled dimension that every phase needs at least (and an absolute floor).
PARTICLES_PER_DIMENSION = 20
MIN_PARTICLES = 100
#: Cap of the phase-1 draws per dataset that phase 2 uses (and of the ψ draws of the phase-3 prior).
DEFAULT_PHASE2_SAMPLES = 2000
#: Phase-1 draws phase 2 uses over all datasets of an agent at most: its cost is N x this many population
#: densities per evaluation, so past 20 datasets each one gives fewer draws (at least :data:`MIN_PHASE2_SAMPLES`);
#: the importance ESS per dataset (ess.csv) tells whether they suffice.
PHASE2_DRAW_BUDGET = 40_000
MIN_PHASE2_SAMPLES = 250


#: Largest TMCMC population (and chunk) a run accepts: its particle arrays then stay within a few GiB.
MAX_POPULATION = 10_000_000


class CalibrationError(ValueError):
    """A calibration input is invalid; the message names the file / field / range. Raised before sampling."""


@dataclass(frozen=True)
class CalibrationConfig:
    """Settings of one calibration run (CLI: ``bubblecal calibrate``).

    Parameters
    ----------
    agents : tuple of str
        Subset of :data:`bubblecal.data.names.AGENTS` (the published study; ``data`` brings its own agents).
    workflow : str
        One of :data:`WORKFLOWS`; the priors are ``priors/<agent>_<workflow>.toml`` unless ``priors`` maps
        the agent to another TOML.
    sampler : str
        'tmcmc' (staged phases 1 -> 2 -> 3) or 'nuts' (joint model).
    population : int or None
        TMCMC particles N per phase (None: :data:`DEFAULT_POPULATION`, or :data:`PAPER_POPULATION` with
        ``paper``).
    paper : bool
        Published settings: N = 50,000, target CoV 0.8 / 0.6, covariance scaling s² = 0.04.
    out : Path
        Output root; one run writes ``out/<agent>/<workflow>/``.
    device : str
        'cpu' or 'gpu' (JAX device).
    bundle : Path or None
        Surrogate bundle directory (None: the shipped one).
    force : bool
        Rerun finished phases instead of reusing them.
    seed : int
        Seed of the JAX keys (agent ``definity``: seed, ``sonovue``: seed + 1000).
    priors : Mapping of str to str
        Agent -> priors name or TOML path replacing the workflow's; with ``data`` the keys are agent labels of
        the file, or ``'*'`` for every agent without its own (default: the shipped priors of the published agent
        of the agent's protocol).
    data_dir : Path or None
        Folder of curve CSVs in DPD units named like the shipped ones (``<agent>_<kind>_<D>um_dpd.csv``) and/or
        ``acoustic_observations_published.csv``, replacing them.
    data : Path or None
        A tidy curves file of measured bubbles (nm, nN, any diameter in the bundle's range;
        docs/data-formats.md, "Tidy bubble files"): one hierarchy per agent label replaces the published study.
    acoustic_data : Path or None
        A tidy resonance file (MHz) for the agents of ``data``: one acoustic dataset per row.
    networks : str
        Network over the diameter serving a curve (the bubbles of ``data``, the published curves with ``surrogates``
        'over-diameter'): 'fast' or 'accurate' (a bundle without a fast network answers with its accurate one).
    surrogates : str or None
        Surrogates of the published study (:data:`SURROGATE_CHOICES`): 'over-diameter' (the networks over the
        diameter, role ``networks``, and the acoustic laws; the per-diameter file where none covers a diameter)
        or 'per-diameter' (the files fitted at each published diameter: the paper's set-up). None:
        'over-diameter', also with ``paper`` (:attr:`resolved_surrogates`). ``data`` always uses the networks over
        the diameter.
    curves : tuple of str
        Restrict to these curve names (e.g. 'definity_compression_2.1um'); empty: all.
    phase2_samples : int or None
        Phase-1 draws per dataset in the phase-2 importance sums, and ψ draws in the phase-3 population prior
        (None: :func:`phase2_samples`).
    num_mcmc_steps : int
        Random-walk Metropolis steps per TMCMC stage.
    chunk_size : int or None
        Particles per TMCMC density evaluation (GPU memory at N = 50,000); None: TMCMC's 'auto'.
    predictive_samples : int
        Posterior draws used by the predictive bands, CRPS and the population predictive.
    crps_replicates : int
        Monte Carlo replicates of the CRPS (``docs/inference.md`` section 7).
    nuts_warmup, nuts_samples, nuts_chains : int
        NUTS warm-up steps and draws per chain, and chains (``sampler='nuts'``).
    netcdf : bool
        Write phase files as ArviZ NetCDF (else ``.npz``).
    figures : bool
        Draw figures and ``report.md`` (needs pandas and matplotlib).
    summaries : bool
        Compute ``summary.csv`` / ``ess.csv`` (needs pandas).
    phase3 : str
        'published' (the Korali phase 3: population prior over p(ψ | D), which holds the dataset's own
        data) or 'exact' (over p(ψ | D_{-i}) by leave-one-out weights: Θ_i is the joint model's marginal).
    phase3_start : str
        One of :data:`PHASE3_STARTS`: the same posterior and evidence (``docs/inference.md`` section 4).
    """

    agents: tuple[str, ...] = AGENTS
    workflow: str = "reduced-acoustic"
    sampler: str = "tmcmc"
    population: int | None = None
    paper: bool = False
    out: Path = Path("calibration")
    device: str = "cpu"
    bundle: Path | None = None
    force: bool = False
    seed: int = 0
    priors: Mapping[str, str] = field(default_factory=dict)
    data_dir: Path | None = None
    data: Path | None = None
    acoustic_data: Path | None = None
    networks: str = "fast"
    surrogates: str | None = None
    curves: tuple[str, ...] = ()
    phase2_samples: int | None = None
    num_mcmc_steps: int = 10
    chunk_size: int | None = None
    predictive_samples: int = 5000
    crps_replicates: int = 5
    nuts_warmup: int = 500
    nuts_samples: int = 500
    nuts_chains: int = 2
    netcdf: bool = True
    figures: bool = True
    summaries: bool = True
    phase3: str = "published"
    phase3_start: str = "phase1"

    def __post_init__(self) -> None:
        # integer settings: (field, lowest, highest, may be None); checked here so the library refuses what
        # the CLI refuses, before anything is sampled
        limits = (("population", 2, MAX_POPULATION, True), ("seed", 0, 2**32 - 1, False),
                  ("phase2_samples", 10, MAX_POPULATION, True), ("num_mcmc_steps", 1, 10_000, False),
                  ("chunk_size", 1, MAX_POPULATION, True), ("predictive_samples", 10, 10**6, False),
                  ("crps_replicates", 1, 1000, False), ("nuts_warmup", 1, 10**6, False),
                  ("nuts_samples", 1, 10**6, False), ("nuts_chains", 1, 64, False))
        for name, lo, hi, optional in limits:
            v = getattr(self, name)
            if v is None and optional:
                continue
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise CalibrationError(f"{name} (--{name.replace('_', '-').replace('num-', '')}) must be an integer in "
                                       f"[{lo:,}, {hi:,}]{' or unset' if optional else ''}, got {v!r}")

    @property
    def num_particles(self) -> int:
        """TMCMC particles per phase: ``population``, else the paper's or the default number."""
        if self.population is not None:
            return int(self.population)
        return PAPER_POPULATION if self.paper else DEFAULT_POPULATION

    @property
    def target_cov(self) -> tuple[float, float]:
        """(phase 1, phases 2 and 3) target coefficient of variation of the TMCMC weights."""
        return PAPER_COV

    @property
    def cov_scale(self) -> float:
        """Covariance scaling s² of the TMCMC proposal."""
        return PAPER_COV_SCALE

    @property
    def resolved_surrogates(self) -> str:
        """The surrogates this run uses (:data:`SURROGATE_CHOICES`): ``surrogates`` when set, else 'over-diameter'
        (with ``paper`` too: the paper's sampler settings on the default surrogates; its per-diameter networks are
        'per-diameter'); always 'over-diameter' with ``data``."""
        if self.data is not None:
            return "over-diameter"
        return self.surrogates if self.surrogates is not None else "over-diameter"

    def surrogate_lookup(self) -> dict[str, str]:
        """``prefer`` (:attr:`resolved_surrogates`) and ``network`` of :meth:`bubblecal.surrogates.Bundle.get`:
        the keyword arguments that pick this run's mechanical surrogates."""
        return {"prefer": self.resolved_surrogates, "network": self.networks}

    def as_dict(self) -> dict:
        """The settings as a JSON-able dict (paths as strings, plus ``num_particles``); ``surrogates`` is written
        as :attr:`resolved_surrogates`, so a rebuilt run uses what it ran on whatever the default becomes.

        Returns
        -------
        dict
            The manifest's ``run.config``; its hash is the run's ``config_hash``.
        """
        d = dataclasses.asdict(self)
        d["surrogates"] = self.resolved_surrogates
        d.update({k: (None if v is None else str(v)) for k, v in d.items() if isinstance(v, Path)})
        d["agents"] = list(self.agents)
        d["priors"] = {k: str(v) for k, v in self.priors.items()}
        d["curves"] = list(self.curves)
        d["num_particles"] = self.num_particles
        return d

    @classmethod
    def from_dict(cls, d: Mapping) -> CalibrationConfig:
        """The config a manifest's ``run.config`` describes: the inverse of :meth:`as_dict`.

        A manifest without ``surrogates`` ran the published study on the per-diameter files, one without
        ``networks`` on the accurate networks: both read so.

        Parameters
        ----------
        d : Mapping
            A dict written by :meth:`as_dict` (derived keys such as ``num_particles`` are ignored).

        Returns
        -------
        CalibrationConfig
            ``from_dict(c.as_dict())`` equals ``c`` with ``surrogates`` set to ``c.resolved_surrogates``.
        """
        names = {f.name for f in dataclasses.fields(cls)}
        kw = {k: v for k, v in d.items() if k in names}
        if "surrogates" not in d and d.get("data") is None:
            kw["surrogates"] = "per-diameter"
        if "networks" not in d:
            kw["networks"] = "accurate"
        for k in ("agents", "curves"):
            kw[k] = tuple(kw.get(k) or ())
        for k in _PATH_FIELDS:
            if kw.get(k) is not None:
                kw[k] = Path(kw[k])
        kw["priors"] = dict(kw.get("priors") or {})
        return cls(**kw)


#: the fields that hold a path (strings in :meth:`CalibrationConfig.as_dict`)
_PATH_FIELDS = ("out", "bundle", "data_dir", "data", "acoustic_data")


def config_from_agents(agent: str, **kwargs) -> CalibrationConfig:
    """Build a config from the CLI's ``--agent definity|sonovue|all``.

    Parameters
    ----------
    agent : str
        An agent name or 'all'.
    **kwargs
        Other :class:`CalibrationConfig` fields.

    Returns
    -------
    CalibrationConfig
    """
    agents = AGENTS if agent == "all" else (agent,)
    return CalibrationConfig(agents=tuple(agents), **kwargs)


def phase_tmcmc_options(config: CalibrationConfig) -> tuple[dict, dict]:
    """TMCMC keyword arguments of (phase 1, phases 2 and 3).

    Parameters
    ----------
    config : CalibrationConfig

    Returns
    -------
    tuple of dict
        ``num_particles``, ``cov_scale``, ``num_mcmc_steps``, ``target_cov`` (and ``chunk_size`` when set);
        these dicts enter the phase hashes.
    """
    base = {"num_particles": config.num_particles, "cov_scale": config.cov_scale,
            "num_mcmc_steps": config.num_mcmc_steps}
    if config.chunk_size:
        base["chunk_size"] = int(config.chunk_size)
    c1, c23 = config.target_cov
    return {**base, "target_cov": c1}, {**base, "target_cov": c23}


def phase2_samples(config: CalibrationConfig, num_datasets: int | None = None) -> int:
    """Phase-1 draws per dataset used by phase 2, or ψ draws kept for the phase-3 prior.

    Parameters
    ----------
    config : CalibrationConfig
    num_datasets : int or None
        Datasets of the agent's phase 2: each gives at most :data:`PHASE2_DRAW_BUDGET` / ``num_datasets`` draws
        (at least :data:`MIN_PHASE2_SAMPLES`). None: the ψ draws of phase 3 (no budget).

    Returns
    -------
    int
        ``config.phase2_samples`` when set, else min(N, :data:`DEFAULT_PHASE2_SAMPLES`) within the budget.
    """
    if config.phase2_samples:
        return int(config.phase2_samples)
    n = min(config.num_particles, DEFAULT_PHASE2_SAMPLES)
    if num_datasets:
        n = min(n, max(MIN_PHASE2_SAMPLES, PHASE2_DRAW_BUDGET // int(num_datasets)))
    return int(n)


def min_population(n_dims: int) -> int:
    """Smallest accepted particle number for a phase sampling ``n_dims`` parameters.

    Parameters
    ----------
    n_dims : int
        Sampled dimensions of the phase.

    Returns
    -------
    int
        max(:data:`MIN_PARTICLES`, :data:`PARTICLES_PER_DIMENSION` x ``n_dims``).
    """
    return max(MIN_PARTICLES, PARTICLES_PER_DIMENSION * n_dims)

def agent_seed(seed: int, agent: str) -> int:
    """The seed of one agent's JAX keys: ``seed`` for Definity, ``seed + 1000`` for SonoVue (the published
    study's), and for any other label ``seed`` plus a stable offset of the label (the same on every machine).

    Parameters
    ----------
    seed : int
        The run's seed (``--seed``).
    agent : str
        Agent name or label.

    Returns
    -------
    int
        A seed in [0, 2**32).
    """
    import zlib

    offset = {"definity": 0, "sonovue": 1000}.get(agent, 2000 + zlib.crc32(agent.encode("utf-8")) % 1_000_000)
    return (int(seed) + offset) % 2**32


def priors_fit_problems(spec, *, protocol: str, workflow: str, who: str) -> list[str]:
    """What keeps a priors file from serving a workflow on curves of one protocol (empty when it fits).

    Parameters
    ----------
    spec : bubblecal.priors.PriorSpec
        The loaded priors (its ``path`` names the file in the messages).
    protocol : str
        'compression' or 'indentation': the loading protocol of the curves.
    workflow : str
        A name of :data:`WORKFLOWS`; 'reduced-acoustic' needs ``workflow.acoustic = true``, the others false.
    who : str
        The curves' owner in the messages, e.g. "the definity curves" or "agent 'batch-7'".

    Returns
    -------
    list of str
        One message per problem, naming the file, the field, its value and what is needed.
    """
    problems = []
    if spec.setup != protocol:
        problems.append(f"{spec.path}: field workflow.setup is {spec.setup!r}, but {who} are {protocol} curves")
    wants = workflow == "reduced-acoustic"
    if spec.acoustic != wants:
        problems.append(f"{spec.path}: field workflow.acoustic is {str(spec.acoustic).lower()}, but workflow "
                        f"{workflow!r} of {who} needs {str(wants).lower()}")
    return problems
