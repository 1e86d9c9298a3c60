"""The [ranges] table of a campaign file: parameter ranges from priors workflow boxes and explicit bounds.

``priors = "<workflow>"`` (or a priors TOML path, or a list of them) gives the shell-parameter box of those
priors (:mod:`bubblecal.priors`); explicit ``param = [lo, hi]`` / ``param = value`` entries override it.
"""

from __future__ import annotations

from pathlib import Path

from bubblecal.campaigns.errors import CampaignFileError
from bubblecal.data import SHELL_PARAMETERS


def _prior_box(path: Path, priors: str) -> dict[str, tuple[float, float]]:
    """The shell-parameter box {param: (lo, hi)} of one workflow prior (fixed values as lo = hi)."""
    from bubblecal.priors import PriorError, available_priors, load_priors

    target = priors
    if (priors.endswith(".toml") or "/" in priors) and not Path(priors).is_absolute():
        target = str(path.parent / priors)
    try:
        spec = load_priors(target)
    except PriorError as exc:
        raise CampaignFileError(path, "[ranges].priors", f"{priors!r}: {exc} (shipped workflows: "
                                                         f"{', '.join(available_priors())})") from None
    box = {}
    for k in SHELL_PARAMETERS:
        if k in spec.parameters:
            box[k] = spec.parameters[k].prior.as_tuple()
        elif k in spec.fixed:
            box[k] = (spec.fixed[k], spec.fixed[k])
    return box


def _ranges(path: Path, raw: dict) -> tuple[dict, str | None]:
    """The [ranges] table -> {param: (lo, hi)} (priors box, then explicit overrides)."""
    if not isinstance(raw, dict):
        raise CampaignFileError(path, "[ranges]", "must be a table")
    allowed = ("priors",) + SHELL_PARAMETERS + ("diameter_um",)
    for key in raw:
        if key not in allowed:
            raise CampaignFileError(path, f"[ranges].{key}", f"unknown key (allowed: {', '.join(allowed)})")
    ranges: dict[str, tuple[float, float]] = {}
    priors = raw.get("priors")
    if priors is not None:
        names = priors if isinstance(priors, list) else [priors]
        if not names or not all(isinstance(n, str) and n for n in names):
            from bubblecal.priors import available_priors

            raise CampaignFileError(path, "[ranges].priors", f"must be a shipped workflow name "
                                                             f"({', '.join(available_priors())}), a TOML path, or a "
                                                             f"list of them (union box); got {priors!r}")
        # a list: the union box, so that every listed workflow's prior lies inside the training domain
        for name in names:
            for k, (lo, hi) in _prior_box(path, name).items():
                ranges[k] = (min(lo, ranges[k][0]), max(hi, ranges[k][1])) if k in ranges else (lo, hi)
        priors = ", ".join(names)
    for k in SHELL_PARAMETERS:
        if k not in raw:
            continue
        v = raw[k]
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            ranges[k] = (float(v), float(v))
        elif isinstance(v, list) and len(v) == 2 and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                           for x in v):
            ranges[k] = (float(v[0]), float(v[1]))
        else:
            raise CampaignFileError(path, f"[ranges].{k}", f"must be [lo, hi] (lo <= hi) or one number (fixed), "
                                                           f"DPD units; got {v!r}")
    missing = [k for k in SHELL_PARAMETERS if k not in ranges]
    if missing:
        raise CampaignFileError(path, f"[ranges].{missing[0]}", "missing: give priors = '<workflow>' or "
                                                                f"{missing[0]} = [lo, hi] / a fixed number")
    return ranges, priors
