"""Typed prior/hyperprior specifications loaded from the user-editable TOML files in this folder.

One file per workflow (``definity_full.toml``, ``sonovue_reduced_acoustic.toml``, ...). The format
is documented at the top of every shipped file. :func:`load_priors` validates the whole file and
raises :class:`PriorError` listing every problem at once (file and key named); nothing is clipped.

Units: DPD (``ka`` 2-D modulus, ``kb`` energy, ``d0`` length; the Lim coefficients and noise
amplitudes are dimensionless) — see :mod:`bubblecal.data.units`.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from bubblecal.data.names import (
    AGENTS,
    LOADING_PROTOCOLS,
    MODEL_PARAMETERS,
    NOISE_PARAMETERS,
    NONLINEAR_PARAMETERS,
    PARAMETER_UNITS,
    POSITIVE_PARAMETERS,
)

__all__ = [
    "Bounds",
    "ParameterPrior",
    "NoisePrior",
    "PriorSpec",
    "PriorError",
    "available_priors",
    "prior_path",
    "load_priors",
    "check_priors",
    "workflow_file_name",
]

_SHELLS = ("full", "reduced")
_WORKFLOW_KEYS = {"agent", "setup", "shell", "acoustic", "description"}
_PARAM_KEYS = {"prior", "hyper_m", "hyper_tau"}


class PriorError(ValueError):
    """A priors file failed validation; ``problems`` names every offending key."""

    def __init__(self, path: str | Path, problems: list[str]):
        self.path = str(path)
        self.problems = list(problems)
        noun = "problem" if len(problems) == 1 else "problems"
        lines = "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(f"priors file {self.path}: {len(self.problems)} {noun}:\n{lines}")


@dataclass(frozen=True)
class Bounds:
    """A closed interval [lo, hi] (units of its parameter)."""

    lo: float
    hi: float

    @property
    def width(self) -> float:
        """hi - lo."""
        return self.hi - self.lo

    def contains(self, value) -> np.ndarray:
        """Elementwise lo <= value <= hi."""
        value = np.asarray(value)
        return (value >= self.lo) & (value <= self.hi)

    def as_tuple(self) -> tuple[float, float]:
        """(lo, hi)."""
        return (self.lo, self.hi)


@dataclass(frozen=True)
class ParameterPrior:
    """Uniform prior of one shell parameter; pooled parameters carry hyperprior bounds of m and tau."""

    name: str
    prior: Bounds
    hyper_m: Bounds | None = None
    hyper_tau: Bounds | None = None

    @property
    def pooled(self) -> bool:
        """True if the parameter is drawn from the population distribution in the hierarchy."""
        return self.hyper_m is not None

    @property
    def unit(self) -> str:
        """Unit of the parameter (DPD)."""
        return PARAMETER_UNITS[self.name]


@dataclass(frozen=True)
class NoisePrior:
    """Uniform prior of a relative noise amplitude (dimensionless); never pooled."""

    name: str
    prior: Bounds


@dataclass(frozen=True)
class PriorSpec:
    """A validated workflow specification: free/fixed shell parameters, noise, hyperpriors.

    ``parameters`` holds the free shell parameters in :data:`MODEL_PARAMETERS` order, ``fixed`` the
    constant ones, ``noise`` the noise amplitudes; ``setup`` is 'compression' or 'indentation'.
    """

    name: str
    path: str
    agent: str
    setup: str
    shell: str
    acoustic: bool
    parameters: dict[str, ParameterPrior]
    fixed: dict[str, float]
    noise: dict[str, NoisePrior]
    description: str = ""

    @property
    def free_names(self) -> tuple[str, ...]:
        """Free shell parameters in canonical order."""
        return tuple(self.parameters)

    @property
    def pooled_names(self) -> tuple[str, ...]:
        """Free parameters pooled in the population model."""
        return tuple(n for n, p in self.parameters.items() if p.pooled)

    @property
    def noise_names(self) -> tuple[str, ...]:
        """Noise amplitudes in file order."""
        return tuple(self.noise)

    @property
    def mechanical_noise_name(self) -> str:
        """'sigma' (spectroscopy-only workflows) or 'sigma_mech' (acoustic workflows)."""
        return "sigma_mech" if self.acoustic else "sigma"

    def bounds(self, name: str) -> Bounds:
        """Prior bounds of a free shell parameter or a noise amplitude."""
        if name in self.parameters:
            return self.parameters[name].prior
        if name in self.noise:
            return self.noise[name].prior
        raise KeyError(f"{name!r} is not a free parameter of {self.name} (free: {', '.join(self.free_names)}; "
                       f"noise: {', '.join(self.noise_names)}; fixed: {', '.join(self.fixed)})")

    def prior_box(self, names: tuple[str, ...] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) arrays of the prior box of ``names`` (default: free shell parameters)."""
        names = self.free_names if names is None else names
        b = [self.bounds(n) for n in names]
        return np.array([x.lo for x in b]), np.array([x.hi for x in b])


# ----------------------------------------------------------------------------------------------
def available_priors() -> list[str]:
    """Names of the shipped workflow files (without .toml)."""
    folder = resources.files("bubblecal.priors")
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def workflow_file_name(agent: str, workflow: str) -> str:
    """Shipped file name for agent and CLI workflow ('full'|'reduced'|'reduced-acoustic')."""
    return f"{agent.lower()}_{workflow.lower().replace('-', '_')}"


def prior_path(name_or_path: str | Path) -> Path:
    """Resolve a shipped workflow name (e.g. 'definity_full') or a file path."""
    candidate = Path(name_or_path)
    if candidate.suffix == ".toml" or candidate.exists():
        return candidate
    key = str(name_or_path).lower().replace("-", "_")
    if key in available_priors():
        return Path(str(resources.files("bubblecal.priors") / f"{key}.toml"))
    raise PriorError(str(name_or_path), [f"no such priors file or shipped workflow; shipped: {', '.join(available_priors())}"])


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _bounds(value, key: str, problems: list[str]) -> Bounds | None:
    if not isinstance(value, list) or len(value) != 2:
        problems.append(f"{key}: must be a list [lo, hi] of two numbers, got {value!r}")
        return None
    lo, hi = value
    if not (_is_number(lo) and _is_number(hi)):
        problems.append(f"{key}: lo and hi must be numbers, got {value!r}")
        return None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        problems.append(f"{key}: bounds must be finite, got {value!r}")
        return None
    if lo >= hi:
        problems.append(f"{key}: lo ({lo:g}) must be smaller than hi ({hi:g})")
        return None
    return Bounds(float(lo), float(hi))


def _validate(raw: dict, problems: list[str]):
    for key in raw:
        if key not in ("workflow", "parameters", "fixed", "noise"):
            problems.append(f"{key}: unknown section (allowed: workflow, parameters, fixed, noise)")

    wf = raw.get("workflow")
    agent = setup = shell = None
    acoustic = False
    description = ""
    if not isinstance(wf, dict):
        problems.append("workflow: missing [workflow] section (agent, setup, shell, acoustic)")
    else:
        for key in wf:
            if key not in _WORKFLOW_KEYS:
                problems.append(f"workflow.{key}: unknown key (allowed: {', '.join(sorted(_WORKFLOW_KEYS))})")
        for key, allowed in (("agent", AGENTS), ("setup", LOADING_PROTOCOLS), ("shell", _SHELLS)):
            value = wf.get(key)
            if value not in allowed:
                problems.append(f"workflow.{key}: {value!r} is not one of {', '.join(allowed)}")
        agent, setup, shell = wf.get("agent"), wf.get("setup"), wf.get("shell")
        acoustic = wf.get("acoustic", None)
        if not isinstance(acoustic, bool):
            problems.append(f"workflow.acoustic: must be true or false, got {acoustic!r}")
            acoustic = False
        description = str(wf.get("description", ""))

    params_raw = raw.get("parameters", {})
    fixed_raw = raw.get("fixed", {})
    noise_raw = raw.get("noise", {})
    for section, value in (("parameters", params_raw), ("fixed", fixed_raw), ("noise", noise_raw)):
        if not isinstance(value, dict):
            problems.append(f"{section}: must be a table, got {type(value).__name__}")
    params_raw = params_raw if isinstance(params_raw, dict) else {}
    fixed_raw = fixed_raw if isinstance(fixed_raw, dict) else {}
    noise_raw = noise_raw if isinstance(noise_raw, dict) else {}

    parameters: dict[str, ParameterPrior] = {}
    for name, entry in params_raw.items():
        key = f"parameters.{name}"
        if name not in MODEL_PARAMETERS:
            problems.append(f"{key}: unknown parameter (allowed: {', '.join(MODEL_PARAMETERS)})")
            continue
        if not isinstance(entry, dict):
            problems.append(f"{key}: must be a table with prior = [lo, hi]")
            continue
        for sub in entry:
            if sub not in _PARAM_KEYS:
                problems.append(f"{key}.{sub}: unknown key (allowed: {', '.join(sorted(_PARAM_KEYS))})")
        if "prior" not in entry:
            problems.append(f"{key}.prior: missing")
            continue
        prior = _bounds(entry["prior"], f"{key}.prior", problems)
        if prior is not None and name in POSITIVE_PARAMETERS and prior.lo <= 0:
            problems.append(f"{key}.prior: lower bound {prior.lo:g} must be > 0 ({name} is a modulus)")
        hyper_m = hyper_tau = None
        if ("hyper_m" in entry) != ("hyper_tau" in entry):
            problems.append(f"{key}: give both hyper_m and hyper_tau (pooled) or neither (not pooled)")
        elif "hyper_m" in entry:
            hyper_m = _bounds(entry["hyper_m"], f"{key}.hyper_m", problems)
            hyper_tau = _bounds(entry["hyper_tau"], f"{key}.hyper_tau", problems)
            if hyper_m is not None and prior is not None and (hyper_m.lo < prior.lo or hyper_m.hi > prior.hi):
                problems.append(f"{key}.hyper_m: range [{hyper_m.lo:g}, {hyper_m.hi:g}] lies outside the prior "
                                f"range [{prior.lo:g}, {prior.hi:g}]")
            if hyper_tau is not None and hyper_tau.lo < 0:
                problems.append(f"{key}.hyper_tau: spread range [{hyper_tau.lo:g}, {hyper_tau.hi:g}] must be >= 0")
        if prior is not None:
            parameters[name] = ParameterPrior(name, prior, hyper_m, hyper_tau)

    fixed: dict[str, float] = {}
    for name, value in fixed_raw.items():
        key = f"fixed.{name}"
        if name not in MODEL_PARAMETERS:
            problems.append(f"{key}: unknown parameter (allowed: {', '.join(MODEL_PARAMETERS)})")
        elif not _is_number(value) or not math.isfinite(value):
            problems.append(f"{key}: must be a finite number, got {value!r}")
        elif name in params_raw:
            problems.append(f"{key}: also listed under [parameters.{name}]; a parameter is free or fixed, not both")
        else:
            fixed[name] = float(value)
    for name in MODEL_PARAMETERS:
        if name not in params_raw and name not in fixed_raw:
            problems.append(f"parameters.{name}: missing (list it under [parameters.{name}] or [fixed])")
    if shell == "reduced":
        for name in NONLINEAR_PARAMETERS:
            if name in params_raw:
                problems.append(f"parameters.{name}: a reduced shell fixes {name} = 0; move it to [fixed]")
            elif name in fixed and fixed[name] != 0.0:
                problems.append(f"fixed.{name}: a reduced shell fixes {name} = 0, got {fixed[name]:g}")

    noise: dict[str, NoisePrior] = {}
    for name, entry in noise_raw.items():
        key = f"noise.{name}"
        if name not in NOISE_PARAMETERS:
            problems.append(f"{key}: unknown noise amplitude (allowed: {', '.join(NOISE_PARAMETERS)})")
            continue
        if not isinstance(entry, dict) or "prior" not in entry:
            problems.append(f"{key}.prior: missing")
            continue
        for sub in entry:
            if sub != "prior":
                problems.append(f"{key}.{sub}: unknown key (noise amplitudes take only prior = [lo, hi]; never pooled)")
        prior = _bounds(entry["prior"], f"{key}.prior", problems)
        if prior is not None and prior.lo < 0:
            problems.append(f"{key}.prior: lower bound {prior.lo:g} must be >= 0 (relative noise amplitude)")
        if prior is not None:
            noise[name] = NoisePrior(name, prior)
    required = ("sigma_mech", "sigma_ac") if acoustic else ("sigma",)
    for name in required:
        if name not in noise_raw:
            problems.append(f"noise.{name}: missing (workflow.acoustic = {str(acoustic).lower()} needs "
                            f"{' and '.join(required)})")
    for name in noise_raw:
        if name in NOISE_PARAMETERS and name not in required:
            problems.append(f"noise.{name}: not used when workflow.acoustic = {str(acoustic).lower()} "
                            f"(expected: {', '.join(required)})")

    ordered = {n: parameters[n] for n in MODEL_PARAMETERS if n in parameters}
    return agent, setup, shell, acoustic, description, ordered, fixed, noise


def load_priors(name_or_path: str | Path) -> PriorSpec:
    """Load and validate a workflow's priors: a shipped name ('definity_reduced_acoustic') or a path.

    Raises :class:`PriorError` listing all problems (file and key named) if the file is invalid.
    """
    path = prior_path(name_or_path)
    try:
        with open(path, "rb") as handle:
            raw = tomllib.load(handle)
    except FileNotFoundError as exc:
        raise PriorError(path, ["file not found"]) from exc
    except tomllib.TOMLDecodeError as exc:
        raise PriorError(path, [f"not valid TOML: {exc}"]) from exc
    problems: list[str] = []
    agent, setup, shell, acoustic, description, params, fixed, noise = _validate(raw, problems)
    if problems:
        raise PriorError(path, problems)
    return PriorSpec(name=path.stem, path=str(path), agent=agent, setup=setup, shell=shell, acoustic=acoustic,
                     parameters=params, fixed=fixed, noise=noise, description=description)


def check_priors(name_or_path: str | Path) -> list[str]:
    """Problems found in a priors file (empty list when valid)."""
    try:
        load_priors(name_or_path)
    except PriorError as exc:
        return exc.problems
    return []
