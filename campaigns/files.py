"""Campaign files (TOML) -> :class:`~bubblecal.campaigns.CampaignConfig`, and the shipped campaign files.

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
    #           loading_fractions = [...] (compression: total displacement / diameter at each point),
    #           diameter_step_um = 0.1 (levels of a diameter range; then no diameter_um here),
    #           ka_values = [...] (grid design), retry_statuses = ["failed", "timeout"], description = "..."

    [ranges]                             # DPD units: ka 2-D modulus, kb energy, b1..a4 dimensionless
    priors = "definity_full"             # shipped workflow name or a priors TOML path: its shell box; a list
                                         # of them (["definity_full", "definity_reduced_acoustic"]): the union box
    kb = 389.23                          # a number fixes a parameter, [lo, hi] samples it (overrides priors)
    # diameter_um = [1.5, 8.0]           # the diameter as a Latin-hypercube dimension [um] (lhs; needs
                                         # [campaign].diameter_step_um; bubblecal.campaigns.diameters)

    [tier]                               # keyword settings of the tier (e.g. ftol, max_steps for quasistatic)

    [dask]
    scheduler_address = ""               # "" or "local" = LocalCluster; "tcp://host:8786"; "inline" = no Dask
    n_workers = 1                        # LocalCluster workers (default: 1 on cuda, core count on cpu)

The shipped campaign files (:func:`available_campaigns`) are package data in ``bubblecal/campaigns/shipped``.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from bubblecal.campaigns.config import DESIGNS, CampaignConfig
from bubblecal.campaigns.errors import CampaignConfigError, CampaignFileError
from bubblecal.campaigns.ranges import _ranges
from bubblecal.campaigns.scheduler import check_scheduler_address
from bubblecal.data import PROTOCOLS
from bubblecal.sim.tiers import TIER_NAMES

__all__ = ["CampaignFile", "available_campaigns", "campaign_path", "load_campaign_file",
           "load_campaign_config", "parse_tier_settings"]

#: The package and folder of the shipped campaign files.
_SHIPPED_PACKAGE, _SHIPPED_FOLDER = "bubblecal.campaigns", "shipped"

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
    "loading_fractions": "compression: a list of >= 2 increasing fractions of the diameter in [0, 0.5]",
    "diameter_step_um": "the level spacing [um] of [ranges].diameter_um = [lo, hi], >= 0.01",
    "ka_values": "a list of ka values > 0 (DPD 2-D modulus)",
    "retry_statuses": "a list of statuses to re-run (failed, timeout, unstable, ruptured, invalid)",
    "description": "free text",
}
_DASK_KEYS = {"scheduler_address": "'' or 'local' (LocalCluster), 'inline' (no Dask) or 'tcp://host:port'",
              "n_workers": "an integer >= 1"}
_SECTIONS = ("campaign", "ranges", "tier", "dask")
#: CampaignConfig field -> TOML key, for error messages
_FIELD_KEY = {"tier_settings": "[tier]", "ranges": "[ranges]"}


@dataclass(frozen=True)
class CampaignFile:
    """A loaded campaign file: the config plus the execution settings of ``[dask]``.

    Parameters
    ----------
    path : str
        The campaign file.
    config : CampaignConfig
        The validated campaign.
    scheduler_address : str, optional
        ``[dask].scheduler_address`` (None when empty: a LocalCluster).
    n_workers : int, optional
        ``[dask].n_workers``.
    priors : str, optional
        The ``[ranges].priors`` workflow(s) of the box, comma-separated.
    description : str
        ``[campaign].description``.
    raw : dict
        The parsed TOML.
    """

    path: str
    config: CampaignConfig
    scheduler_address: str | None = None
    n_workers: int | None = None
    priors: str | None = None
    description: str = ""
    raw: dict = field(default_factory=dict)


def _shipped_folder():
    """The folder of the shipped campaign files (an importlib.resources Traversable)."""
    return resources.files(_SHIPPED_PACKAGE) / _SHIPPED_FOLDER


def available_campaigns() -> list[str]:
    """Names of the shipped campaign files.

    Returns
    -------
    list of str
        Sorted names without ``.toml``, e.g. ``definity_compression_2.1um``.
    """
    folder = _shipped_folder()
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def campaign_path(name_or_path: str | Path) -> Path:
    """The path of a campaign file given by path or by shipped name.

    Parameters
    ----------
    name_or_path : str or Path
        A ``.toml`` path or an existing file (returned as given), or a shipped campaign name
        (:func:`available_campaigns`).

    Returns
    -------
    Path
        The campaign file.

    Raises
    ------
    CampaignFileError
        Neither an existing file nor a shipped name (key ``path``; the message lists the shipped names).
    """
    candidate = Path(name_or_path)
    if candidate.suffix == ".toml" or candidate.exists():
        return candidate
    key = str(name_or_path)
    if key in available_campaigns():
        return Path(str(_shipped_folder() / f"{key}.toml"))
    raise CampaignFileError(name_or_path, "path", f"no such file or shipped campaign; shipped: "
                                                  f"{', '.join(available_campaigns())}")


def _key_for(fld: str) -> str:
    """The TOML key of a CampaignConfig field (for error messages)."""
    if fld.startswith("ranges."):
        return f"[ranges].{fld.split('.', 1)[1]}"
    if fld in _FIELD_KEY:
        return _FIELD_KEY[fld]
    return f"[campaign].{fld}"


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
    """Parse command-line ``--tier-setting KEY=VALUE`` items into ``[tier]`` overrides.

    Parameters
    ----------
    items : list of str
        ``KEY=VALUE`` strings; each value is read as a TOML value, a bare word (e.g. ``mirheo``) as a string.

    Returns
    -------
    dict
        ``{key: value}``.

    Raises
    ------
    ValueError
        An item is not ``KEY=VALUE`` with an identifier key; the message names it.
    """
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


def _read(path: Path) -> dict:
    """The parsed TOML with known sections only."""
    try:
        with open(path, "rb") as fh:
            raw = tomllib.load(fh)
    except FileNotFoundError:
        raise CampaignFileError(path, "path", "file not found") from None
    except IsADirectoryError:
        raise CampaignFileError(path, "path", "is a folder, not a campaign TOML file") from None
    except UnicodeDecodeError as exc:
        raise CampaignFileError(path, "syntax", f"not UTF-8 text (byte {exc.start}); TOML files are UTF-8") from None
    except tomllib.TOMLDecodeError as exc:
        raise CampaignFileError(path, "syntax", f"not valid TOML: {exc}") from None
    except OSError as exc:
        raise CampaignFileError(path, "path", f"cannot read file: {exc.strerror or exc}") from None
    for key in raw:
        if key not in _SECTIONS:
            raise CampaignFileError(path, f"[{key}]", f"unknown section (allowed: {', '.join(_SECTIONS)})")
    return raw


def _campaign_table(path: Path, raw: dict) -> dict:
    """The [campaign] table: known keys, the required ones present."""
    camp = raw.get("campaign")
    if not isinstance(camp, dict):
        raise CampaignFileError(path, "[campaign]", "missing section (name, protocol, diameter_um, tier, "
                                                    "n_samples, seed, ...)")
    for key in camp:
        if key not in _CAMPAIGN_KEYS:
            raise CampaignFileError(path, f"[campaign].{key}", f"unknown key (allowed: "
                                                               f"{', '.join(_CAMPAIGN_KEYS)})")
    required = ("name", "protocol") if "diameter_um" in raw.get("ranges", {}) else ("name", "protocol", "diameter_um")
    for key in required:
        if key not in camp:
            raise CampaignFileError(path, f"[campaign].{key}", f"missing; must be {_CAMPAIGN_KEYS[key]}")
    design = camp.get("design", "lhs")
    if "n_samples" not in camp and not (design == "grid" and "ka_values" in camp):
        raise CampaignFileError(path, "[campaign].n_samples", f"missing; must be {_CAMPAIGN_KEYS['n_samples']}")
    return camp


def _dask_table(path: Path, raw: dict) -> tuple[str, int | None]:
    """The [dask] table -> (scheduler_address, n_workers)."""
    dask = raw.get("dask", {})
    if not isinstance(dask, dict):
        raise CampaignFileError(path, "[dask]", "must be a table (scheduler_address, n_workers)")
    for key in dask:
        if key not in _DASK_KEYS:
            raise CampaignFileError(path, f"[dask].{key}", f"unknown key (allowed: {', '.join(_DASK_KEYS)})")
    address = dask.get("scheduler_address", "")
    try:
        check_scheduler_address(address)
    except CampaignConfigError:
        raise CampaignFileError(path, "[dask].scheduler_address", f"must be {_DASK_KEYS['scheduler_address']}, "
                                                                  f"got {address!r}") from None
    n_workers = dask.get("n_workers")
    if n_workers is not None and (isinstance(n_workers, bool) or not isinstance(n_workers, int) or n_workers < 1):
        raise CampaignFileError(path, "[dask].n_workers", f"must be {_DASK_KEYS['n_workers']}, got {n_workers!r}")
    return address, n_workers


def _store_path(path: Path, camp: dict, store: str | Path | None) -> Path:
    """``store`` if given, else [campaign].store (relative to the file's folder), else ./<name>.store."""
    if store is not None:
        return Path(store)
    if "store" in camp:
        if not isinstance(camp["store"], str) or not camp["store"]:
            raise CampaignFileError(path, "[campaign].store", f"must be {_CAMPAIGN_KEYS['store']}")
        store_path = Path(camp["store"]).expanduser()
        if not store_path.is_absolute():
            store_path = path.resolve().parent / store_path
        return store_path
    return Path.cwd() / f"{camp['name']}.store"


def load_campaign_file(name_or_path: str | Path, *, store: str | Path | None = None,
                       tier_overrides: dict | None = None) -> CampaignFile:
    """Read and validate a campaign TOML file.

    Parameters
    ----------
    name_or_path : str or Path
        A campaign file, or a shipped campaign name (:func:`available_campaigns`).
    store : str or Path, optional
        Overrides ``[campaign].store`` (campaign store directory).
    tier_overrides : dict, optional
        ``[tier]`` keys set on top of the file's, validated like them (a different design).

    Returns
    -------
    CampaignFile
        The validated config and the ``[dask]`` settings.

    Raises
    ------
    CampaignFileError
        The file is missing, not TOML, or a key is invalid; the message names the file, the key and the
        allowed values.
    """
    path = campaign_path(name_or_path)
    raw = _read(path)
    camp = _campaign_table(path, raw)
    if "ranges" not in raw:
        raise CampaignFileError(path, "[ranges]", "missing section: priors = '<workflow>' and/or ka = [lo, hi], ...")
    ranges, priors = _ranges(path, raw["ranges"])  # the shell box; [ranges].diameter_um is the diameter range
    diameter_range = raw["ranges"].get("diameter_um")
    tier_settings = raw.get("tier", {})
    if not isinstance(tier_settings, dict):
        raise CampaignFileError(path, "[tier]", "must be a table of setting = value")
    if tier_overrides:
        tier_settings = {**tier_settings, **tier_overrides}
    address, n_workers = _dask_table(path, raw)

    kwargs = dict(name=camp["name"], protocol=camp["protocol"], ranges=ranges, tier_settings=tier_settings,
                  store=str(_store_path(path, camp, store)))
    d = camp.get("diameter_um")
    kwargs["diameter_um"] = tuple(d) if isinstance(d, list) else d
    if diameter_range is not None:
        kwargs["diameter_range_um"] = tuple(diameter_range) if isinstance(diameter_range, list) else diameter_range
    for key in ("tier", "design", "n_samples", "seed", "replicas_per_task", "device", "subdivisions",
                "diameter_step_um"):
        if key in camp:
            kwargs[key] = camp[key]
    if "n_samples" not in camp:
        kwargs["n_samples"] = None
    for key in ("loading_grid", "loading_fractions", "ka_values", "retry_statuses"):
        if key in camp:
            if not isinstance(camp[key], list):
                raise CampaignFileError(path, f"[campaign].{key}", f"must be {_CAMPAIGN_KEYS[key]}, got "
                                                                   f"{camp[key]!r}")
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
    """The config of a campaign TOML file.

    Parameters
    ----------
    path : str or Path
        A campaign file or a shipped campaign name.

    Returns
    -------
    CampaignConfig
        ``load_campaign_file(path).config``.

    Raises
    ------
    CampaignFileError
        As :func:`load_campaign_file`.
    """
    return load_campaign_file(path).config
