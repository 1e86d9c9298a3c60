"""The ``bubblecal calibrate`` main job: staged hierarchy per agent on the shipped data, priors and surrogates.

Pipeline (``shared/docs/inference.md`` §4, §7)::

    config = CalibrationConfig(agents=("definity", "sonovue"), workflow="reduced-acoustic", out=Path("calibration"))
    plan = make_plan(config)          # validates EVERYTHING before any sampling (CalibrationError otherwise)
    results = run_calibration(plan)   # phases 1 -> 2 -> 3 per agent, summaries, figures, report.md

Per agent the datasets are its three loading curves (phase 1: one TMCMC posterior each, under the uniform
priors of the workflow's TOML) and, in the acoustic workflow, its acoustic datasets (Definity's 14
bubbles = one dataset, SonoVue's 3 bubbles = three, :func:`bubblecal.data.acoustic_datasets`).
Phase 2 samples the population ψ = (m_k, τ_k) (:func:`bubblecal.models.phase2_model`), phase 3 every
dataset under the learned population prior (``population=`` of the single-dataset models, p0 divided
out), then the population-predictive θ_new for a new bubble. ``sampler="nuts"`` samples the joint model
(:func:`bubblecal.models.hierarchical_model`, non-centred) with NUTS instead and reports the same summaries.

Output, under ``out/<agent>/<workflow>/``:

* ``phase1_<dataset>.nc``, ``phase2.nc``, ``phase3_<dataset>.nc`` (ArviZ NetCDF; ``.npz`` when
  ``netcdf=False``, e.g. on a machine without ArviZ), each written atomically (temp file + rename) as soon
  as the phase ends; ``joint_nuts.nc`` for NUTS;
* ``manifest.json``: the configuration, its hash and per phase the config hash, log Z, status, wall time.
  A phase whose file exists and whose hash matches is reused on rerun (``force=True`` reruns all). The
  hash of a phase covers its data, priors, surrogate, sampler settings, seed and the hashes of the
  phases it depends on;
* ``summary.csv`` (see :mod:`bubblecal.workflows.report`), ``ess.csv``, ``figures/*.png``, ``report.md``.

Units: DPD inside; summaries add physical units (E [MPa] from k_a, κ [k_BT] from k_b, d0 [nm], CRPS in
nN for compression / nm for indentation / MHz for acoustics) through :mod:`bubblecal.data.units`.
MAP = the posterior draw with the largest log likelihood + log prior; every prior of the staged phases is
uniform (the phase-3 population prior is a likelihood factor), so this is the largest stored log likelihood.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import json
import math
import time
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bubblecal.data import atomic_write

__all__ = ["AGENTS", "WORKFLOWS", "SAMPLERS", "PHASE3_TARGETS", "DEVICES", "DEFAULT_POPULATION", "PAPER_POPULATION",
           "CalibrationError", "CalibrationConfig", "AgentPlan", "Plan", "PhaseStore", "AgentResult", "make_plan", "run_calibration",
           "run_agent", "resolve_bundle", "phase_tmcmc_options", "min_population"]

AGENTS = ("definity", "sonovue")
WORKFLOWS = ("reduced-acoustic", "reduced", "full")
SAMPLERS = ("tmcmc", "nuts")
#: phase 3 of the staged hierarchy: the published (Korali) target or the joint model's marginal
PHASE3_TARGETS = ("published", "exact")
DEVICES = ("cpu", "gpu")
#: Default particles per phase: both agents (reduced-acoustic) finish on 2 loaded CPU cores in < 10 min
#: (compile-dominated with the synthetic bundle: N = 1000, 2000, 5000 take 118, 116, 134 s unloaded; larger
#: shipped MLPs cost more per particle, hence not more)
#: (benchmarks/RESULTS.md).
DEFAULT_POPULATION = 2000
#: The published settings (``--paper``): N = 50,000 per phase, target CoV 0.8 (phase 1) / 0.6 (phases 2, 3),
#: covariance scaling s² = 0.04.
PAPER_POPULATION = 50_000
PAPER_COV = (0.8, 0.6)
PAPER_COV_SCALE = 0.04
#: Particles per sampled dimension that every phase needs at least (and an absolute floor).
PARTICLES_PER_DIMENSION = 20
MIN_PARTICLES = 100


class CalibrationError(ValueError):
    """A calibration input is invalid; the message names the file / field / range. Raised before sampling."""


@dataclass(frozen=True)
class CalibrationConfig:
    """Settings of one calibration run (CLI: ``bubblecal calibrate``).

    ``agents``: subset of :data:`AGENTS`; ``workflow``: one of :data:`WORKFLOWS` (priors
    ``priors/<agent>_<workflow>.toml`` unless ``priors`` maps the agent to another TOML); ``sampler``:
    'tmcmc' (staged) or 'nuts' (joint); ``population``: TMCMC particles N per phase (``paper=True``: the
    published 50,000, CoV 0.8/0.6, s² 0.04); ``phase2_samples``: phase-1 draws per dataset used by the
    phase-2 importance sums, and phase-2 ψ draws used by the phase-3 population prior (None: min(N, 2000));
    ``out``: output root; ``device``: 'cpu' or 'gpu';
    ``bundle``: surrogate bundle directory (None: the shipped one); ``force``: rerun finished phases;
    ``data_dir``: optional folder of curve CSVs (DPD units) named like the shipped ones
    (``<agent>_<kind>_<D>um_dpd.csv``) and/or ``acoustic_observations_published.csv`` replacing them;
    ``chunk_size``: TMCMC evaluates the likelihood this many particles at a time (GPU memory at N = 50,000);
    ``curves``: restrict to these curve names (e.g. 'definity_compression_2.1um'; empty: all);
    ``netcdf``: write ArviZ NetCDF (else .npz); ``figures``: draw figures and the report; ``summaries``:
    compute summary.csv / ess.csv (needs pandas; ``figures`` needs it too); ``phase3``: 'published' (the
    Korali phase 3: population prior over p(ψ | D), which holds the dataset's own data) or 'exact'
    (over p(ψ | D_{-i}) by leave-one-out weights: Θ_i is the joint model's marginal).
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

    @property
    def num_particles(self) -> int:
        if self.population is not None:
            return int(self.population)
        return PAPER_POPULATION if self.paper else DEFAULT_POPULATION

    @property
    def target_cov(self) -> tuple[float, float]:
        """(phase 1, phases 2 and 3) target coefficient of variation."""
        return PAPER_COV

    @property
    def cov_scale(self) -> float:
        return PAPER_COV_SCALE

    def as_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d.update({k: (None if v is None else str(v)) for k, v in d.items() if isinstance(v, Path)})
        d["agents"] = list(self.agents)
        d["priors"] = {k: str(v) for k, v in self.priors.items()}
        d["curves"] = list(self.curves)
        d["num_particles"] = self.num_particles
        return d


def phase_tmcmc_options(config: CalibrationConfig) -> tuple[dict, dict]:
    """TMCMC keyword arguments of (phase 1, phases 2 and 3)."""
    base = {"num_particles": config.num_particles, "cov_scale": config.cov_scale,
            "num_mcmc_steps": config.num_mcmc_steps}
    if config.chunk_size:
        base["chunk_size"] = int(config.chunk_size)
    c1, c23 = config.target_cov
    return {**base, "target_cov": c1}, {**base, "target_cov": c23}


def min_population(n_dims: int) -> int:
    """Smallest accepted particle number for a phase sampling ``n_dims`` parameters."""
    return max(MIN_PARTICLES, PARTICLES_PER_DIMENSION * n_dims)


# ------------------------------------------------------------------------------------------------
# plan: every check before sampling
# ------------------------------------------------------------------------------------------------
@dataclass
class AgentPlan:
    """What one agent's run needs: priors, curves with their surrogates, acoustic datasets, output folder."""

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

    @property
    def dataset_names(self) -> list[str]:
        return [c.name for c in self.curves] + [d.name for d in self.acoustic]

    def dims(self) -> dict[str, int]:
        """Sampled dimensions of each phase (phase 1 / 3: the largest dataset; phase 2: 2 per pooled parameter)."""
        spec = self.spec
        mech = len(spec.parameters) + 1
        ac = 2 if self.acoustic else 0
        return {"phase1": max(mech, ac), "phase2": 2 * len(spec.pooled_names), "phase3": max(mech, ac)}


@dataclass
class Plan:
    config: CalibrationConfig
    bundle: object
    bundle_path: Path
    synthetic_bundle: bool
    agents: list[AgentPlan]


def resolve_bundle(path: Path | None) -> Path:
    """The bundle directory to use: ``path`` or the shipped default (CalibrationError with advice if absent)."""
    from bubblecal.surrogates import NoDefaultBundleError, default_bundle_path

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


def _workflow_priors_name(agent: str, workflow: str) -> str:
    from bubblecal.priors import workflow_file_name

    return workflow_file_name(agent, workflow)


def _load_curves(agent: str, data_dir: Path | None) -> list:
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
    from bubblecal.data import DataError, acoustic_datasets, load_acoustic_table

    path = None if data_dir is None else Path(data_dir) / "acoustic_observations_published.csv"
    if path is not None and path.is_file():
        try:
            rows = load_acoustic_table(path)
        except DataError as exc:
            raise CalibrationError(str(exc)) from None
        return acoustic_datasets(agent, rows)
    return acoustic_datasets(agent)


def make_plan(config: CalibrationConfig) -> Plan:
    """Validate the whole configuration and load every input; raise :class:`CalibrationError` (one clear
    message naming the file, field or range) before any sampling starts."""
    from bubblecal.priors import PriorError, load_priors
    from bubblecal.surrogates import (
        AcousticFormatError,
        AcousticRangeError,
        SurrogateFormatError,
        is_synthetic_bundle,
        load_bundle,
    )

    bad = [a for a in config.agents if a not in AGENTS]
    if bad or not config.agents:
        raise CalibrationError(f"--agent must be one of {', '.join(AGENTS)} or all, got {', '.join(bad) or 'none'}")
    if config.workflow not in WORKFLOWS:
        raise CalibrationError(f"--workflow must be one of {', '.join(WORKFLOWS)}, got {config.workflow!r}")
    if config.sampler not in SAMPLERS:
        raise CalibrationError(f"--sampler must be one of {', '.join(SAMPLERS)}, got {config.sampler!r}")
    if config.phase3 not in PHASE3_TARGETS:
        raise CalibrationError(f"--phase3 must be one of {', '.join(PHASE3_TARGETS)}, got {config.phase3!r}")
    if config.device not in DEVICES:
        raise CalibrationError(f"--device must be one of {', '.join(DEVICES)}, got {config.device!r}")
    _check_device(config.device)
    if config.num_mcmc_steps < 1:
        raise CalibrationError(f"--mcmc-steps must be >= 1, got {config.num_mcmc_steps}")
    if config.crps_replicates < 1 or config.predictive_samples < 10:
        raise CalibrationError("crps_replicates must be >= 1 and predictive_samples >= 10")
    if config.phase2_samples is not None and config.phase2_samples < 10:
        raise CalibrationError(f"phase2_samples must be >= 10, got {config.phase2_samples}")
    if config.data_dir is not None and not Path(config.data_dir).is_dir():
        raise CalibrationError(f"--data-dir {config.data_dir}: not a directory")

    bundle_path = resolve_bundle(config.bundle)
    try:
        bundle = load_bundle(bundle_path)
    except (SurrogateFormatError, AcousticFormatError, FileNotFoundError, KeyError, ValueError) as exc:
        raise CalibrationError(f"surrogate bundle {bundle_path}: {exc}") from None

    agents = []
    for agent in config.agents:
        source = config.priors.get(agent, _workflow_priors_name(agent, config.workflow))
        try:
            spec = load_priors(source)
        except PriorError as exc:
            raise CalibrationError(str(exc)) from None
        if spec.agent != agent:
            raise CalibrationError(f"{spec.path}: field workflow.agent is {spec.agent!r}, expected {agent!r}")
        wants_acoustic = config.workflow == "reduced-acoustic"
        if spec.acoustic != wants_acoustic:
            raise CalibrationError(f"{spec.path}: field workflow.acoustic is {str(spec.acoustic).lower()}, but workflow "
                                   f"{config.workflow!r} needs {str(wants_acoustic).lower()}")
        curves = _load_curves(agent, config.data_dir)
        if config.curves:
            from bubblecal.data import REFERENCE_CURVES

            unknown = [c for c in config.curves if c not in REFERENCE_CURVES]
            if unknown:
                raise CalibrationError(f"--curve {', '.join(unknown)}: unknown; curves: {', '.join(REFERENCE_CURVES)}")
            curves = [c for c in curves if c.name in config.curves]
            if not curves:
                raise CalibrationError(f"--curve: none of {', '.join(config.curves)} belongs to {agent}")
        surrogates, domain = [], []
        for curve in curves:
            try:
                sur = bundle.get(curve.kind, curve.diameter_um)
            except KeyError as exc:
                raise CalibrationError(f"{exc.args[0]}; the {agent} curve {curve.name} needs it") from None
            if spec.setup != curve.kind:
                raise CalibrationError(f"{spec.path}: field workflow.setup is {spec.setup!r}, the {agent} curves are "
                                       f"{curve.kind}")
            surrogates.append(sur)
            domain += _domain_messages(sur, spec, curve.x)
        acoustic, f_res = [], None
        if spec.acoustic:
            acoustic = _load_acoustic(agent, config.data_dir)
            if not acoustic:
                raise CalibrationError(f"no acoustic observations of {agent} (workflow {config.workflow})")
            if agent not in bundle.acoustic:
                raise CalibrationError(f"bundle {bundle_path} has no acoustic surrogate {agent!r} (has: "
                                       f"{', '.join(bundle.acoustic) or 'none'}); workflow {config.workflow} needs it")
            f_res = bundle.acoustic[agent]
            lo, hi = spec.parameters["ka"].prior.as_tuple()
            for ds in acoustic:
                for d in np.atleast_1d(ds.diameter_um):
                    try:
                        r_lo, r_hi = f_res.ka_ranges(float(d))
                    except AcousticRangeError as exc:
                        raise CalibrationError(f"bundle {bundle_path}: {exc}; acoustic dataset {ds.name} needs it") from None
                    if lo < r_lo * (1 - 1e-9) or hi > r_hi * (1 + 1e-9):
                        domain.append(f"acoustic {agent} {float(d):g} um: fitted ka range [{r_lo:.6g}, {r_hi:.6g}] "
                                      f"does not contain the ka prior [{lo:.6g}, {hi:.6g}]")
        ap = AgentPlan(agent=agent, workflow=config.workflow, spec=spec, priors_path=Path(spec.path), curves=curves,
                       surrogates=surrogates, acoustic=acoustic, f_res=f_res,
                       out_dir=Path(config.out) / agent / config.workflow, domain_warnings=domain)
        n = config.num_particles
        if config.sampler == "tmcmc":
            for phase, dim in ap.dims().items():
                need = min_population(dim)
                if n < need:
                    raise CalibrationError(f"--population {n} is too small: {agent} {phase} samples {dim} parameters "
                                           f"and needs N >= {need} ({PARTICLES_PER_DIMENSION} per dimension, at least "
                                           f"{MIN_PARTICLES})")
        agents.append(ap)
    return Plan(config=config, bundle=bundle, bundle_path=bundle_path,
                synthetic_bundle=is_synthetic_bundle(bundle), agents=agents)


def _domain_messages(surrogate, spec, x) -> list[str]:
    """The prior box vs training box check of ``bubblecal compare`` (skipped where typer/rich are absent)."""
    try:
        from bubblecal.workflows.cli_compare import _prior_box_domain_warnings
    except ImportError:  # pragma: no cover - minimal device images
        return []
    return _prior_box_domain_warnings(surrogate, spec, x)


def _check_device(device: str) -> None:
    import jax

    if device == "gpu":
        try:
            jax.devices("gpu")
        except RuntimeError:
            raise CalibrationError("--device gpu: JAX sees no GPU on this machine (jax.devices() = "
                                   f"{[d.platform for d in jax.devices()]}); use --device cpu") from None


@contextlib.contextmanager
def _on_device(device: str):
    import jax

    platform = "gpu" if device == "gpu" else "cpu"
    with jax.default_device(jax.devices(platform)[0]):
        yield


# ------------------------------------------------------------------------------------------------
# phase store: atomic files, manifest with config hashes, reuse
# ------------------------------------------------------------------------------------------------
def _hash(obj) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _array_hash(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(np.asarray(a, dtype="<f8")).tobytes())
    return h.hexdigest()[:16]


class PhaseStore:
    """Phase files of one agent/workflow folder plus ``manifest.json`` (config hash per phase).

    ``expected[name]`` holds the hash a phase must carry to be reused; :meth:`load` returns the stored
    :class:`~bubblecal.inference.hierarchical.PhaseResult` when file and hash match (and not ``force``),
    :meth:`save` writes the file atomically and records it in the manifest.
    """

    def __init__(self, folder: Path, netcdf: bool = True, force: bool = False, run_info: Mapping | None = None):
        self.folder = Path(folder)
        self.netcdf = netcdf
        self.force = force
        self.expected: dict[str, str] = {}
        self.loglik: dict[str, np.ndarray] = {}
        self.reused: list[str] = []
        self.manifest_path = self.folder / "manifest.json"
        self.manifest = self._read_manifest()
        if run_info is not None:
            self.manifest["run"] = dict(run_info)

    def _read_manifest(self) -> dict:
        if self.manifest_path.is_file():
            try:
                return json.loads(self.manifest_path.read_text())
            except json.JSONDecodeError:
                pass
        return {"format": "bubblecal-calibration-run", "format_version": 1, "phases": {}}

    def write_manifest(self) -> None:
        text = json.dumps(self.manifest, indent=1, default=str, allow_nan=True)
        atomic_write(self.manifest_path, lambda p: p.write_text(text))

    def path(self, name: str) -> Path:
        return self.folder / (f"{name}.nc" if self.netcdf else f"{name}.npz")

    def _existing(self, name: str) -> Path | None:
        for suffix in (".nc", ".npz"):
            p = self.folder / f"{name}{suffix}"
            if p.is_file():
                return p
        return None

    def load(self, name: str):
        entry = self.manifest["phases"].get(name)
        path = self._existing(name)
        if self.force or entry is None or path is None or entry.get("config_hash") != self.expected.get(name):
            return None
        result, loglik = read_phase(path)
        self.loglik[name] = loglik
        self.reused.append(name)
        return result

    def save(self, result) -> None:
        name = result.name
        path = self.path(name)
        loglik = np.asarray(result.sampler.state.log_likelihood) if result.sampler is not None else None
        if loglik is not None:
            self.loglik[name] = loglik
        attrs = {"config_hash": self.expected.get(name, ""), "phase": name}
        write_phase(path, result, loglik, attrs)
        self.manifest["phases"][name] = {
            "file": path.name, "config_hash": self.expected.get(name, ""), "log_evidence": result.log_evidence,
            "log_evidence_se": result.log_evidence_se if math.isfinite(result.log_evidence_se) else None,
            "status": result.status, "seconds": result.seconds,
            "num_draws": int(next(iter(result.samples.values())).shape[0])}
        self.write_manifest()


def write_phase(path: Path, result, loglik, attrs: Mapping) -> Path:
    """Write a phase result atomically: ArviZ NetCDF (``.nc``) or plain ``.npz`` (samples + attrs JSON)."""
    path = Path(path)
    meta = {"log_evidence": result.log_evidence, "log_evidence_se": result.log_evidence_se, "status": result.status,
            "seconds": result.seconds, "name": result.name, **attrs}
    if path.suffix == ".nc":
        import arviz as az

        if result.sampler is not None:
            idata = result.sampler.to_inference_data()
        else:
            stats = {"loglik": np.asarray(loglik)[None]} if loglik is not None else None
            idata = az.from_dict(posterior={k: np.asarray(v)[None] for k, v in result.samples.items()},
                                 sample_stats=stats)
        idata.posterior.attrs.update({k: (json.dumps(v) if isinstance(v, (dict, list)) else
                                          ("nan" if isinstance(v, float) and not math.isfinite(v) else v))
                                      for k, v in meta.items()})
        atomic_write(path, lambda p: idata.to_netcdf(str(p)))
    else:
        arrays = {f"sample__{k}": np.asarray(v) for k, v in result.samples.items()}
        if loglik is not None:
            arrays["loglik"] = np.asarray(loglik)
        arrays["meta"] = np.array(json.dumps(meta, default=str))

        def _w(p):
            with open(p, "wb") as fh:
                np.savez(fh, **arrays)

        atomic_write(path, _w)
    return path


def read_phase(path: Path):
    """(PhaseResult, loglik or None) from a file written by :func:`write_phase`."""
    from bubblecal.inference import PhaseResult

    path = Path(path)
    if path.suffix == ".nc":
        import arviz as az

        idata = az.from_netcdf(str(path))
        post = idata.posterior
        samples = {k: np.asarray(post[k].values[0]) for k in post.data_vars}
        meta = dict(post.attrs)
        loglik = (np.asarray(idata.sample_stats["loglik"].values[0])
                  if "sample_stats" in idata.groups() and "loglik" in idata.sample_stats else None)
    else:
        with np.load(path, allow_pickle=False) as npz:
            samples = {k[len("sample__"):]: npz[k] for k in npz.files if k.startswith("sample__")}
            loglik = npz["loglik"] if "loglik" in npz.files else None
            meta = json.loads(str(npz["meta"]))

    def _f(v):
        try:
            return float(v)
        except (TypeError, ValueError):
            return math.nan

    result = PhaseResult(name=str(meta.get("name", meta.get("phase", path.stem))), samples=samples,
                         log_evidence=_f(meta.get("log_evidence")), log_evidence_se=_f(meta.get("log_evidence_se")),
                         status=str(meta.get("status", "converged")), seconds=_f(meta.get("seconds")))
    return result, loglik


# ------------------------------------------------------------------------------------------------
# running one agent
# ------------------------------------------------------------------------------------------------
@dataclass
class AgentResult:
    """Everything one agent's run produced (paths under ``plan.out_dir``)."""

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


def _curve_arguments(ap: AgentPlan, pad: bool) -> list[tuple[tuple, dict]]:
    """(args, kwargs) of :func:`bubblecal.models.mechanical_model` for every curve of the agent.

    The surrogate goes in as a :class:`~bubblecal.models.TracedSurrogate`, so its weights are
    arguments of the compiled TMCMC programs and curves whose networks have one shape share them. With
    ``pad`` those curves are also padded (masked) to one length, so they share the programs in fact; it
    costs the padded points' evaluations, hence only where compiling dominates (the GPU).
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
        if pad:  # every curve of a group gets a mask (all True on the longest): one argument structure
            x, y, mask = pad_curve(x, y, length[shape_key(sur)])
            out.append(((x, y, sur, ap.spec), {"mask": mask}))
        else:
            out.append(((x, y, sur, ap.spec), {}))
    return out


def _pad_curves(config: CalibrationConfig) -> bool:
    """Pad curves of one network shape to one length (shared compiled programs): on the GPU only, where
    compiling a phase's programs costs more than the padded points; on CPU cores the particles dominate."""
    return config.device == "gpu"


def _dataset_objects(ap: AgentPlan, pad: bool = False):
    from bubblecal.inference import Dataset
    from bubblecal.models import acoustic_model, mechanical_model

    out = []
    for curve, (args, kwargs) in zip(ap.curves, _curve_arguments(ap, pad), strict=True):
        out.append(Dataset(curve.name, mechanical_model, args, kwargs))
    for ds, args in zip(ap.acoustic, _acoustic_arguments(ap), strict=True):
        out.append(Dataset(ds.name, acoustic_model, args))
    return out


def _acoustic_arguments(ap: AgentPlan) -> list[tuple]:
    """Positional arguments of :func:`bubblecal.models.acoustic_model` for every acoustic dataset: the
    surrogate's quadratics at the dataset's diameters as a :class:`~bubblecal.models.acoustic.FrequencyTable`
    (arrays, so datasets with as many bubbles share the compiled programs)."""
    from bubblecal.models import FrequencyTable

    return [(np.asarray(ds.diameter_um, dtype=float), np.asarray(ds.frequency_MHz, dtype=float),
             FrequencyTable.at(ap.f_res, ds.diameter_um), ap.spec) for ds in ap.acoustic]


def _phase_hashes(ap: AgentPlan, config: CalibrationConfig, bundle_hashes: Mapping[str, str]) -> dict[str, str]:
    """Config hash of every phase (data, priors, surrogate, sampler settings, seed, upstream hashes)."""
    spec_text = Path(ap.priors_path).read_text() if Path(ap.priors_path).is_file() else repr(ap.spec)
    o1, o23 = phase_tmcmc_options(config)
    common = {"agent": ap.agent, "workflow": ap.workflow, "priors": _hash(spec_text), "seed": config.seed,
              "datasets": ap.dataset_names}
    hashes = {}
    for curve, sur in zip(ap.curves, ap.surrogates, strict=True):
        hashes[f"phase1_{curve.name}"] = _hash({**common, "phase": 1, "data": _array_hash(curve.x, curve.y),
                                                "surrogate": sur.data_hash, "options": o1})
    for ds in ap.acoustic:
        hashes[f"phase1_{ds.name}"] = _hash({**common, "phase": 1, "data": _array_hash(ds.diameter_um, ds.frequency_MHz),
                                             "surrogate": bundle_hashes.get(f"acoustic_{ap.agent}", ""), "options": o1})
    p1 = [hashes[f"phase1_{n}"] for n in ap.dataset_names]
    hashes["phase2"] = _hash({**common, "phase": 2, "upstream": p1, "options": o23,
                              "phase2_samples": _phase2_samples(config)})
    for n in ap.dataset_names:
        h3 = {**common, "phase": 3, "self": hashes[f"phase1_{n}"], "upstream": hashes["phase2"], "options": o23}
        if config.phase3 != "published":  # keeps the hashes of earlier (published) runs unchanged
            h3["phase3"] = config.phase3
        hashes[f"phase3_{n}"] = _hash(h3)
    return hashes


def _phase2_samples(config: CalibrationConfig) -> int:
    return int(config.phase2_samples or min(config.num_particles, 2000))


def _bundle_hashes(bundle) -> dict[str, str]:
    out = {}
    for name, ac in bundle.acoustic.items():
        out[f"acoustic_{name}"] = _hash(ac.to_dict())
    return out


def run_agent(plan: Plan, ap: AgentPlan, *, progress: Callable[[str], None] | None = None,
              inject: Callable[[str], None] | None = None) -> AgentResult:
    """Run one agent (staged TMCMC or joint NUTS), then summaries, figures and its report.

    ``inject(phase_name)`` is called before each phase runs (tests inject crashes through it).
    """
    import jax

    from bubblecal.inference import run_staged
    from bubblecal.models import acoustic_model, mechanical_model, phase2_model

    config = plan.config
    say = progress or (lambda _m: None)
    ap.out_dir.mkdir(parents=True, exist_ok=True)
    run_info = {"config": config.as_dict(), "config_hash": _hash(config.as_dict()), "agent": ap.agent,
                "priors": str(ap.priors_path), "bundle": str(plan.bundle_path), "synthetic_bundle": plan.synthetic_bundle}
    store = PhaseStore(ap.out_dir, netcdf=config.netcdf, force=config.force, run_info=run_info)
    store.expected = _phase_hashes(ap, config, _bundle_hashes(plan.bundle))
    store.write_manifest()
    seconds: dict[str, float] = {}
    t_start = time.perf_counter()
    staged = joint = None
    key = jax.random.PRNGKey(config.seed + (0 if ap.agent == "definity" else 1000))

    if config.sampler == "tmcmc":
        pad = _pad_curves(config)
        datasets = _dataset_objects(ap, pad)
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
            n_psi = _phase2_samples(config)
            size = len(next(iter(m_samples.values())))
            idx = np.linspace(0, size - 1, min(size, n_psi)).round().astype(int)
            pop = ({k: np.asarray(v)[idx] for k, v in m_samples.items()},
                   {k: np.asarray(v)[idx] for k, v in tau_samples.items()})
            if i < n_curves:
                args, kwargs = curve_arguments[i]
                return functools.partial(mechanical_model, *args, **kwargs, population=pop)
            return functools.partial(acoustic_model, *acoustic_arguments[i - n_curves], population=pop)

        def load(name):
            result = store.load(name)
            if result is None and inject is not None:
                inject(name)
            return result

        o1, o23 = phase_tmcmc_options(config)
        with _on_device(config.device), warnings.catch_warnings():
            warnings.simplefilter("ignore", category=FutureWarning)
            reweight = None
            if config.phase3 == "exact":
                from bubblecal.models import leave_one_out_log_weights, pooled_bounds

                bounds = pooled_bounds(ap.spec)

                def reweight(i, phase1_i, m_samples, tau_samples):
                    return leave_one_out_log_weights(m_samples, tau_samples, phase1_i, bounds)

            staged = run_staged(datasets, phase2_factory, phase3_factory, key, phase1_options=o1, phase2_options=o23,
                                phase3_options=o23, phase2_max_samples=_phase2_samples(config), load=load,
                                save=store.save, progress=say, phase3_reweight=reweight)
            if staged.phase3_ess:
                say("phase 3 leave-one-out importance ESS: "
                    + ", ".join(f"{k} {v:.0f}" for k, v in staged.phase3_ess.items()))
        for r in [*staged.phase1, staged.phase2, *staged.phase3]:
            seconds[r.name] = r.seconds
    else:
        joint = _run_joint(ap, config, key, store, say)
        seconds["joint_nuts"] = joint.seconds
    seconds["sampling_total"] = time.perf_counter() - t_start

    t0 = time.perf_counter()
    result = AgentResult(plan=ap, staged=staged, joint=joint, loglik=store.loglik, summary=None, ess=None,
                         population_predictive=None, seconds=seconds, reused=list(store.reused))
    if config.summaries or config.figures:
        from bubblecal.workflows.report import summarise_agent

        summarise_agent(result, config)
    seconds["summaries"] = time.perf_counter() - t0
    store.manifest["summary"] = {"wall_seconds": seconds, "reused": store.reused}
    store.write_manifest()
    return result


@dataclass
class _JointResult:
    samples: dict
    loglik: np.ndarray
    seconds: float
    diagnostics: dict
    reused: bool


def _run_joint(ap: AgentPlan, config: CalibrationConfig, key, store: PhaseStore, say) -> _JointResult:
    """Joint hierarchical model with NUTS (non-centred); reuses ``joint_nuts`` when its hash matches."""
    from numpyro.infer import init_to_value, log_likelihood

    from bubblecal.inference import PhaseResult, run_nuts
    from bubblecal.models import hierarchical_model, nuts_init_values

    name = "joint_nuts"
    store.expected[name] = _hash({"phases": store.expected, "nuts": [config.nuts_warmup, config.nuts_samples,
                                                                      config.nuts_chains], "seed": config.seed})
    cached = store.load(name)
    if cached is not None:
        say(f"{name}: reused")
        return _JointResult(cached.samples, store.loglik.get(name), cached.seconds, {}, True)
    say(f"{name}: running NUTS ({config.nuts_chains} chains x {config.nuts_samples} draws)")
    t0 = time.perf_counter()
    kwargs = {"acoustic": ap.acoustic, "f_res": ap.f_res, "noncentred": True}
    init = nuts_init_values(ap.spec, n_curves=len(ap.curves))
    with _on_device(config.device):
        res = run_nuts(hierarchical_model, ap.curves, ap.surrogates, ap.spec, rng_key=key,
                       num_warmup=config.nuts_warmup, num_samples=config.nuts_samples, num_chains=config.nuts_chains,
                       target_accept_prob=0.9, init_strategy=init_to_value(values=init), **kwargs)
        ll = log_likelihood(hierarchical_model, res.samples, ap.curves, ap.surrogates, ap.spec, **kwargs)
    total_ll = sum(np.asarray(v).reshape(np.asarray(v).shape[0], -1).sum(axis=1) for v in ll.values())
    seconds = time.perf_counter() - t0
    samples = {k: np.asarray(v) for k, v in res.samples.items()}
    result = PhaseResult(name=name, samples=samples, log_evidence=math.nan, log_evidence_se=math.nan,
                         status="converged" if res.converged else "not converged", seconds=seconds)
    store.loglik[name] = total_ll
    write_phase(store.path(name), result, total_ll, {"config_hash": store.expected[name], "phase": name,
                                                      "max_r_hat": res.max_r_hat, "min_n_eff": res.min_n_eff,
                                                      "num_divergences": res.num_divergences})
    store.manifest["phases"][name] = {"file": store.path(name).name, "config_hash": store.expected[name],
                                      "status": result.status, "seconds": seconds, "max_r_hat": res.max_r_hat,
                                      "min_n_eff": res.min_n_eff, "num_divergences": res.num_divergences}
    store.write_manifest()
    diag = {"max_r_hat": res.max_r_hat, "min_n_eff": res.min_n_eff, "num_divergences": res.num_divergences}
    return _JointResult(samples, total_ll, seconds, diag, False)


def run_calibration(plan: Plan, *, progress: Callable[[str], None] | None = None,
                    inject: Callable[[str], None] | None = None) -> list[AgentResult]:
    """Run every agent of ``plan`` (see :func:`run_agent`); figures and report.md per agent."""
    results = []
    for ap in plan.agents:
        result = run_agent(plan, ap, progress=progress, inject=inject)
        if plan.config.figures:
            from bubblecal.workflows.figures import agent_figures
            from bubblecal.workflows.report import write_report

            result.figures = agent_figures(result, plan)
            result.report = write_report(result, plan)
        results.append(result)
    return results


def config_from_agents(agent: str, **kwargs) -> CalibrationConfig:
    """Build a config from the CLI's ``--agent definity|sonovue|all``."""
    agents = AGENTS if agent == "all" else (agent,)
    return CalibrationConfig(agents=tuple(agents), **kwargs)
