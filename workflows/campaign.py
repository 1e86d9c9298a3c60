"""Campaign configuration files (TOML) -> :class:`bubblecal.sim.campaign.CampaignConfig`.

Format (every key is checked; an error names the file, the field and the allowed values)::

    [campaign]
    name = "definity_compression_2.1um"  # ids "<name>-000000" ...; letters, digits, '.', '_', '-'
    protocol = "compression"             # compression | indentation | ringdown
    diameter_um = 2.1                    # [um], 0.5 - 20; a list only with design = "grid" (ringdown sweeps)
    tier = "quasistatic"                 # explicit | implicit | quasistatic
    design = "lhs"                       # lhs (Latin hypercube) | grid (ka values, everything else fixed)
    n_samples = 6000                     # lhs: points; grid: ka values per diameter
    seed = 21001                         # design + per-sample seeds (a restart regenerates the same design)
    replicas_per_task = 100              # replicas batched in one task (one GPU launch)
    device = "cuda"                      # cpu | cuda | cuda:N
    store = "stores/def21"               # campaign store directory; relative = against this file's folder;
                                         # absent: ./<name>.store in the current directory
    # optional: subdivisions = 4 (icosphere level), loading_grid = [...] (default: the published grid),
    #           ka_values = [...] (grid design), retry_statuses = ["failed", "timeout"]

    [ranges]                             # DPD units: ka 2-D modulus, kb energy, b1..a4 dimensionless
    priors = "definity_full"             # shipped workflow name or a priors TOML path: its shell box; a list
                                         # of them (["definity_full", "definity_reduced_acoustic"]): the union box
    kb = 389.23                          # a number fixes a parameter, [lo, hi] samples it (overrides priors)

    [tier]                               # keyword settings of the tier (e.g. ftol, max_steps for quasistatic)

    [dask]
    scheduler_address = ""               # "" or "local" = LocalCluster; "tcp://host:8786"; "inline" = no Dask
    n_workers = 1                        # LocalCluster workers (default: 1 on cuda, core count on cpu)

The shipped configurations (:func:`available_campaigns`) live in ``bubblecal/workflows/campaigns``.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from bubblecal.data import PROTOCOLS, SHELL_PARAMETERS
from bubblecal.sim.campaign import DESIGNS, CampaignConfig, CampaignConfigError
from bubblecal.sim.tiers import TIER_NAMES

__all__ = ["CampaignFileError", "CampaignFile", "available_campaigns", "campaign_path", "load_campaign_file",
           "load_campaign_config"]

_CAMPAIGN_KEYS = {
    "name": "a string of letters, digits, '.', '_', '-'",
    "protocol": " | ".join(PROTOCOLS),
    "diameter_um": "a diameter in um (0.5 - 20), or a list of them for design = 'grid'",
    "tier": " | ".join(TIER_NAMES),
    "design": " | ".join(DESIGNS),
    "n_samples": "an integer >= 1",
    "seed": "an integer >= 0",
    "replicas_per_task": "an integer >= 1",
    "device": "cpu | cuda | cuda:N",
    "store": "a directory path (relative to this file's folder)",
    "subdivisions": "an integer 0 - 7",
    "loading_grid": "a list of >= 2 increasing non-negative numbers (DPD length or force)",
    "ka_values": "a list of ka values > 0 (DPD 2-D modulus)",
    "retry_statuses": "a list of statuses to re-run (failed, timeout, unstable, ruptured, invalid)",
    "description": "free text",
}
_DASK_KEYS = {"scheduler_address": "'' or 'local' (LocalCluster), 'inline' (no Dask) or 'tcp://host:port'",
              "n_workers": "an integer >= 1"}
_SECTIONS = ("campaign", "ranges", "tier", "dask")
#: CampaignConfig field -> TOML key, for error messages
_FIELD_KEY = {"tier_settings": "[tier]", "ranges": "[ranges]"}


class CampaignFileError(ValueError):
    """A campaign TOML file is invalid; the message names the file, the field and the allowed values."""

    def __init__(self, path: str | Path, key: str, message: str):
        self.path = str(path)
        self.key = key
        super().__init__(f"campaign file {self.path}: {key}: {message}")


@dataclass(frozen=True)
class CampaignFile:
    """A loaded campaign file: the config plus the execution settings of ``[dask]``."""

    path: str
    config: CampaignConfig
    scheduler_address: str | None = None
    n_workers: int | None = None
    priors: str | None = None
    description: str = ""
    raw: dict = field(default_factory=dict)


def available_campaigns() -> list[str]:
    """Names of the shipped campaign configurations (without .toml)."""
    folder = resources.files("bubblecal.workflows.campaigns")
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def campaign_path(name_or_path: str | Path) -> Path:
    """A TOML path, or the shipped configuration called ``name_or_path`` (see :func:`available_campaigns`)."""
    candidate = Path(name_or_path)
    if candidate.suffix == ".toml" or candidate.exists():
        return candidate
    key = str(name_or_path)
    if key in available_campaigns():
        return Path(str(resources.files("bubblecal.workflows.campaigns") / f"{key}.toml"))
    raise CampaignFileError(name_or_path, "path", f"no such file or shipped campaign; shipped: "
                                                  f"{', '.join(available_campaigns())}")


def _key_for(fld: str) -> str:
    if fld.startswith("ranges."):
        return f"[ranges].{fld.split('.', 1)[1]}"
    if fld in _FIELD_KEY:
        return _FIELD_KEY[fld]
    return f"[campaign].{fld}"


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
    allowed = ("priors",) + SHELL_PARAMETERS
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


def _check_tier_settings(path: Path, tier: str, protocol: str, settings: dict) -> None:
    """Unknown [tier] keys are errors when the tier's settings can be listed (dataclass tiers)."""
    if protocol == "ringdown" or not settings:
        return
    import dataclasses

    from bubblecal.sim.tiers import get_tier

    try:
        get_tier(tier, **settings)
    except TypeError as exc:
        try:
            proto = get_tier(tier)
            names = [f.name for f in dataclasses.fields(proto) if f.name != "name"]
        except Exception:  # tier not constructible without settings: report the TypeError only
            names = []
        bad = [k for k in settings if names and k not in names]
        key = f"[tier].{bad[0]}" if bad else "[tier]"
        allowed = f" (allowed for tier {tier!r}: {', '.join(names)})" if names else ""
        raise CampaignFileError(path, key, f"{exc}{allowed}") from None
    except ValueError as exc:
        named = [k for k in settings if k in str(exc)]  # the tiers' messages name the offending setting
        raise CampaignFileError(path, f"[tier].{named[0]}" if named else "[tier]", str(exc)) from None


def parse_tier_settings(items: list[str]) -> dict:
    """``KEY=VALUE`` strings (command-line ``--tier-setting``) -> {key: value}, each value read as a TOML value
    (bare words as strings); ValueError names the malformed item."""
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key.isidentifier():
            raise ValueError(f"--tier-setting {item!r}: expected KEY=VALUE, e.g. first_load_ramp=6")
        try:
            out[key] = tomllib.loads(f"v = {value.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            out[key] = value.strip()  # a bare word such as mirheo
    return out


def load_campaign_file(name_or_path: str | Path, *, store: str | Path | None = None,
                       tier_overrides: dict | None = None) -> CampaignFile:
    """Read and validate a campaign TOML (path or shipped name); ``store`` overrides ``[campaign].store``;
    ``tier_overrides`` set ``[tier]`` keys on top of the file's (validated like them; a different design)."""
    path = campaign_path(name_or_path)
    try:
        with open(path, "rb") as fh:
            raw = tomllib.load(fh)
    except FileNotFoundError:
        raise CampaignFileError(path, "path", "file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise CampaignFileError(path, "syntax", f"not valid TOML: {exc}") from None
    for key in raw:
        if key not in _SECTIONS:
            raise CampaignFileError(path, f"[{key}]", f"unknown section (allowed: {', '.join(_SECTIONS)})")
    camp = raw.get("campaign")
    if not isinstance(camp, dict):
        raise CampaignFileError(path, "[campaign]", "missing section (name, protocol, diameter_um, tier, n_samples, "
                                                    "seed, ...)")
    for key in camp:
        if key not in _CAMPAIGN_KEYS:
            raise CampaignFileError(path, f"[campaign].{key}", f"unknown key (allowed: {', '.join(_CAMPAIGN_KEYS)})")
    for key in ("name", "protocol", "diameter_um"):
        if key not in camp:
            raise CampaignFileError(path, f"[campaign].{key}", f"missing; must be {_CAMPAIGN_KEYS[key]}")
    design = camp.get("design", "lhs")
    if "n_samples" not in camp and not (design == "grid" and "ka_values" in camp):
        raise CampaignFileError(path, "[campaign].n_samples", f"missing; must be {_CAMPAIGN_KEYS['n_samples']}")
    if "ranges" not in raw:
        raise CampaignFileError(path, "[ranges]", "missing section: priors = '<workflow>' and/or ka = [lo, hi], ...")
    ranges, priors = _ranges(path, raw["ranges"])
    tier_settings = raw.get("tier", {})
    if not isinstance(tier_settings, dict):
        raise CampaignFileError(path, "[tier]", "must be a table of setting = value")
    if tier_overrides:
        tier_settings = {**tier_settings, **tier_overrides}
    dask = raw.get("dask", {})
    if not isinstance(dask, dict):
        raise CampaignFileError(path, "[dask]", "must be a table (scheduler_address, n_workers)")
    for key in dask:
        if key not in _DASK_KEYS:
            raise CampaignFileError(path, f"[dask].{key}", f"unknown key (allowed: {', '.join(_DASK_KEYS)})")
    address = dask.get("scheduler_address", "")
    if not isinstance(address, str):
        raise CampaignFileError(path, "[dask].scheduler_address", f"must be {_DASK_KEYS['scheduler_address']}")
    n_workers = dask.get("n_workers")
    if n_workers is not None and (isinstance(n_workers, bool) or not isinstance(n_workers, int) or n_workers < 1):
        raise CampaignFileError(path, "[dask].n_workers", f"must be {_DASK_KEYS['n_workers']}, got {n_workers!r}")

    name = camp["name"]
    if store is not None:
        store_path = Path(store)
    elif "store" in camp:
        if not isinstance(camp["store"], str) or not camp["store"]:
            raise CampaignFileError(path, "[campaign].store", f"must be {_CAMPAIGN_KEYS['store']}")
        store_path = Path(camp["store"]).expanduser()
        if not store_path.is_absolute():
            store_path = path.resolve().parent / store_path
    else:
        store_path = Path.cwd() / f"{name}.store"
    kwargs = dict(name=name, protocol=camp["protocol"], ranges=ranges, tier_settings=tier_settings,
                  store=str(store_path))
    d = camp["diameter_um"]
    kwargs["diameter_um"] = tuple(d) if isinstance(d, list) else d
    for key in ("tier", "design", "n_samples", "seed", "replicas_per_task", "device", "subdivisions"):
        if key in camp:
            kwargs[key] = camp[key]
    if "n_samples" not in camp:
        kwargs["n_samples"] = None
    for key in ("loading_grid", "ka_values", "retry_statuses"):
        if key in camp:
            if not isinstance(camp[key], list):
                raise CampaignFileError(path, f"[campaign].{key}", f"must be {_CAMPAIGN_KEYS[key]}, got {camp[key]!r}")
            kwargs[key] = tuple(camp[key])
    try:
        config = CampaignConfig(**kwargs)
    except CampaignConfigError as exc:
        allowed = _CAMPAIGN_KEYS.get(exc.field)
        hint = f" (allowed: {allowed})" if allowed and allowed not in exc.detail else ""
        raise CampaignFileError(path, _key_for(exc.field), f"{exc.detail}{hint}") from None
    _check_tier_settings(path, config.tier, config.protocol, config.tier_settings)
    return CampaignFile(path=str(path), config=config, scheduler_address=address or None, n_workers=n_workers,
                        priors=priors, description=str(camp.get("description", "")), raw=raw)


def load_campaign_config(path: str | Path) -> CampaignConfig:
    """The :class:`CampaignConfig` of a campaign TOML (path or shipped name); errors: :class:`CampaignFileError`."""
    return load_campaign_file(path).config
