"""Expected breathing-mode frequencies (docs/physics.md section 6, check 7) and the step schedule they imply."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["breathing_mode_prediction", "auto_schedule", "WATER_MASS_DENSITY_DPD", "WATER_BULK_MODULUS_DPD"]

#: Mass density of DPD water (bead mass 1 x number density 3), DPD mass / length^3.
WATER_MASS_DENSITY_DPD = 3.0
#: Isothermal bulk modulus rho dP/drho of DPD water at a = 100, rho = 3 from the check-1 pressure
#: 89.05 = rho + alpha a rho^2 (alpha = 0.0956): K = rho (1 + 2 alpha a rho) = rho + 2 (P - rho) ~ 175 DPD pressure.
WATER_BULK_MODULUS_DPD = 3.0 + 2.0 * (89.05 - 3.0)


def breathing_mode_prediction(ka, radius, p_gas, shell_mass, *, area_ratio: float = 1.0, explicit: bool = False,
                              box=None,
                              rho_water: float = WATER_MASS_DENSITY_DPD,
                              bulk_modulus: float = WATER_BULK_MODULUS_DPD) -> dict[str, np.ndarray]:
    """Breathing-mode natural angular frequency of a spherical shell (check 7, docs/physics.md section 6).

    ``omega0_sq = (16 pi ka + 12 pi R p_gas) / M``: Lim area term E = 8 pi ka x^2 for a radial displacement x
    (alpha = 2 x / R; shear and stress-free Kantor bending vanish for a uniform dilation) plus the isothermal
    gas (dp = -3 p x / R over 4 pi R^2).

    Mesh correction: on a triangulated sphere whose N_v equal-mass vertices lie at radius r_v the uniform
    dilation gives 16 pi ka A_mesh / (4 pi r_v^2) instead of 16 pi ka (``area_ratio`` = A_mesh / (4 pi r_v^2):
    0.928, 0.981, 0.995, 0.9988 for icosphere subdivisions 1-4); returned as ``omega0_sq_mesh``.

    With ``explicit=True`` the water's effect is estimated as well: added mass of the radial flow
    4 pi rho R^3 (1 - R / R_box) (R_box = radius of the sphere of the box volume) and the stiffness of
    compressing the periodic box's water, K (4 pi R^2)^2 / V_water; returned as ``omega0_sq_water``.

    Parameters
    ----------
    ka : array_like
        Lim 2-D modulus (DPD force / length).
    radius : array_like
        Shell radius R (DPD length).
    p_gas : array_like
        Gas pressure inside (DPD pressure).
    shell_mass : array_like
        M = N_v m_v, mass factor included (DPD mass).
    area_ratio : float
        A_mesh / (4 pi r_v^2) of the mesh (dimensionless).
    explicit : bool
        Also estimate the explicit water's added mass and box stiffness.
    box : sequence of float, optional
        Box edge lengths (DPD length); required with ``explicit``.
    rho_water : float
        Water mass density (DPD mass / length^3).
    bulk_modulus : float
        Isothermal bulk modulus of the water (DPD pressure).

    Returns
    -------
    dict
        Arrays (broadcast): ``k_shell``, ``k_gas``, ``shell_mass``, ``omega0_sq`` (check 7), ``omega0`` (rad
        per DPD time), ``area_ratio``, ``omega0_sq_mesh``; with ``explicit`` also ``added_mass``,
        ``k_water_box``, ``omega0_sq_water``, ``omega0_water``.

    Raises
    ------
    ValueError
        If ``explicit`` is set without ``box``.
    """
    ka = np.asarray(ka, dtype=np.float64)
    R = np.asarray(radius, dtype=np.float64)
    p = np.asarray(p_gas, dtype=np.float64)
    M = np.asarray(shell_mass, dtype=np.float64)
    k_shell = 16.0 * math.pi * ka
    k_gas = 12.0 * math.pi * R * p
    w2 = (k_shell + k_gas) / M
    w2m = (k_shell * float(area_ratio) + k_gas) / M
    out = {"k_shell": k_shell, "k_gas": k_gas, "shell_mass": M, "omega0_sq": w2, "omega0": np.sqrt(w2),
           "area_ratio": np.full_like(w2, float(area_ratio)), "omega0_sq_mesh": w2m}
    if explicit:
        if box is None:
            raise ValueError("breathing_mode_prediction(explicit=True) needs the box edge lengths")
        vbox = float(np.prod(np.asarray(box, dtype=np.float64)))
        r_box = (3.0 * vbox / (4.0 * math.pi)) ** (1.0 / 3.0)
        m_add = 4.0 * math.pi * rho_water * R**3 * np.clip(1.0 - R / r_box, 0.0, None)
        v_water = vbox - 4.0 / 3.0 * math.pi * R**3
        k_box = bulk_modulus * (4.0 * math.pi * R**2) ** 2 / v_water
        w2w = (k_shell + k_gas + k_box) / (M + m_add)
        out.update({"added_mass": m_add, "k_water_box": k_box, "omega0_sq_water": w2w, "omega0_water": np.sqrt(w2w)})
    return out


def auto_schedule(omega_min: float, omega_max: float, dt: float, *, n_periods: float = 8.0,
                  samples_per_period: int = 40, equilibration_periods: float = 2.0,
                  min_equilibration: int = 1000) -> dict[str, int]:
    """Step counts for a ringdown from the expected angular frequencies.

    Parameters
    ----------
    omega_min, omega_max : float
        Slowest and fastest expected angular frequency (rad per DPD time).
    dt : float
        Time step (DPD time).
    n_periods : float
        Longest periods covered by the record.
    samples_per_period : int
        Minimum samples per shortest period.
    equilibration_periods : float
        Longest periods of equilibration.
    min_equilibration : int
        Minimum equilibration steps.

    Returns
    -------
    dict
        ``record_every``, ``record_steps`` (a multiple of it) and ``equilibration_steps``, in steps of ``dt``.

    Raises
    ------
    ValueError
        Unless 0 < omega_min <= omega_max and dt > 0.
    """
    if not (omega_min > 0 and omega_max >= omega_min and dt > 0):
        raise ValueError(f"auto_schedule needs 0 < omega_min <= omega_max and dt > 0, got {omega_min}, "
                         f"{omega_max}, {dt}")
    t_short = 2.0 * math.pi / omega_max
    t_long = 2.0 * math.pi / omega_min
    every = max(1, int(t_short / (samples_per_period * dt)))
    rec = int(math.ceil(n_periods * t_long / dt / every)) * every
    eq = max(int(min_equilibration), int(math.ceil(equilibration_periods * t_long / dt)))
    return {"record_every": every, "record_steps": rec, "equilibration_steps": eq}


def _schedule(pred_w, dt, equilibration_steps, record_steps, record_every, n_periods, samples_per_period):
    """(equilibration, record, record_every) steps: the given ones, the rest from :func:`auto_schedule`."""
    w = np.asarray(pred_w, dtype=np.float64)
    w = w[np.isfinite(w) & (w > 0)]
    if w.size == 0:
        raise ValueError("cannot schedule the ringdown: no positive predicted frequency")
    auto = auto_schedule(float(w.min()), float(w.max()), dt, n_periods=n_periods,
                         samples_per_period=samples_per_period)
    every = int(record_every) if record_every is not None else auto["record_every"]
    if record_steps is None:
        rec = int(math.ceil(auto["record_steps"] / every)) * every
    else:
        rec = int(record_steps)
    if rec % every:
        raise ValueError(f"record_steps ({rec}) must be a multiple of record_every ({every})")
    eq = int(equilibration_steps) if equilibration_steps is not None else auto["equilibration_steps"]
    return eq, rec, every
