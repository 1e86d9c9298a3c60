"""Mean-field thermal contact between a fluctuating shell and an analytic plate (DPD units).

The athermal quasi-static tier relaxes the *mean* shape of the shell; in the explicit and implicit
tiers every vertex also fluctuates along the shell normal, so vertices near a plate keep colliding
with it: an entropic repulsion that gives F(d = 0) > 0 and an additive offset along the whole
compression curve, which no minimisation produces (its size: docs/decisions.md, benchmarks/RESULTS.md).

Model (statistical mechanics of one vertex against a hard wall; nothing fitted):

* the WCA plate is replaced by a hard wall at its Barker-Henderson distance
  h_w = int_0^{r_c} (1 - exp(-U(h)/kT)) dh (U the capped WCA energy: 0.9954 for eps = 1000);
* a vertex held by the shell's elasticity fluctuates along the normal with rms ``sigma``; next to the wall
  its distribution is a Gaussian truncated at h_w.  FIRE relaxes the *mean* shape, so the plate force is
  written as a function of the vertex's mean distance h: with g = (h - h_w)/sigma,
  F = (kT / sigma) Psi(g),  Psi(g) = M(z) where z + M(z) = g and M(z) = phi(z)/Phi(z) (inverse Mills ratio).
  This is exact for a linear spring plus a hard wall (the spring force at the mean balances the mean
  wall force), and it does not count the shell's elasticity twice (the elastic energy of the mean shape
  stays with the shell).  Limits: far from the wall Psi ~ phi(g) (entropic tail); pressed, Psi ~ 1/g,
  i.e. F = kT / (h - h_w), the ideal-gas repulsion of a confined particle.  A vertex pressed with force f
  therefore sits kT/f beyond h_w instead of at the WCA's 1 - f/72,000: the plates act ~0.003-0.05 earlier.
* sigma from thin-shell theory (normal fluctuation of a closed shell, dominated by the modes at the
  elastic length): sigma^2 = kT R / (8 sqrt(kappa Y)), kappa = (sqrt 3 / 2) kb (our Kantor kernel,
  :mod:`bubblecal.sim.validation.checks`), Y = 4 K mu / (K + mu) = ka for the Lim model with mu = ka/3.  At
  3.0 um, k_a 5,580, k_b 100 this gives 0.033 DPD length.
* below g_0 = 0.05 (a mean position within 5 % of sigma of the wall; only FIRE overshoots go there) Psi is
  continued linearly, and the force is capped like the athermal one.

The Warp kernel of the same law is ``plate_force_kernel`` of :mod:`bubblecal.sim.engine.kernels.qs_loading`.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["ThermalContact", "hard_wall_distance", "shell_fluctuation_sigma", "thermal_plate_force",
           "wall_force_psi", "psi_continuation", "inverse_mills_ratio", "G_MIN"]

_SQRT_2_OVER_PI = math.sqrt(2.0 / math.pi)
#: below this z the inverse Mills ratio uses its asymptotic series (erfc would underflow in float32)
Z_ASYMPTOTIC = -8.0


@dataclass(frozen=True)
class ThermalContact:
    """Thermal (entropic) plate contact of the quasi-static tier (module docstring).

    Parameters
    ----------
    kT : float
        Thermal energy (DPD energy; 1 in the DPD models).
    sigma : float, optional
        rms normal fluctuation of a vertex (DPD length) for every shell; None = per shell from thin-shell theory
        (:func:`shell_fluctuation_sigma`).

    Raises
    ------
    ValueError
        If ``kT`` is not a positive finite number, or ``sigma`` is given and is not.
    """

    kT: float = 1.0
    sigma: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.kT) and self.kT > 0):
            raise ValueError(f"ThermalContact.kT must be a positive finite DPD energy, got {self.kT!r}")
        if self.sigma is not None and not (math.isfinite(self.sigma) and self.sigma > 0):
            raise ValueError(f"ThermalContact.sigma must be None or a positive finite DPD length, got {self.sigma!r}")


def shell_fluctuation_sigma(params: Sequence, radius_dpd: float, kT: float = 1.0) -> np.ndarray:
    """rms normal fluctuation of a vertex of each shell, from thin-shell theory.

    sigma^2 = kT R / (8 sqrt(kappa Y)), kappa = (sqrt 3 / 2) kb, Y = 4 ka mu / (ka + mu).

    Parameters
    ----------
    params : sequence of bubblecal.sim.engine.kernels.shell.ShellParams
        Kernel units: ``ka``, ``mu`` 2-D moduli (DPD; mu None = ka / 3), ``kb`` Kantor constant (DPD energy).
    radius_dpd : float
        Shell radius R (DPD length).
    kT : float
        Thermal energy (DPD energy).

    Returns
    -------
    numpy.ndarray
        sigma per shell (DPD length).

    Raises
    ------
    ValueError
        If ``radius_dpd`` is not a positive finite number, or a shell has kb <= 0 or ka <= 0.
    """
    if not (math.isfinite(radius_dpd) and radius_dpd > 0):
        raise ValueError(f"radius_dpd must be a positive finite DPD length, got {radius_dpd!r}")
    out = np.empty(len(params))
    for i, p in enumerate(params):
        mu = p.ka / 3.0 if p.mu is None else p.mu
        kappa = math.sqrt(3.0) / 2.0 * p.kb
        young = 4.0 * p.ka * mu / (p.ka + mu)
        if not (kappa > 0 and young > 0):
            raise ValueError(f"thermal contact needs kb > 0 and ka > 0 (shell {i}: kb {p.kb!r}, ka {p.ka!r})")
        out[i] = math.sqrt(kT * radius_dpd / (8.0 * math.sqrt(kappa * young)))
    return out


@functools.cache  # a slow quadrature; PlateContact is frozen, so (contact, kT) is a key
def hard_wall_distance(contact, kT: float = 1.0) -> float:
    """Barker-Henderson hard-wall distance of a capped WCA plate.

    Parameters
    ----------
    contact : bubblecal.sim.protocols.PlateContact
        The plate law.
    kT : float
        Thermal energy (DPD energy).

    Returns
    -------
    float
        h_w = int_0^{r_c} (1 - exp(-U(h)/kT)) dh (DPD length).
    """
    from scipy.integrate import quad

    from bubblecal.sim.protocols.plates import plate_force_energy

    def integrand(h):
        _, e = plate_force_energy(np.array([h]), contact)
        return 1.0 - math.exp(-min(e[0] / kT, 700.0))

    # the integrand is 1 up to ~0.9 and falls to 0 at the cut-off: integrate the tail finely
    head = 0.8 * contact.cutoff
    tail, _ = quad(integrand, head, contact.cutoff, limit=200, epsabs=1e-12)
    return head + tail


def inverse_mills_ratio(z: np.ndarray) -> np.ndarray:
    """Inverse Mills ratio phi(z) / Phi(z) of the standard normal, stable for any z.

    Parameters
    ----------
    z : numpy.ndarray
        Arguments (dimensionless).

    Returns
    -------
    numpy.ndarray
        phi(z) / Phi(z) (dimensionless); an asymptotic series below :data:`Z_ASYMPTOTIC` (the same rule as the
        Warp kernel), 0 from z = 12 on.
    """
    from scipy.special import ndtr

    z = np.asarray(z, dtype=np.float64)
    out = np.zeros_like(z)
    far = z < Z_ASYMPTOTIC
    iz2 = 1.0 / z[far] ** 2
    out[far] = -z[far] / (1.0 - iz2 + 3.0 * iz2**2 - 15.0 * iz2**3)
    mid = (~far) & (z < 12.0)
    out[mid] = _SQRT_2_OVER_PI * 0.5 * np.exp(-0.5 * z[mid] ** 2) / ndtr(z[mid])
    return out


#: below this reduced mean distance the wall force is continued linearly (module docstring)
G_MIN = 0.05
#: Newton iterations for z + M(z) = g (from z = -1/g below g = 1, z = g above: residual < 1e-11 after 6)
NEWTON_STEPS = 8


def _psi_exact(g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Psi(g) and dPsi/dg for g >= G_MIN (Newton on the convex z + M(z) = g)."""
    z = np.where(g < 1.0, -1.0 / g, g)
    for _ in range(NEWTON_STEPS):
        m = inverse_mills_ratio(z)
        z = z - (z + m - g) / np.maximum(1.0 - m * (z + m), 1e-300)
    m = inverse_mills_ratio(z)
    dm = -m * (z + m)
    return m, dm / (1.0 + dm)


@functools.cache
def psi_continuation() -> tuple[float, float]:
    """The linear continuation of Psi below :data:`G_MIN` (shared by :func:`wall_force_psi` and the Warp kernel).

    Returns
    -------
    tuple of float
        Psi(G_MIN) and dPsi/dg at G_MIN (dimensionless).
    """
    p0, dp0 = _psi_exact(np.array([G_MIN]))
    return float(p0[0]), float(dp0[0])


def wall_force_psi(g: np.ndarray) -> np.ndarray:
    """Reduced mean wall force Psi(g) (module docstring); F = (kT / sigma) Psi.

    Parameters
    ----------
    g : numpy.ndarray
        Reduced mean distance (h - h_w) / sigma from the hard wall (dimensionless).

    Returns
    -------
    numpy.ndarray
        Psi(g) (dimensionless), continued linearly below :data:`G_MIN`.
    """
    g = np.asarray(g, dtype=np.float64)
    out = np.empty_like(g)
    hi = g >= G_MIN
    out[hi] = _psi_exact(g[hi])[0]
    p0, dp0 = psi_continuation()
    out[~hi] = p0 + dp0 * (g[~hi] - G_MIN)
    return out


def thermal_plate_force(h: np.ndarray, sigma: np.ndarray, h_wall: float, kT: float = 1.0,
                        force_cap: float = np.inf) -> np.ndarray:
    """Mean plate force on thermally fluctuating vertices: (kT / sigma) Psi((h - h_wall) / sigma), capped.

    Parameters
    ----------
    h : numpy.ndarray
        Mean vertex-plate distances (DPD length).
    sigma : numpy.ndarray
        rms normal fluctuation (DPD length), broadcast against ``h``.
    h_wall : float
        Hard-wall distance (DPD length; :func:`hard_wall_distance`).
    kT : float
        Thermal energy (DPD energy).
    force_cap : float
        Largest force per vertex (DPD force).

    Returns
    -------
    numpy.ndarray
        Force magnitude (>= 0, pushing the vertex away from the plate; DPD force).
    """
    h = np.asarray(h, dtype=np.float64)
    s = np.broadcast_to(np.asarray(sigma, dtype=np.float64), h.shape)
    return np.minimum(kT / s * wall_force_psi((h - h_wall) / s), force_cap)
