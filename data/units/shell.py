"""Conversions between Young's modulus and the shell constants k_a, mu, k_b, and the published variable Yt.

Methods of :class:`~bubblecal.data.UnitSystem` (mixed in); they use its base units, shell thickness h,
Poisson ratio nu and force scale fscale (formulas in :mod:`bubblecal.data.units`, docs/physics.md section 1).
"""

from __future__ import annotations

import math

import numpy as np

__all__: list[str] = []


class _ShellConversions:
    """Mixin of :class:`~bubblecal.data.UnitSystem`: Young's modulus <-> shell constants."""

    def young_to_ka(self, E_Pa):
        """Young's modulus E [Pa] -> stretching modulus k_a [DPD 2-D modulus].

        Parameters
        ----------
        E_Pa : float or array_like
            Young's modulus of the shell material [Pa].

        Returns
        -------
        float or numpy.ndarray
            k_a = fscale E h / (2 (1 - nu)) [DPD 2-D modulus].
        """
        E = np.asarray(E_Pa, dtype=float)
        return self.modulus2d_to_dpd(E * self.shell_thickness_m / (2.0 * (1.0 - self.poisson)))

    def ka_to_young(self, ka):
        """Stretching modulus k_a [DPD 2-D modulus] -> Young's modulus E [Pa].

        Parameters
        ----------
        ka : float or array_like
            Stretching modulus [DPD 2-D modulus].

        Returns
        -------
        float or numpy.ndarray
            Young's modulus [Pa] (inverse of :meth:`young_to_ka`).
        """
        return self.modulus2d_to_physical(ka) * 2.0 * (1.0 - self.poisson) / self.shell_thickness_m

    def young_to_mu(self, E_Pa):
        """Young's modulus E [Pa] -> shear modulus mu [DPD 2-D modulus] (= k_a/3 at nu = 1/2).

        Parameters
        ----------
        E_Pa : float or array_like
            Young's modulus of the shell material [Pa].

        Returns
        -------
        float or numpy.ndarray
            mu = fscale E h / (2 (1 + nu)) [DPD 2-D modulus].
        """
        E = np.asarray(E_Pa, dtype=float)
        return self.modulus2d_to_dpd(E * self.shell_thickness_m / (2.0 * (1.0 + self.poisson)))

    def young_to_kb(self, E_Pa):
        """Young's modulus E [Pa] -> Kantor bending constant k_b [DPD energy, k_BT].

        Parameters
        ----------
        E_Pa : float or array_like
            Young's modulus of the shell material [Pa].

        Returns
        -------
        float or numpy.ndarray
            k_b = fscale (2/sqrt 3) E h^3 / (12 (1 - nu^2)) / u_e [DPD energy].
        """
        E = np.asarray(E_Pa, dtype=float)
        h = self.shell_thickness_m
        kappa = E * h**3 / (12.0 * (1.0 - self.poisson**2))
        return self.fscale * (2.0 / math.sqrt(3.0)) * kappa / self.energy_J

    def kb_to_young(self, kb):
        """Kantor bending constant k_b [DPD energy] -> Young's modulus E [Pa] (inverse of young_to_kb).

        Parameters
        ----------
        kb : float or array_like
            Kantor bending constant [DPD energy, k_BT].

        Returns
        -------
        float or numpy.ndarray
            Young's modulus [Pa].
        """
        h = self.shell_thickness_m
        kappa = np.asarray(kb, dtype=float) * self.energy_J / (self.fscale * 2.0 / math.sqrt(3.0))
        return kappa * 12.0 * (1.0 - self.poisson**2) / h**3

    def kb_to_bending_kBT(self, kb):
        """Kantor constant k_b [DPD energy] -> continuum bending modulus kappa [k_B T] = k_b sqrt(3)/(2 fscale).

        Parameters
        ----------
        kb : float or array_like
            Kantor bending constant [DPD energy, k_BT, fscale applied].

        Returns
        -------
        float or numpy.ndarray
            Continuum bending modulus of the real shell [k_B T].
        """
        return np.asarray(kb, dtype=float) * math.sqrt(3.0) / (2.0 * self.fscale)

    def bending_kBT_to_kb(self, kappa_kBT):
        """Continuum bending modulus kappa [k_B T] -> Kantor constant k_b [DPD energy].

        Parameters
        ----------
        kappa_kBT : float or array_like
            Continuum bending modulus of the real shell [k_B T].

        Returns
        -------
        float or numpy.ndarray
            Kantor bending constant [DPD energy, k_BT, fscale applied].
        """
        return np.asarray(kappa_kBT, dtype=float) * 2.0 * self.fscale / math.sqrt(3.0)

    def ka_to_yt(self, ka):
        """k_a [DPD 2-D modulus] -> published sampling variable Yt [Pa] (= 1790.92 k_a at the defaults).

        Parameters
        ----------
        ka : float or array_like
            Stretching modulus [DPD 2-D modulus].

        Returns
        -------
        float or numpy.ndarray
            Yt [Pa].
        """
        return np.asarray(ka, dtype=float) * self.yt_per_ka

    def yt_to_ka(self, yt_Pa):
        """Published sampling variable Yt [Pa] -> k_a [DPD 2-D modulus].

        Parameters
        ----------
        yt_Pa : float or array_like
            Yt [Pa].

        Returns
        -------
        float or numpy.ndarray
            Stretching modulus [DPD 2-D modulus].
        """
        return np.asarray(yt_Pa, dtype=float) / self.yt_per_ka
