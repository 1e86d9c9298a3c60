"""Result types of the quasi-static compression and indentation runs (DPD units)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["IndentationResult", "CompressionResult"]


@dataclass(kw_only=True)
class _ChainResult:
    """Fields every quasi-static result has (documented in :class:`IndentationResult`)."""

    volume: np.ndarray
    max_area_strain: np.ndarray
    fmax: np.ndarray
    fire_steps: np.ndarray
    status: list[str]
    point_status: list[list[str]]
    x_final: np.ndarray
    settings: dict = field(default_factory=dict)
    seconds: float = 0.0


@dataclass(kw_only=True)
class IndentationResult(_ChainResult):
    """Quasi-static indentation curves of R replicas at P forces (DPD units).

    Parameters
    ----------
    volume : numpy.ndarray
        [R, P] enclosed volume (DPD length^3).
    max_area_strain : numpy.ndarray
        [R, P] max triangle area strain abs(A/A0 - 1).
    fmax : numpy.ndarray
        [R, P] final per-vertex force residual (DPD force).
    fire_steps : numpy.ndarray
        [R, P] FIRE iterations per point (sub-steps and ramp points included).
    status : list of str
        [R] curve verdict: 'ok', 'not_converged', 'nonfinite' or 'ruptured'.
    point_status : list of list of str
        [R][P] per-point verdicts.
    x_final : numpy.ndarray
        [R*Nv, 3] final positions (DPD length).
    settings : dict
        The run's choices (gas, loading, FIRE, schedule, ...).
    seconds : float
        Wall time (s).
    forces : numpy.ndarray
        [P] total force per pole (DPD force).
    displacement : numpy.ndarray
        [R, P] d(F) = H0 - H, the axial extent reduction (DPD length); NaN after a failure.
    axial_diameter : numpy.ndarray
        [R, P] H = max z - min z of the shell (DPD length).
    axial_diameter0 : numpy.ndarray
        [R] H0 of the reference (DPD length).
    d_patch : numpy.ndarray
        [R, P] reduction of the distance between the loaded patches' mean z (DPD length).
    """

    forces: np.ndarray
    displacement: np.ndarray
    axial_diameter: np.ndarray
    axial_diameter0: np.ndarray
    d_patch: np.ndarray


@dataclass(kw_only=True)
class CompressionResult(_ChainResult):
    """Quasi-static compression curves of R replicas at P imposed total displacements (DPD units).

    Parameters
    ----------
    volume : numpy.ndarray
        [R, P] enclosed volume (DPD length^3).
    max_area_strain : numpy.ndarray
        [R, P] max triangle area strain abs(A/A0 - 1).
    fmax : numpy.ndarray
        [R, P] final per-vertex force residual (DPD force).
    fire_steps : numpy.ndarray
        [R, P] FIRE iterations per point (sub-steps and ramp points included).
    status : list of str
        [R] curve verdict: 'ok', 'not_converged', 'nonfinite' or 'ruptured'.
    point_status : list of list of str
        [R][P] per-point verdicts.
    x_final : numpy.ndarray
        [R*Nv, 3] final positions (DPD length).
    settings : dict
        The run's choices (gas, loading, FIRE, schedule, ...).
    seconds : float
        Wall time (s).
    displacements : numpy.ndarray
        [P] imposed total displacements (DPD length); [R, P] for a batch of several sizes.
    force : numpy.ndarray
        [R, P] compressive force on the top plate (ONE plate; DPD force); NaN after a failure.
    force_bottom : numpy.ndarray
        [R, P] the same for the bottom plate (equal at equilibrium).
    n_contacts : numpy.ndarray
        [R, P] vertices in range of the top plate.
    plate_z : numpy.ndarray
        [P] top plate height (DPD length), [R, P] for several sizes; the bottom plate is mirrored about z_c.
    """

    displacements: np.ndarray
    force: np.ndarray
    force_bottom: np.ndarray
    n_contacts: np.ndarray
    plate_z: np.ndarray
