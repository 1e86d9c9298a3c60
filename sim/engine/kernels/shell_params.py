"""Shell parameters (one frozen dataclass per replica); re-exported by :mod:`bubblecal.sim.engine.kernels.shell`.

Kept free of Warp so that configuration code can import it cheaply.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

__all__ = ["ShellParams", "BENDING_MODELS", "FORCE_MODES", "shell_params_from_arrays"]

BENDING_MODELS = ("kantor", "juelicher")
#: how ShellForceField sums the Lim / Kantor forces: auto (gather on a GPU, scatter on the CPU), per vertex, per element
FORCE_MODES = ("auto", "gather", "scatter")


def _check(name: str, value, lo: float | None = None, hi: float | None = None, *, lo_open: bool = False,
           allow_none: bool = False) -> None:
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
    """Membrane parameters of one replica (DPD units; physics.md section 3).

    * ``ka`` area-dilation modulus k_a (> 0, DPD 2-D modulus); ``mu`` shear modulus (None -> ka/3).
    * ``a3, a4, b1, b2`` Lim non-linear coefficients (dimensionless).
    * ``kb`` bending constant (>= 0, DPD energy); ``bending`` = ``'kantor'`` (stress-free:
      E = kb sum_e [1 - cos(theta_e - theta0_e)]) or ``'juelicher'`` (E = 2 kb sum_v A_v (H_v - c0/2)^2);
      ``c0`` spontaneous curvature (Juelicher only, 1/DPD length).
    * ``ka_tot``, ``kv_tot`` global area / volume constraints (>= 0; 0 = off, the default):
      U_A = ka_tot (A - A0)^2 / (2 A0), U_V = kv_tot (V - V0)^2 / (2 V0).
    * ``p_back`` constant outward back pressure p_b (DPD pressure): force p_b dV/dx_v.
    * ``self_avoid`` repulsive (WCA) Lennard-Jones between the vertices of one shell, energy scale
      ``self_avoid_epsilon`` (DPD energy) and cut-off ``self_avoid_cutoff`` x the shortest reference
      edge (sigma = cut-off / 2^(1/6)).  On by default.
    * ``bond_viscosity`` dissipative force -eta ((v_b - v_a).e) e along every edge (0 = off).
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
        return {f.name: getattr(self, f.name) for f in fields(self)}


def shell_params_from_arrays(params, kb_scale: float = 1.0) -> list[ShellParams]:
    """One :class:`ShellParams` per replica from a mapping of ``ka, kb, b1, b2, a3, a4`` -> sequences [R]
    (DPD units; mu = ka / 3), with kb multiplied by ``kb_scale`` (a bending-convention factor)."""
    names = ("ka", "kb", "b1", "b2", "a3", "a4")
    return [ShellParams(**{k: float(params[k][r]) * (kb_scale if k == "kb" else 1.0) for k in names})
            for r in range(len(params["ka"]))]
