"""Conversions of lengths, forces, stiffnesses, 2-D moduli, pressure, time, frequency and bubble size.

Methods of :class:`~bubblecal.data.UnitSystem` (mixed in); they use its base units.
"""

from __future__ import annotations

import math

import numpy as np

__all__: list[str] = []


class _QuantityConversions:
    """Mixin of :class:`~bubblecal.data.UnitSystem`: conversions of physical quantities to and from DPD units."""

    # ----- length -------------------------------------------------------------------------
    def length_to_dpd(self, length_m):
        """Length [m] -> DPD length [u_l].

        Parameters
        ----------
        length_m : float or array_like
            Length [m].

        Returns
        -------
        float or numpy.ndarray
            Length [DPD length].
        """
        return np.asarray(length_m, dtype=float) / self.length_m

    def length_to_physical(self, length_dpd):
        """DPD length [u_l] -> length [m].

        Parameters
        ----------
        length_dpd : float or array_like
            Length [DPD length].

        Returns
        -------
        float or numpy.ndarray
            Length [m].
        """
        return np.asarray(length_dpd, dtype=float) * self.length_m

    def nm_to_dpd(self, length_nm):
        """Length [nm] -> DPD length [u_l] (1 DPD length = 250 nm at the defaults).

        Parameters
        ----------
        length_nm : float or array_like
            Length [nm].

        Returns
        -------
        float or numpy.ndarray
            Length [DPD length].
        """
        return self.length_to_dpd(np.asarray(length_nm, dtype=float) * 1e-9)

    def dpd_to_nm(self, length_dpd):
        """DPD length [u_l] -> length [nm].

        Parameters
        ----------
        length_dpd : float or array_like
            Length [DPD length].

        Returns
        -------
        float or numpy.ndarray
            Length [nm].
        """
        return self.length_to_physical(length_dpd) * 1e9

    # ----- force --------------------------------------------------------------------------
    def force_to_dpd(self, force_N):
        """Shell force [N] -> DPD force (fscale applied): F_dpd = fscale F / (u_e/u_l).

        Parameters
        ----------
        force_N : float or array_like
            Force on the shell [N].

        Returns
        -------
        float or numpy.ndarray
            Force [DPD force].
        """
        return self.fscale * np.asarray(force_N, dtype=float) / self.force_N

    def force_to_physical(self, force_dpd):
        """DPD force -> shell force [N] (inverse of :meth:`force_to_dpd`).

        Parameters
        ----------
        force_dpd : float or array_like
            Force [DPD force].

        Returns
        -------
        float or numpy.ndarray
            Force on the shell [N].
        """
        return np.asarray(force_dpd, dtype=float) * self.force_N / self.fscale

    def nN_to_dpd(self, force_nN):
        """Force [nN] -> DPD force (1 nN = 446.698 DPD force at the defaults).

        Parameters
        ----------
        force_nN : float or array_like
            Force on the shell [nN].

        Returns
        -------
        float or numpy.ndarray
            Force [DPD force].
        """
        return self.force_to_dpd(np.asarray(force_nN, dtype=float) * 1e-9)

    def dpd_to_nN(self, force_dpd):
        """DPD force -> force [nN].

        Parameters
        ----------
        force_dpd : float or array_like
            Force [DPD force].

        Returns
        -------
        float or numpy.ndarray
            Force on the shell [nN].
        """
        return self.force_to_physical(force_dpd) * 1e9

    # ----- stiffness (force per length) -----------------------------------------------------
    def stiffness_to_dpd(self, stiffness_N_per_m):
        """Spring stiffness [N/m] -> DPD force per DPD length (fscale applied).

        Parameters
        ----------
        stiffness_N_per_m : float or array_like
            Stiffness [N/m].

        Returns
        -------
        float or numpy.ndarray
            Stiffness [DPD force / DPD length].
        """
        return self.fscale * np.asarray(stiffness_N_per_m, dtype=float) / (self.force_N / self.length_m)

    def stiffness_to_physical(self, stiffness_dpd):
        """DPD force per DPD length -> stiffness [N/m].

        Parameters
        ----------
        stiffness_dpd : float or array_like
            Stiffness [DPD force / DPD length].

        Returns
        -------
        float or numpy.ndarray
            Stiffness [N/m].
        """
        return np.asarray(stiffness_dpd, dtype=float) * (self.force_N / self.length_m) / self.fscale

    # ----- 2-D modulus ----------------------------------------------------------------------
    def modulus2d_to_dpd(self, modulus_N_per_m):
        """2-D modulus (k_a, mu) [N/m] -> DPD 2-D modulus (fscale applied).

        Parameters
        ----------
        modulus_N_per_m : float or array_like
            2-D modulus [N/m].

        Returns
        -------
        float or numpy.ndarray
            2-D modulus [DPD 2-D modulus, k_BT/r_c^2].
        """
        return self.fscale * np.asarray(modulus_N_per_m, dtype=float) / self.modulus2d_N_per_m

    def modulus2d_to_physical(self, modulus_dpd):
        """DPD 2-D modulus -> 2-D modulus [N/m].

        Parameters
        ----------
        modulus_dpd : float or array_like
            2-D modulus [DPD 2-D modulus, k_BT/r_c^2].

        Returns
        -------
        float or numpy.ndarray
            2-D modulus [N/m].
        """
        return np.asarray(modulus_dpd, dtype=float) * self.modulus2d_N_per_m / self.fscale

    # ----- pressure -------------------------------------------------------------------------
    def pressure_to_dpd(self, pressure_Pa):
        """Solvent pressure [Pa] -> DPD pressure (u_e/u_l^3; no fscale).

        Parameters
        ----------
        pressure_Pa : float or array_like
            Pressure [Pa].

        Returns
        -------
        float or numpy.ndarray
            Pressure [DPD pressure].
        """
        return np.asarray(pressure_Pa, dtype=float) / self.pressure_Pa

    def pressure_to_physical(self, pressure_dpd):
        """DPD pressure -> solvent pressure [Pa].

        Parameters
        ----------
        pressure_dpd : float or array_like
            Pressure [DPD pressure].

        Returns
        -------
        float or numpy.ndarray
            Pressure [Pa].
        """
        return np.asarray(pressure_dpd, dtype=float) * self.pressure_Pa

    # ----- time and frequency ---------------------------------------------------------------
    def time_to_dpd(self, time_s):
        """Time [s] -> DPD time [u_t].

        Parameters
        ----------
        time_s : float or array_like
            Time [s].

        Returns
        -------
        float or numpy.ndarray
            Time [DPD time].
        """
        return np.asarray(time_s, dtype=float) / self.time_s

    def time_to_physical(self, time_dpd):
        """DPD time [u_t] -> time [s].

        Parameters
        ----------
        time_dpd : float or array_like
            Time [DPD time].

        Returns
        -------
        float or numpy.ndarray
            Time [s].
        """
        return np.asarray(time_dpd, dtype=float) * self.time_s

    def frequency_to_physical(self, frequency_dpd, mass_factor: float = 1.0):
        """Frequency [cycles per u_t] measured with shell mass x mass_factor -> real frequency [Hz].

        f = f_dpd sqrt(mass_factor) / u_t: the ringdown runs with a heavier shell (f ~ M^-1/2).

        Parameters
        ----------
        frequency_dpd : float or array_like
            Frequency [cycles per DPD time] measured in the run.
        mass_factor : float
            Factor M by which the run multiplied the shell mass [-].

        Returns
        -------
        float or numpy.ndarray
            Frequency of the real bubble [Hz].

        Raises
        ------
        ValueError
            If ``mass_factor`` <= 0.
        """
        if mass_factor <= 0:
            raise ValueError(f"mass_factor must be > 0, got {mass_factor}")
        return np.asarray(frequency_dpd, dtype=float) * math.sqrt(mass_factor) / self.time_s

    def frequency_to_dpd(self, frequency_Hz, mass_factor: float = 1.0):
        """Real frequency [Hz] -> frequency [cycles per u_t] in a run with shell mass x mass_factor.

        Parameters
        ----------
        frequency_Hz : float or array_like
            Frequency of the real bubble [Hz].
        mass_factor : float
            Factor M by which the run multiplies the shell mass [-].

        Returns
        -------
        float or numpy.ndarray
            Frequency [cycles per DPD time] in the run.

        Raises
        ------
        ValueError
            If ``mass_factor`` <= 0.
        """
        if mass_factor <= 0:
            raise ValueError(f"mass_factor must be > 0, got {mass_factor}")
        return np.asarray(frequency_Hz, dtype=float) * self.time_s / math.sqrt(mass_factor)

    def angular_to_physical_Hz(self, omega_dpd, mass_factor: float = 1.0):
        """Angular frequency [rad per u_t] -> frequency [Hz]: f = omega sqrt(M) / (2 pi u_t).

        Parameters
        ----------
        omega_dpd : float or array_like
            Angular frequency [rad per DPD time] measured in the run.
        mass_factor : float
            Factor M by which the run multiplied the shell mass [-].

        Returns
        -------
        float or numpy.ndarray
            Frequency of the real bubble [Hz].

        Raises
        ------
        ValueError
            If ``mass_factor`` <= 0.
        """
        return self.frequency_to_physical(np.asarray(omega_dpd, dtype=float) / (2 * math.pi), mass_factor)

    # ----- geometry -----------------------------------------------------------------------
    def radius_dpd(self, diameter_um):
        """Bubble diameter [um] -> DPD radius [u_l] (2.1 um -> 4.2 at u_l = 0.25 um).

        Parameters
        ----------
        diameter_um : float or array_like
            Bubble diameter [um].

        Returns
        -------
        float or numpy.ndarray
            Bubble radius [DPD length].
        """
        return np.asarray(diameter_um, dtype=float) * 1e-6 / (2.0 * self.length_m)
