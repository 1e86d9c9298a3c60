"""The compression protocol's plates: a capped repulsive LJ (WCA) between an analytic plate and the shell
vertices (docs/physics.md section 5), shared by every tier.

The plate acts on shell vertices only, through the distance h of a vertex to the plate (h <= 0: behind
it).  Repulsive LJ with ``epsilon`` = 1000, ``sigma`` = 2^(-1/6), cut-off r_c = 2^(1/6) sigma = 1; the
force magnitude is capped at ``force_cap`` (1e4 DPD force per vertex, reached at h ~ 0.91) and the energy is
continued linearly below that distance (also behind the plate), so a minimiser can recover a vertex that
crossed.  The MD tiers evaluate the same law in a Warp kernel (:mod:`bubblecal.sim.protocols.md_loading`),
the quasi-static tier in its device chain (:mod:`bubblecal.sim.tiers.quasistatic`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["PlateContact", "plate_force_energy", "plate_cap_distance"]


@dataclass(frozen=True)
class PlateContact:
    """Capped repulsive LJ between an analytic plate and shell vertices (DPD units).

    Parameters
    ----------
    epsilon : float
        LJ energy (DPD energy).
    sigma : float
        LJ length (DPD length); the cut-off is 2^(1/6) sigma.
    force_cap : float
        Largest force magnitude per vertex (DPD force).
    gap : float
        Plate offset beyond the reference shell's extent at zero displacement (DPD length); 1 = the LJ
        range, so the plates just touch the reference shell at d = 0.

    Raises
    ------
    ValueError
        If a value is not finite, or ``epsilon``, ``sigma`` or ``force_cap`` is not positive, or ``gap`` < 0.
    """

    epsilon: float = 1000.0
    sigma: float = 2.0 ** (-1.0 / 6.0)
    force_cap: float = 1.0e4
    gap: float = 1.0

    def __post_init__(self) -> None:
        for name in ("epsilon", "sigma", "force_cap"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"PlateContact.{name} must be a positive finite number, got {v!r}")
        if not (math.isfinite(self.gap) and self.gap >= 0):
            raise ValueError(f"PlateContact.gap must be a finite number >= 0, got {self.gap!r}")

    @property
    def cutoff(self) -> float:
        """Cut-off distance 2^(1/6) sigma (DPD length)."""
        return 2.0 ** (1.0 / 6.0) * self.sigma


def plate_force_energy(h: np.ndarray, contact: PlateContact) -> tuple[np.ndarray, np.ndarray]:
    """Repulsive force magnitude and energy of the capped plate law at vertex-plate distances ``h``.

    Parameters
    ----------
    h : numpy.ndarray
        Vertex-plate distances (DPD length); h <= 0 lies behind the plate.
    contact : PlateContact
        The plate law.

    Returns
    -------
    force : numpy.ndarray
        Force magnitude (>= 0, pushing the vertex away from the plate; DPD force), capped at
        ``contact.force_cap``.
    energy : numpy.ndarray
        Energy (DPD energy), continued linearly below the capping distance.
    """
    h = np.asarray(h, dtype=np.float64)
    eps, sig, rc, cap = contact.epsilon, contact.sigma, contact.cutoff, contact.force_cap
    h_cap = plate_cap_distance(eps, sig, cap)
    e_cap = _lj_energy(np.array([h_cap]), eps, sig)[0]
    f = np.zeros_like(h)
    e = np.zeros_like(h)
    near = (h < rc) & (h > h_cap)
    f[near] = _lj_force(h[near], eps, sig)
    e[near] = _lj_energy(h[near], eps, sig)
    capped = h <= h_cap
    f[capped] = cap
    e[capped] = e_cap + cap * (h_cap - h[capped])
    return f, e


def _lj_force(h, eps, sig):
    """Repulsive LJ force magnitude at distance h."""
    s6 = (sig / h) ** 6
    return 24.0 * eps * (2.0 * s6 * s6 - s6) / h


def _lj_energy(h, eps, sig):
    """WCA energy (LJ shifted by eps) at distance h."""
    s6 = (sig / h) ** 6
    return 4.0 * eps * (s6 * s6 - s6) + eps


def plate_cap_distance(eps: float, sig: float, cap: float) -> float:
    """Distance (DPD length) at which the LJ force reaches ``cap`` (bisection on the monotone branch h < r_c).

    Parameters
    ----------
    eps : float
        LJ energy (DPD energy).
    sig : float
        LJ length (DPD length).
    cap : float
        Force cap (DPD force).

    Returns
    -------
    float
        The capping distance; 1e-3 sigma when the force stays below ``cap`` down to there.
    """
    lo, hi = 1e-3 * sig, 2.0 ** (1.0 / 6.0) * sig
    if _lj_force(lo, eps, sig) <= cap:
        return lo
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if _lj_force(mid, eps, sig) > cap:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)
