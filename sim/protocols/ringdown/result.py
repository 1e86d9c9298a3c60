"""The result type of the ringdown protocol: R traces R(t) of one diameter."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bubblecal.data import STATUSES

__all__ = ["RingdownBatch"]


@dataclass
class RingdownBatch:
    """R ringdown traces of one diameter (DPD units).

    Parameters
    ----------
    t : numpy.ndarray
        [T] DPD time since the perturbation (t = 0 is the first sample, taken right after it).
    radius : numpy.ndarray
        [R, T] R(t) = (3 V / 4 pi)^(1/3) of each replica's mesh (DPD length).
    status : list of str
        [R] from :data:`bubblecal.data.names.STATUSES`.
    params : dict
        The shell parameters per replica (:data:`bubblecal.data.names.SHELL_PARAMETERS` -> [R]; ka DPD 2-D
        modulus with mu = ka / 3, kb DPD energy).
    seeds : tuple of int
        One per replica.
    info : dict
        Settings (tier, dt, steps, mass factor, perturbation, ...), ``vertex_mass`` (DPD mass, mass factor
        included), ``n_vertices``, ``shell_mass`` (= n_vertices x vertex_mass), ``radius_reference`` (mesh
        radius), ``radius_equilibrium`` [R] (mean R over the last 10 % of equilibration), ``p_gas`` [R]
        (ideal-gas pressure inside, DPD pressure), ``prediction`` (:func:`breathing_mode_prediction` per
        replica).
    vertices : numpy.ndarray, optional
        [R, Tv, Nv', 3] (float32, DPD length) when recorded: every ``vertex_every``-th record, the first
        Nv' = ``vertex_indices.size`` vertices (an icosphere's first 10 4^k + 2 vertices are the coarser
        icosphere of level k, so the subset stays uniform).
    vertex_t : numpy.ndarray, optional
        [Tv] DPD time of each recorded frame.
    vertex_indices : numpy.ndarray, optional
        The recorded vertex indices.
    seconds : float
        Wall time of the run (s).

    Raises
    ------
    ValueError
        If ``radius`` is not [R, T] or ``status`` does not hold R values from STATUSES.
    """

    t: np.ndarray
    radius: np.ndarray
    status: list[str]
    params: dict[str, np.ndarray]
    seeds: tuple[int, ...]
    info: dict = field(default_factory=dict)
    vertices: np.ndarray | None = None
    vertex_t: np.ndarray | None = None
    vertex_indices: np.ndarray | None = None
    seconds: float = 0.0

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=np.float64)
        self.radius = np.asarray(self.radius, dtype=np.float64)
        R = len(self.seeds)
        if self.radius.shape != (R, self.t.size):
            raise ValueError(f"RingdownBatch.radius must have shape {(R, self.t.size)}, got {self.radius.shape}")
        bad = [s for s in self.status if s not in STATUSES]
        if len(self.status) != R or bad:
            raise ValueError(f"RingdownBatch.status must be {R} values from {STATUSES}, got {self.status!r}")

    @property
    def n_replicas(self) -> int:
        """Number of replicas R."""
        return len(self.seeds)

    @property
    def ok(self) -> np.ndarray:
        """Boolean mask [R]: status 'ok' and a finite trace."""
        return np.array([s == "ok" for s in self.status]) & np.all(np.isfinite(self.radius), axis=1)
