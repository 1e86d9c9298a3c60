"""The campaign configuration: :class:`CampaignConfig`, its validation, and the fields that define a design.

A config is validated on construction; every error is a :class:`CampaignConfigError` that names the field and
the allowed values.  The design-defining fields (:data:`DESIGN_FIELDS`) are hashed into
:meth:`CampaignConfig.design_hash`, which a campaign store keeps in its header: a store belongs to one design.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bubblecal.campaigns.diameters import check_loading, diameter_levels, fraction_grid, published_grid
from bubblecal.campaigns.errors import CampaignConfigError
from bubblecal.data import PROTOCOLS, RECORD_STATUSES, RETRY_STATUSES, SHELL_PARAMETERS, jsonable
from bubblecal.sim.tiers import TIER_NAMES

__all__ = [
    "DESIGNS",
    "DESIGN_FIELDS",
    "OPTIONAL_DESIGN_FIELDS",
    "EXECUTION_ONLY_TIER_SETTINGS",
    "CampaignConfig",
]

#: Design kinds: Latin hypercube over the free parameters, or a ka grid (ringdown sweeps).
DESIGNS = ("lhs", "grid")
#: Fields that define the design (and the meaning of the records): a store refuses a config that changes them.
DESIGN_FIELDS = ("name", "protocol", "diameter_um", "ranges", "n_samples", "seed", "tier", "tier_settings",
                 "design", "ka_values", "loading_grid", "subdivisions")
#: Design-defining fields of designs over a diameter range or with a scaled grid: hashed only when set, so the
#: designs of the other campaigns keep their hashes.
OPTIONAL_DESIGN_FIELDS = ("diameter_range_um", "diameter_step_um", "loading_fractions")
#: [tier] keys that change how curves are scheduled on the device, not the curves: left out of the design hash.
EXECUTION_ONLY_TIER_SETTINGS = ("schedule", "max_replicas", "sync_every")

_DIAMETER_RANGE_UM = (0.5, 20.0)
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")


def _is_number(v) -> bool:
    """A real number (bool excluded)."""
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def _is_int(v) -> bool:
    """An integer (bool excluded)."""
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool)


@dataclass(frozen=True)
class CampaignConfig:
    """One training-data campaign (validated on construction; errors name the field).

    Parameters
    ----------
    name : str
        Sample-id prefix and default store name (letters, digits, '.', '_', '-'; starts with a letter or digit).
    protocol : str
        One of :data:`bubblecal.data.names.PROTOCOLS`: 'compression', 'indentation' or 'ringdown'.
    diameter_um : float or tuple of float or None
        Bubble diameter [um] in [0.5, 20]; a tuple of several diameters only with ``design='grid'``; None
        with ``diameter_range_um``.
    ranges : Mapping[str, tuple[float, float]]
        ``{ka, kb, b1, b2, a3, a4: (lo, hi)}`` in DPD units (ka DPD 2-D modulus, lo > 0; kb DPD energy, lo >= 0;
        b1..a4 dimensionless); ``lo == hi`` fixes a parameter.
    n_samples : int
        LHS points; for 'grid' the number of ka values per diameter (None: ``len(ka_values)``).
    seed : int
        Seed of the design and of the per-sample seeds, in [0, 2^63).
    tier : str
        One of :data:`bubblecal.sim.tiers.TIER_NAMES`.
    tier_settings : Mapping[str, object]
        Keyword arguments of the tier (ringdown: of ``bubblecal.sim.protocols.ringdown.ringdown_batch``).
    design : str
        'lhs' or 'grid' (:data:`DESIGNS`).
    ka_values : tuple of float, optional
        Explicit ka grid [DPD 2-D modulus] for 'grid'.
    loading_grid : tuple of float, optional
        Compression total displacements [DPD length] or indentation forces [DPD force], >= 2 increasing
        non-negative values; None = the published grid (:mod:`bubblecal.sim.protocols.loading`); None for ringdown.
    replicas_per_task : int
        Replicas batched in one task (one GPU launch), >= 1.
    device : str
        'cpu', 'cuda' or 'cuda:N'.
    subdivisions : int, optional
        Icosphere level 0-7 (None = the mesh default for the diameter).
    store : str or Path
        Campaign store directory.
    retry_statuses : tuple of str
        Record statuses a restart re-runs (default :data:`bubblecal.data.names.RETRY_STATUSES`; never 'ok').
    diameter_range_um : tuple of float, optional
        (lo, hi) [um]: the diameter is a dimension of the Latin hypercube, on the levels lo, lo + step, ..., hi
        (:mod:`bubblecal.campaigns.diameters`); 'lhs' compression or indentation only, within
        :data:`~bubblecal.campaigns.diameters.DIAMETER_DESIGN_RANGE_UM`.
    diameter_step_um : float, optional
        Level spacing [um] of ``diameter_range_um`` (required with it).
    loading_fractions : tuple of float, optional
        Compression only: total plate displacements as fractions of the diameter (the grid at diameter D is
        ``fraction * D`` in DPD length); required by compression over a diameter range.

    Raises
    ------
    CampaignConfigError
        A field is invalid; ``field`` names it.
    """

    name: str
    protocol: str
    diameter_um: float | tuple[float, ...]
    ranges: Mapping[str, tuple[float, float]]
    n_samples: int
    seed: int = 0
    tier: str = "quasistatic"
    tier_settings: Mapping[str, object] = field(default_factory=dict)
    design: str = "lhs"
    ka_values: tuple[float, ...] | None = None
    loading_grid: tuple[float, ...] | None = None
    replicas_per_task: int = 16
    device: str = "cpu"
    subdivisions: int | None = None
    store: str | Path = "campaign.store"
    retry_statuses: tuple[str, ...] = RETRY_STATUSES
    diameter_range_um: tuple[float, float] | None = None
    diameter_step_um: float | None = None
    loading_fractions: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        # the checks run in this order, so a config with several errors always reports the same one
        self._check_kinds()
        self._check_diameters()
        self._check_ranges()
        self._check_sizes()
        self._check_execution()
        self._check_loading_grid()
        self._check_retry_and_store()

    # -- validation (each step normalises the fields it checked) ---------------------------------
    def _check_kinds(self) -> None:
        """name, protocol, design."""
        if not isinstance(self.name, str) or not _NAME_RE.match(self.name):
            raise CampaignConfigError("name", f"must be a non-empty string of letters, digits, '.', '_', '-' "
                                              f"(starting with a letter or digit), got {self.name!r}")
        if self.protocol not in PROTOCOLS:
            raise CampaignConfigError("protocol", f"must be one of {', '.join(PROTOCOLS)}, got {self.protocol!r}")
        if self.design not in DESIGNS:
            raise CampaignConfigError("design", f"must be one of {', '.join(DESIGNS)}, got {self.design!r}")

    def _check_diameters(self) -> None:
        """diameter_um: a float, or a tuple of several for 'grid'; or a range with its level spacing."""
        if self.diameter_range_um is not None or self.diameter_step_um is not None:
            self._check_diameter_range()
            return
        d = self.diameter_um
        many = isinstance(d, (list, tuple))
        values = list(d) if many else [d]
        if not values:
            raise CampaignConfigError("diameter_um", "must name at least one diameter [um]")
        lo_d, hi_d = _DIAMETER_RANGE_UM
        for v in values:
            if not _is_number(v) or not (math.isfinite(v) and lo_d <= v <= hi_d):
                raise CampaignConfigError("diameter_um", f"must be a number in [{lo_d:g}, {hi_d:g}] um, got {v!r}")
        if many and len(set(values)) != len(values):
            raise CampaignConfigError("diameter_um", f"lists a diameter twice: {values}")
        if many and len(values) > 1 and self.design != "grid":
            raise CampaignConfigError("diameter_um", "several diameters are allowed only with design = 'grid' "
                                                     "(ringdown sweeps); use one campaign per diameter for 'lhs'")
        object.__setattr__(self, "diameter_um",
                           tuple(float(v) for v in values) if many and len(values) > 1 else float(values[0]))

    def _check_diameter_range(self) -> None:
        """diameter_range_um and diameter_step_um of a design over the diameter."""
        if self.diameter_range_um is None or self.diameter_step_um is None:
            missing = "diameter_step_um" if self.diameter_range_um is not None else "ranges.diameter_um"
            raise CampaignConfigError(missing, "a design over a diameter range needs both [ranges].diameter_um = "
                                               "[lo, hi] and diameter_step_um (the level spacing, um)")
        if self.diameter_um is not None:
            raise CampaignConfigError("diameter_um", "give either diameter_um (one diameter) or a diameter range "
                                                     "([ranges].diameter_um = [lo, hi]), not both")
        if self.design != "lhs" or self.protocol == "ringdown":
            raise CampaignConfigError("ranges.diameter_um", "a diameter range is a dimension of a Latin hypercube "
                                                            "(design = 'lhs', compression or indentation); ringdown "
                                                            "sweeps list their diameters in diameter_um")
        r = self.diameter_range_um
        if not isinstance(r, (list, tuple)) or len(r) != 2:
            raise CampaignConfigError("ranges.diameter_um", f"must be [lo, hi] in um, got {r!r}")
        diameter_levels(r[0], r[1], self.diameter_step_um)  # validates the range and the step
        object.__setattr__(self, "diameter_range_um", (float(r[0]), float(r[1])))
        object.__setattr__(self, "diameter_step_um", float(self.diameter_step_um))

    def _check_ranges(self) -> None:
        """ranges: every shell parameter, (lo, hi) finite with lo <= hi, in SHELL_PARAMETERS order."""
        if not isinstance(self.ranges, Mapping):
            raise CampaignConfigError("ranges", f"must map {', '.join(SHELL_PARAMETERS)} to (lo, hi)")
        unknown = [k for k in self.ranges if k not in SHELL_PARAMETERS]
        if unknown:
            raise CampaignConfigError(f"ranges.{unknown[0]}", f"unknown parameter (allowed: "
                                                              f"{', '.join(SHELL_PARAMETERS)})")
        ranges = {}
        for k in SHELL_PARAMETERS:
            if k not in self.ranges:
                raise CampaignConfigError(f"ranges.{k}", "missing; give (lo, hi) in DPD units (lo == hi fixes it)")
            b = self.ranges[k]
            if not isinstance(b, (list, tuple)) or len(b) != 2 or not all(_is_number(x) for x in b):
                raise CampaignConfigError(f"ranges.{k}", f"must be [lo, hi] of two numbers, got {b!r}")
            lo, hi = float(b[0]), float(b[1])
            if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
                raise CampaignConfigError(f"ranges.{k}", f"must be finite with lo <= hi, got [{lo:g}, {hi:g}]")
            if k == "ka" and lo <= 0:
                raise CampaignConfigError("ranges.ka", f"lower bound must be > 0 (DPD 2-D modulus), got {lo:g}")
            if k == "kb" and lo < 0:
                raise CampaignConfigError("ranges.kb", f"lower bound must be >= 0 (DPD energy), got {lo:g}")
            ranges[k] = (lo, hi)
        object.__setattr__(self, "ranges", ranges)

    def _check_sizes(self) -> None:
        """ka_values, n_samples, seed, and what each design needs of the free parameters."""
        set_ = object.__setattr__
        if self.ka_values is not None:
            if self.design != "grid":
                raise CampaignConfigError("ka_values", "only used with design = 'grid'")
            kv = list(self.ka_values)
            if len(kv) < 1 or not all(_is_number(v) and math.isfinite(v) and v > 0 for v in kv):
                raise CampaignConfigError("ka_values", f"must be a non-empty list of finite ka > 0 (DPD 2-D "
                                                       f"modulus), got {self.ka_values!r}")
            if len(set(kv)) != len(kv):
                raise CampaignConfigError("ka_values", "lists a value twice")
            set_(self, "ka_values", tuple(float(v) for v in kv))
            if self.n_samples is None:
                set_(self, "n_samples", len(kv))
        if not _is_int(self.n_samples) or self.n_samples < 1:
            raise CampaignConfigError("n_samples", f"must be an integer >= 1, got {self.n_samples!r}")
        set_(self, "n_samples", int(self.n_samples))
        if self.ka_values is not None and len(self.ka_values) != self.n_samples:
            raise CampaignConfigError("n_samples", f"is {self.n_samples} but ka_values lists "
                                                   f"{len(self.ka_values)} values (leave n_samples out or make "
                                                   "them agree)")
        if not _is_int(self.seed) or not (0 <= self.seed < 2**63):
            raise CampaignConfigError("seed", f"must be an integer in [0, 2^63), got {self.seed!r}")
        free = [k for k, (lo, hi) in self.ranges.items() if hi > lo]
        if self.design == "lhs" and not free:
            raise CampaignConfigError("ranges", "design 'lhs' needs at least one free parameter (lo < hi)")
        if self.design == "grid":
            if [k for k in free if k != "ka"]:
                raise CampaignConfigError(f"ranges.{[k for k in free if k != 'ka'][0]}",
                                          "design 'grid' varies ka only; fix every other parameter (lo == hi)")
            if self.ka_values is None and self.n_samples > 1 and "ka" not in free:
                raise CampaignConfigError("ranges.ka", "design 'grid' with n_samples > 1 needs lo < hi for ka "
                                                       "(or explicit ka_values)")

    def _check_execution(self) -> None:
        """tier, tier_settings, replicas_per_task, device, subdivisions."""
        if self.tier not in TIER_NAMES:
            raise CampaignConfigError("tier", f"must be one of {', '.join(TIER_NAMES)}, got {self.tier!r}")
        if not isinstance(self.tier_settings, Mapping) or not all(isinstance(k, str) for k in self.tier_settings):
            raise CampaignConfigError("tier_settings", f"must be a table of name = value, got "
                                                       f"{self.tier_settings!r}")
        object.__setattr__(self, "tier_settings", dict(self.tier_settings))
        if not _is_int(self.replicas_per_task) or self.replicas_per_task < 1:
            raise CampaignConfigError("replicas_per_task", f"must be an integer >= 1, got "
                                                           f"{self.replicas_per_task!r}")
        if not isinstance(self.device, str) or not re.match(r"^(cpu|cuda(:\d+)?)$", self.device):
            raise CampaignConfigError("device", f"must be 'cpu', 'cuda' or 'cuda:N', got {self.device!r}")
        if self.subdivisions is not None and (not _is_int(self.subdivisions) or not 0 <= self.subdivisions <= 7):
            raise CampaignConfigError("subdivisions", f"must be an integer in [0, 7] or absent, got "
                                                      f"{self.subdivisions!r}")

    def _check_loading_grid(self) -> None:
        """loading_grid / loading_fractions (:func:`bubblecal.campaigns.diameters.check_loading`)."""
        grid, fractions = check_loading(self)
        object.__setattr__(self, "loading_grid", grid)
        object.__setattr__(self, "loading_fractions", fractions)

    def _check_retry_and_store(self) -> None:
        """retry_statuses (record statuses other than 'ok'), store (a non-empty path)."""
        rs = tuple(self.retry_statuses)
        bad = [s for s in rs if s not in RECORD_STATUSES or s == "ok"]
        if bad:
            raise CampaignConfigError("retry_statuses", f"{bad} not allowed; choose from "
                                                        f"{[s for s in RECORD_STATUSES if s != 'ok']}")
        object.__setattr__(self, "retry_statuses", rs)
        if not isinstance(self.store, (str, Path)) or not str(self.store):
            raise CampaignConfigError("store", f"must be a directory path, got {self.store!r}")

    # -- derived ----------------------------------------------------------------------------------
    @property
    def diameters(self) -> tuple[float, ...]:
        """The campaign's diameters [um]: one, a grid's several, or the levels of a diameter range."""
        if self.diameter_range_um is not None:
            return diameter_levels(*self.diameter_range_um, self.diameter_step_um)
        d = self.diameter_um
        return tuple(d) if isinstance(d, tuple) else (float(d),)

    @property
    def free_names(self) -> tuple[str, ...]:
        """Parameters that vary (lo < hi), in :data:`bubblecal.data.names.SHELL_PARAMETERS` order."""
        return tuple(k for k in SHELL_PARAMETERS if self.ranges[k][1] > self.ranges[k][0])

    @property
    def fixed(self) -> dict[str, float]:
        """Parameters held constant (lo == hi) -> value (DPD units)."""
        return {k: lo for k, (lo, hi) in self.ranges.items() if hi == lo}

    @property
    def n_design(self) -> int:
        """Number of design points (grid: ka values x diameters)."""
        return self.n_samples * len(self.diameters) if self.design == "grid" else self.n_samples

    @property
    def pools_levels(self) -> bool:
        """Whether a task may hold several diameter levels (one refill pool over bubble sizes): the quasi-static
        tier over a diameter range on one mesh level."""
        return self.diameter_range_um is not None and self.tier == "quasistatic" and self.subdivisions is not None

    @property
    def n_tasks(self) -> int:
        """Tasks of a full run (chunks of ``replicas_per_task`` per diameter, or over the levels)."""
        if self.pools_levels:
            return math.ceil(self.n_design / self.replicas_per_task)
        n_levels = len(self.diameters)
        if self.diameter_range_um is not None:  # n // L or n // L + 1 points per level (diameters.level_of_unit)
            q, r = divmod(self.n_samples, n_levels)
            rpt = self.replicas_per_task
            return r * math.ceil((q + 1) / rpt) + (n_levels - r) * math.ceil(q / rpt)
        per = math.ceil(self.n_design / n_levels / self.replicas_per_task)
        return per * n_levels

    @property
    def store_path(self) -> Path:
        """The campaign store directory as a :class:`~pathlib.Path`."""
        return Path(self.store)

    def grid_for(self, diameter_um: float) -> tuple[float, ...] | None:
        """The loading grid at one diameter.

        Parameters
        ----------
        diameter_um : float
            Bubble diameter [um] (one of :attr:`diameters`).

        Returns
        -------
        tuple of float or None
            Compression total displacements [DPD length] or indentation forces [DPD force]: ``loading_grid``,
            ``loading_fractions`` times the diameter, else the published grid; None for ringdown.
        """
        if self.protocol == "ringdown":
            return None
        if self.loading_fractions is not None:
            return fraction_grid(self.loading_fractions, diameter_um)
        if self.loading_grid is not None:
            return self.loading_grid
        return published_grid(self.protocol, diameter_um)

    def physics_tier_settings(self) -> dict:
        """The tier settings that change the curves: ``tier_settings`` without :data:`EXECUTION_ONLY_TIER_SETTINGS`.

        Returns
        -------
        dict
            A new dict for ``get_tier(tier, **settings)`` (scheduling-only settings give bit-identical curves).
        """
        return {k: v for k, v in self.tier_settings.items() if k not in EXECUTION_ONLY_TIER_SETTINGS}

    def design_dict(self) -> dict:
        """The fields that define the design and the records' meaning (:data:`DESIGN_FIELDS`), JSON-able;
        ``tier_settings`` is :meth:`physics_tier_settings`."""
        out = {}
        for k in DESIGN_FIELDS + OPTIONAL_DESIGN_FIELDS:
            v = getattr(self, k)
            if k in OPTIONAL_DESIGN_FIELDS and v is None:
                continue
            if k == "ranges":
                v = {p: list(b) for p, b in v.items()}
            elif isinstance(v, tuple):
                v = list(v)
            out[k] = v
        # scheduling-only settings give bit-identical curves, so they do not change the design
        out["tier_settings"] = jsonable(self.physics_tier_settings())
        return out

    def design_hash(self) -> str:
        """sha256 (first 16 hex digits) of :meth:`design_dict`: a store belongs to one design."""
        text = json.dumps(self.design_dict(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def to_dict(self) -> dict:
        """Every field, JSON-able (the store header keeps it)."""
        out = self.design_dict()
        out["tier_settings"] = jsonable(self.tier_settings)
        out.update(replicas_per_task=self.replicas_per_task, device=self.device, store=str(self.store),
                   retry_statuses=list(self.retry_statuses))
        return out
