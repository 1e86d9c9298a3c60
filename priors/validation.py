"""Validation of a parsed priors TOML table: every problem is collected, nothing is clipped.

Each problem names the offending key (``workflow.agent``, ``parameters.kb.prior``, ``noise.sigma``, ...);
:func:`bubblecal.priors.load_priors` raises them together in one :class:`~bubblecal.priors.PriorError`.
The file format is documented at the top of every shipped priors file.
"""

from __future__ import annotations

import math

from bubblecal.data import (
    AGENTS,
    LOADING_PROTOCOLS,
    MODEL_PARAMETERS,
    NOISE_PARAMETERS,
    NONLINEAR_PARAMETERS,
    POSITIVE_PARAMETERS,
)
from bubblecal.priors.spec import Bounds, NoisePrior, ParameterPrior

__all__: list[str] = []

_SHELLS = ("full", "reduced")
_SECTIONS = ("workflow", "parameters", "fixed", "noise")
_WORKFLOW_KEYS = {"agent", "setup", "shell", "acoustic", "description"}
_PARAM_KEYS = {"prior", "hyper_m", "hyper_tau"}


def _is_number(value) -> bool:
    """True for an int or float that is not a bool."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _bounds(value, key: str, problems: list[str]) -> Bounds | None:
    """``value`` as Bounds if it is a finite [lo, hi] pair with lo < hi, else None with a problem added."""
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


def _validate_workflow(wf, problems: list[str]):
    """The ``[workflow]`` section: (agent, setup, shell, acoustic, description)."""
    agent = setup = shell = None
    acoustic = False
    description = ""
    if not isinstance(wf, dict):
        problems.append("workflow: missing [workflow] section (agent, setup, shell, acoustic)")
        return agent, setup, shell, acoustic, description
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
    return agent, setup, shell, acoustic, description


def _validate_parameters(params_raw: dict, problems: list[str]) -> dict[str, ParameterPrior]:
    """The ``[parameters.NAME]`` tables: free parameters with their priors and hyperpriors, in file order."""
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
    return parameters


def _validate_fixed(fixed_raw: dict, params_raw: dict, shell, problems: list[str]) -> dict[str, float]:
    """The ``[fixed]`` table, then: every parameter free or fixed, and a reduced shell's b1 = b2 = a3 = a4 = 0."""
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
    return fixed


def _validate_noise(noise_raw: dict, acoustic: bool, problems: list[str]) -> dict[str, NoisePrior]:
    """The ``[noise.NAME]`` tables: sigma alone, or sigma_mech and sigma_ac for an acoustic workflow."""
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
    return noise


def _validate(raw: dict, problems: list[str]):
    """Validate a parsed priors table, appending every problem to ``problems``.

    Returns (agent, setup, shell, acoustic, description, parameters in MODEL_PARAMETERS order, fixed, noise);
    the values are meaningful only when no problem was added.
    """
    for key in raw:
        if key not in _SECTIONS:
            problems.append(f"{key}: unknown section (allowed: {', '.join(_SECTIONS)})")
    agent, setup, shell, acoustic, description = _validate_workflow(raw.get("workflow"), problems)

    params_raw = raw.get("parameters", {})
    fixed_raw = raw.get("fixed", {})
    noise_raw = raw.get("noise", {})
    for section, value in (("parameters", params_raw), ("fixed", fixed_raw), ("noise", noise_raw)):
        if not isinstance(value, dict):
            problems.append(f"{section}: must be a table, got {type(value).__name__}")
    params_raw = params_raw if isinstance(params_raw, dict) else {}
    fixed_raw = fixed_raw if isinstance(fixed_raw, dict) else {}
    noise_raw = noise_raw if isinstance(noise_raw, dict) else {}

    parameters = _validate_parameters(params_raw, problems)
    fixed = _validate_fixed(fixed_raw, params_raw, shell, problems)
    noise = _validate_noise(noise_raw, acoustic, problems)
    ordered = {n: parameters[n] for n in MODEL_PARAMETERS if n in parameters}
    return agent, setup, shell, acoustic, description, ordered, fixed, noise
