"""The tier interface: a request of R curves on one grid, the batch of curves a tier returns, and the registry
behind :func:`get_tier` (docs/physics.md section 7).

Registering is cheap: a tier class module imports no Warp and compiles nothing until its ``run`` is called, so
configuration code can build and validate a :class:`CurveRequest` or a tier without a device.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from bubblecal.data import LOADING_PROTOCOLS, SHELL_PARAMETERS, STATUSES
from bubblecal.sim.tiers.conventions import (
    DEFAULT_INDENTATION_CONVENTION,
    KB_KERNEL_SCALE,
    indentation_convention,
)

__all__ = ["TIER_NAMES", "CurveRequest", "CurveBatch", "Tier", "register_tier", "get_tier"]

#: The fidelity tiers, most to least expensive.
TIER_NAMES = ("explicit", "implicit", "quasistatic")


@dataclass(frozen=True)
class CurveRequest:
    """R curves to simulate on one loading grid.

    Parameters
    ----------
    protocol : str
        'compression' (grid = total displacements d, DPD length) or 'indentation' (grid = total force per pole,
        DPD force); one of :data:`bubblecal.data.names.LOADING_PROTOCOLS`.
    diameter_um : float
        Bubble diameter (um), in [0.5, 20]; the mesh radius in DPD length comes from :mod:`bubblecal.data.units`.
    grid : tuple of float
        The loading grid [P >= 2]: finite, non-negative, strictly increasing.
    params : mapping
        Each of :data:`bubblecal.data.names.SHELL_PARAMETERS` -> array [R] (ka DPD 2-D modulus > 0, kb DPD
        energy >= 0, b1 ... a4 dimensionless); stored as float64 arrays.
    seeds : tuple of int
        One per replica.
    subdivisions : int, optional
        Icosphere level (None = the mesh's default for the diameter).
    diameters_um : tuple of float, optional
        One diameter [um] per replica, in [0.5, 20], for a pool of several bubble sizes on one mesh level
        (``subdivisions`` required; the quasi-static tier only); None: ``diameter_um`` for all.
    grids : numpy.ndarray, optional
        [R, P] one loading grid per replica (a compression grid that scales with each replica's size), each
        valid as ``grid``; None: ``grid`` for all.

    Raises
    ------
    ValueError
        If a field is invalid; the message names the field (``CurveRequest.<field>``).
    """

    protocol: str
    diameter_um: float
    grid: tuple[float, ...]
    params: Mapping[str, np.ndarray]
    seeds: tuple[int, ...]
    subdivisions: int | None = None
    diameters_um: tuple[float, ...] | None = None
    grids: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.protocol not in LOADING_PROTOCOLS:
            raise ValueError(f"CurveRequest.protocol must be one of {LOADING_PROTOCOLS}, got {self.protocol!r}")
        d = self.diameter_um
        if isinstance(d, bool) or not isinstance(d, (int, float)) or not (math.isfinite(d) and 0.5 <= d <= 20.0):
            raise ValueError(f"CurveRequest.diameter_um must lie in [0.5, 20] um, got {d!r}")
        grid = np.asarray(self.grid, dtype=np.float64)
        if grid.ndim != 1 or grid.size < 2 or not np.all(np.isfinite(grid)) or np.any(grid < 0) \
                or np.any(np.diff(grid) <= 0):
            raise ValueError(f"CurveRequest.grid must be >= 2 finite, non-negative, strictly increasing values, "
                             f"got {self.grid!r}")
        object.__setattr__(self, "grid", tuple(float(v) for v in grid))
        missing = [k for k in SHELL_PARAMETERS if k not in self.params]
        if missing:
            raise ValueError(f"CurveRequest.params is missing {missing} (needs {list(SHELL_PARAMETERS)})")
        arrays = {k: np.atleast_1d(np.asarray(self.params[k], dtype=np.float64)) for k in SHELL_PARAMETERS}
        sizes = {a.shape for a in arrays.values()}
        if len(sizes) != 1 or len(next(iter(sizes))) != 1:
            raise ValueError(f"CurveRequest.params arrays must all have shape [R], got "
                             f"{ {k: a.shape for k, a in arrays.items()} }")
        for k, a in arrays.items():
            if not np.all(np.isfinite(a)):
                raise ValueError(f"CurveRequest.params[{k!r}] must be finite")
        if np.any(arrays["ka"] <= 0) or np.any(arrays["kb"] < 0):
            raise ValueError("CurveRequest.params: ka must be > 0 and kb >= 0 (DPD units)")
        object.__setattr__(self, "params", arrays)
        seeds = tuple(int(s) for s in self.seeds)
        if len(seeds) != self.n_replicas:
            raise ValueError(f"CurveRequest.seeds must have one seed per replica ({self.n_replicas}), "
                             f"got {len(seeds)}")
        object.__setattr__(self, "seeds", seeds)
        if self.diameters_um is not None:
            ds = tuple(float(v) for v in self.diameters_um)
            if len(ds) != self.n_replicas or not all(math.isfinite(v) and 0.5 <= v <= 20.0 for v in ds):
                raise ValueError(f"CurveRequest.diameters_um must hold one diameter in [0.5, 20] um per replica "
                                 f"({self.n_replicas}), got {self.diameters_um!r}")
            if self.subdivisions is None:
                raise ValueError("CurveRequest.diameters_um needs subdivisions (one mesh level for every size)")
            object.__setattr__(self, "diameters_um", ds)
        if self.grids is not None:
            g = np.asarray(self.grids, dtype=np.float64)
            ok = g.shape == (self.n_replicas, len(self.grid)) and np.all(np.isfinite(g)) and np.all(g >= 0)
            if not ok or np.any(np.diff(g, axis=1) <= 0):
                raise ValueError(f"CurveRequest.grids must be [R, P] = [{self.n_replicas}, {len(self.grid)}] finite, "
                                 "non-negative grids, each strictly increasing")
            object.__setattr__(self, "grids", g)

    @property
    def several_sizes(self) -> bool:
        """Whether the replicas have different diameters (``diameters_um`` not all ``diameter_um``)."""
        return self.diameters_um is not None and any(d != self.diameter_um for d in self.diameters_um)

    @property
    def n_replicas(self) -> int:
        """Number of replicas R."""
        return int(self.params["ka"].shape[0])

    def grid_array(self) -> np.ndarray:
        """The loading grid [P] as float64 (DPD length for compression, DPD force for indentation); [R, P] when
        the replicas have their own ``grids``."""
        return np.asarray(self.grid if self.grids is None else self.grids, dtype=np.float64)

    def shell_params(self, convention: str = DEFAULT_INDENTATION_CONVENTION) -> list:
        """One kernel parameter set per replica, with the published kb mapped to our kernel's.

        Parameters
        ----------
        convention : str
            Indentation convention (:data:`bubblecal.sim.tiers.INDENTATION_CONVENTIONS`); compression uses
            :data:`bubblecal.sim.tiers.KB_KERNEL_SCALE` whatever the convention, but the name is checked too.

        Returns
        -------
        list of bubblecal.sim.engine.kernels.shell.ShellParams
            R parameter sets (mu = ka / 3; kb in DPD energy, scaled).

        Raises
        ------
        ValueError
            If ``convention`` is unknown.
        """
        from bubblecal.sim.engine import shell_params_from_arrays

        conv = indentation_convention(convention)  # checked for compression too: a typo never passes
        scale = conv.kb_scale if self.protocol == "indentation" else KB_KERNEL_SCALE[self.protocol]
        return shell_params_from_arrays(self.params, scale)


@dataclass
class CurveBatch:
    """The curves of one :class:`CurveRequest`, as a tier returns them.

    Parameters
    ----------
    tier : str
        The tier's name.
    request : CurveRequest
        The request simulated.
    observable : numpy.ndarray
        [R, P] compression: sum of the forces on both plates (DPD force); indentation: pole-to-pole distance
        reduction (DPD length).  Rows whose status is not 'ok' may hold NaN.
    status : list of str
        [R] from :data:`bubblecal.data.names.STATUSES`.
    info : dict
        Tier settings, mesh, step counts and per-tier diagnostics.
    seconds : float
        Wall time of the run (s).

    Raises
    ------
    ValueError
        If ``observable`` is not [R, P] or ``status`` does not hold R values from STATUSES.
    """

    tier: str
    request: CurveRequest
    observable: np.ndarray
    status: list[str]
    info: dict = field(default_factory=dict)
    seconds: float = 0.0

    def __post_init__(self) -> None:
        R, P = self.request.n_replicas, len(self.request.grid)
        self.observable = np.asarray(self.observable, dtype=np.float64)
        if self.observable.shape != (R, P):
            raise ValueError(f"CurveBatch.observable must have shape {(R, P)}, got {self.observable.shape}")
        bad = [s for s in self.status if s not in STATUSES]
        if len(self.status) != R or bad:
            raise ValueError(f"CurveBatch.status must be {R} values from {STATUSES}, got {self.status!r}")

    @property
    def ok(self) -> np.ndarray:
        """Boolean mask [R] of replicas with status 'ok' and a finite curve."""
        return np.array([s == "ok" for s in self.status]) & np.all(np.isfinite(self.observable), axis=1)


class Tier(Protocol):
    """A fidelity tier: ``run(request, device)`` -> :class:`CurveBatch`.

    A tier batches the R replicas of a request into the same kernel launches and reports one status per
    replica (:data:`bubblecal.data.names.STATUSES`); its settings are keyword arguments of its constructor
    (``get_tier(name, **settings)``).

    Attributes
    ----------
    name : str
        The tier's name, one of :data:`TIER_NAMES`.
    """

    name: str

    def run(self, request: CurveRequest, device: str = "cpu") -> CurveBatch:
        """Simulate ``request`` on the Warp ``device`` (units: :class:`CurveRequest`)."""
        ...


_REGISTRY: dict[str, Callable[..., Tier]] = {}


def register_tier(name: str, factory: Callable[..., Tier]) -> None:
    """Make ``get_tier(name, **settings)`` call ``factory(**settings)``.

    Parameters
    ----------
    name : str
        One of :data:`TIER_NAMES`.
    factory : callable
        Builds the tier from its settings (usually the tier class).

    Raises
    ------
    ValueError
        If ``name`` is not one of :data:`TIER_NAMES`.
    """
    if name not in TIER_NAMES:
        raise ValueError(f"tier name must be one of {TIER_NAMES}, got {name!r}")
    _REGISTRY[name] = factory


def get_tier(name: str, **settings) -> Tier:
    """The tier called ``name``, configured by ``settings``.

    Parameters
    ----------
    name : str
        One of :data:`TIER_NAMES` (the built-in tiers register themselves when :mod:`bubblecal.sim.tiers` is
        imported).
    **settings
        The tier class's fields (e.g. ``subdivisions``, ``indentation_convention``).

    Returns
    -------
    Tier

    Raises
    ------
    ValueError
        If no tier is registered under ``name``, or a setting is invalid.
    """
    if name not in _REGISTRY:
        raise ValueError(f"tier must be one of {sorted(_REGISTRY) or TIER_NAMES}, got {name!r}")
    return _REGISTRY[name](**settings)
