"""Shell parameters (one frozen dataclass per replica), exported by :mod:`bubblecal.sim.engine.kernels.shell`.

Kept free of Warp so that configuration code can import it cheaply.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from bubblecal.data import SHELL_PARAMETERS

__all__ = ["ShellParams", "BENDING_MODELS", "FORCE_MODES", "shell_params_from_arrays"]

#: Bending energies of :class:`ShellParams` (``bending``).
BENDING_MODELS = ("kantor", "juelicher")
#: how ShellForceField sums the Lim / Kantor forces: auto (gather on a GPU, scatter on the CPU), per vertex, per element
FORCE_MODES = ("auto", "gather", "scatter")


def _check(name: str, value, lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
           allow_none: bool = False) -> None:
    """Raise ValueError unless ``value`` is a finite number in the given range."""
    if value is None and allow_none:
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"ShellParams.{name} must be a finite number, got {value!r}")
    if lo is not None and (value <= lo if lo_open else value < lo):
        rng = f"{'(' if lo_open else '['}{lo}, {hi if hi is not None else 'inf'}{']' if hi is not None else ')'}"
        raise ValueError(f"ShellParams.{name} must lie in {rng}, got {value!r}")
    if hi is not None and value > hi:
        rng = f"{'(' if lo_open else '['}{lo if lo is not None else '-inf'}, {hi}]"
        raise ValueError(f"ShellParams.{name} must lie in {rng}, got {value!r}")


@dataclass(frozen=True)
class ShellParams:
    """Membrane parameters of one replica (DPD units; docs/physics.md section 3).

    Parameters
    ----------
    ka : float
        Area-dilation modulus k_a (> 0, DPD 2-D modulus k_BT / r_c^2).
    mu : float, optional
        Shear modulus (>= 0, DPD 2-D modulus); None -> ka / 3.
    a3, a4, b1, b2 : float, optional
        Lim non-linear coefficients (dimensionless).
    kb : float, optional
        Bending constant (>= 0, DPD energy k_BT).
    bending : str, optional
        One of :data:`BENDING_MODELS`: ``'kantor'`` (stress-free: E = kb sum_e [1 - cos(theta_e - theta0_e)])
        or ``'juelicher'`` (E = 2 kb sum_v A_v (H_v - c0/2)^2).
    c0 : float, optional
        Spontaneous curvature (Juelicher only, 1 / DPD length).
    ka_tot, kv_tot : float, optional
        Global area / volume constraints (>= 0; 0 = off, the default; DPD 2-D modulus and DPD pressure):
        U_A = ka_tot (A - A0)^2 / (2 A0), U_V = kv_tot (V - V0)^2 / (2 V0).
    p_back : float, optional
        Constant outward back pressure p_b (DPD pressure): force p_b dV/dx_v.
    self_avoid : bool, optional
        Repulsive (WCA) Lennard-Jones between the vertices of one shell; on by default.
    self_avoid_epsilon : float, optional
        Its energy scale (>= 0, k_BT).
    self_avoid_cutoff : float, optional
        Its cut-off as a fraction (0, 1] of the shortest reference edge (sigma = cut-off / 2^(1/6)).
    bond_viscosity : float, optional
        Dissipative force -eta ((v_b - v_a).e) e along every edge (>= 0, DPD mass / time; 0 = off).

    Raises
    ------
    ValueError
        When a value is not finite, out of its range, or ``bending`` is unknown.
    """

    ka: float
    mu: float | None = None
    a3: float = 0.0
    a4: float = 0.0
    b1: float = 0.0
    b2: float = 0.0
    kb: float = 0.0
    bending: str = "kantor"
    c0: float = 0.0
    ka_tot: float = 0.0
    kv_tot: float = 0.0
    p_back: float = 0.0
    self_avoid: bool = True
    self_avoid_epsilon: float = 1.0
    self_avoid_cutoff: float = 0.8
    bond_viscosity: float = 0.0

    def __post_init__(self) -> None:
        """Check every field and fill in mu = ka / 3 when it is None."""
        _check("ka", self.ka, 0.0, lo_open=True)
        if self.mu is None:
            object.__setattr__(self, "mu", float(self.ka) / 3.0)
        _check("mu", self.mu, 0.0)
        for name in ("a3", "a4", "b1", "b2", "c0", "p_back"):
            _check(name, getattr(self, name))
        for name in ("kb", "ka_tot", "kv_tot", "bond_viscosity", "self_avoid_epsilon"):
            _check(name, getattr(self, name), 0.0)
        _check("self_avoid_cutoff", self.self_avoid_cutoff, 0.0, 1.0, lo_open=True)
        if self.bending not in BENDING_MODELS:
            raise ValueError(f"ShellParams.bending must be one of {BENDING_MODELS}, got {self.bending!r}")
        if not isinstance(self.self_avoid, bool):
            raise ValueError(f"ShellParams.self_avoid must be a bool, got {self.self_avoid!r}")

    def as_dict(self) -> dict:
        """Every field by name.

        Returns
        -------
        dict
            JSON-friendly.
        """
        return {f.name: getattr(self, f.name) for f in fields(self)}


def shell_params_from_arrays(params, kb_scale: float = 1.0) -> list[ShellParams]:
    """One :class:`ShellParams` per replica from per-replica arrays of the shell constants.

    Parameters
    ----------
    params : mapping
        :data:`bubblecal.data.names.SHELL_PARAMETERS` (``ka, kb, b1, b2, a3, a4``) -> sequences [R], DPD units.
    kb_scale : float, optional
        Factor on kb (a bending-convention factor).

    Returns
    -------
    list of ShellParams
        R parameter sets with mu = ka / 3 and the other fields at their defaults.

    Raises
    ------
    ValueError
        When a value is out of range (see :class:`ShellParams`).
    """
    return [ShellParams(**{k: float(params[k][r]) * (kb_scale if k == "kb" else 1.0) for k in SHELL_PARAMETERS})
            for r in range(len(params["ka"]))]
