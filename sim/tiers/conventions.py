"""The published conventions every tier applies (docs/physics.md sections 5-7; the measurements behind them:
docs/decisions.md and benchmarks/RESULTS.md).

Compression (one place, every tier): the grid value ``d`` is the TOTAL imposed displacement (each plate moves
d/2, the gap shrinks by d) and the observable is the SUM of the reaction forces on both plates (= 2x the force
on one plate at equilibrium): :data:`DISPLACEMENT_CONVENTION`.  This is the convention of the published Mirheo
training data (``F_Delta.dat``).  An AFM measures the force on ONE plate at total displacement d; calibrating
with this convention reproduces the published study, see :mod:`bubblecal.models.mechanical`.

Bending (per protocol, :data:`KB_KERNEL_SCALE`): the published ``kb`` is the field's value; our Kantor kernel
gets ``kb * KB_KERNEL_SCALE[protocol]``.  Our kernel's effective rigidity is kappa = (sqrt 3 / 2) kb; the
published indentation data follow kappa = kb / sqrt 3 (docs/physics.md section 6), hence the scale 2/3 of
indentation under the ``bubblecal-v1`` convention.  The published compression data follow our kernel's
convention (scale 1).

Indentation (tier setting ``indentation_convention``, :data:`INDENTATION_CONVENTIONS`): how a published
indentation parameter set maps onto our kernel's kb and which vertices carry the pole force.

* ``bubblecal-v1`` (the default, :data:`DEFAULT_INDENTATION_CONVENTION`): k = max(1, floor(0.01 N_v)) top-most
  and as many bottom-most vertices (docs/physics.md section 5; 25 on the subdivision-4 mesh) and kernel
  kb = 2/3 published kb.  The scale 2/3 was fitted at 3.2 um with this patch: it compensates the loaded
  patch, not the bending modulus, so the error it leaves depends on ka / kb and on the diameter.
* ``mirheo``: the published curves' own convention: every vertex within 4.6 deg of a pole carries the pole
  force (the pole vertex and its first ring on the subdivision-4 mesh: 7 vertices; two rings at subdivision 5:
  19) and kernel kb = published kb, as in compression.  The patch is a polar cap, not a vertex fraction, so it
  stays the same on every mesh level.

Campaign files that do not name a convention keep the default, ``bubblecal-v1``.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "DISPLACEMENT_CONVENTION",
    "KB_KERNEL_SCALE",
    "IndentationConvention",
    "INDENTATION_CONVENTIONS",
    "DEFAULT_INDENTATION_CONVENTION",
    "indentation_convention",
]

#: Compression: grid d = total displacement; observable F = sum of the forces on both plates (module docstring).
DISPLACEMENT_CONVENTION = "total_displacement_both_plates_force"
#: Published kb -> our Kantor kernel's kb, per protocol, under the default indentation convention
#: ``bubblecal-v1``; the ``mirheo`` convention maps indentation's kb like compression's (scale 1).
KB_KERNEL_SCALE = {"compression": 1.0, "indentation": 2.0 / 3.0}


@dataclass(frozen=True)
class IndentationConvention:
    """How a published indentation parameter set maps onto our kernels and loading (module docstring).

    The pole force F is shared by the vertices of :func:`bubblecal.sim.engine.pole_patches`.

    Parameters
    ----------
    name : str
        The key in :data:`INDENTATION_CONVENTIONS`.
    kb_scale : float
        Published kb -> our Kantor kernel's kb (dimensionless factor).
    loaded_fraction : float or None
        k = max(1, floor(loaded_fraction N_v)) top-most and as many bottom-most vertices carry the load.
    description : str
        One line for records and messages.
    loaded_cap_deg : float or None
        Every vertex within this polar angle (deg) of a pole carries the load (the same patch on every mesh
        level); used when ``loaded_fraction`` is None.
    """

    name: str
    kb_scale: float
    loaded_fraction: float | None
    description: str
    loaded_cap_deg: float | None = None

    def pole_patch(self) -> dict:
        """Keyword arguments of :func:`bubblecal.sim.engine.pole_patches`.

        Returns
        -------
        dict
            ``{"fraction": loaded_fraction, "cap_deg": loaded_cap_deg}``.
        """
        return {"fraction": self.loaded_fraction, "cap_deg": self.loaded_cap_deg}


#: Named indentation conventions (a tier setting, ``indentation_convention``; module docstring).
INDENTATION_CONVENTIONS = {
    "bubblecal-v1": IndentationConvention(
        "bubblecal-v1", 2.0 / 3.0, 0.01, "k = floor(0.01 N_v) loaded vertices per pole, kernel kb = 2/3 published kb"),
    "mirheo": IndentationConvention(
        "mirheo", 1.0, None, "the vertices within 4.6 deg of each pole carry the pole force (the pole vertex and "
        "its first ring at subdivision 4: 7; two rings at 5: 19), kernel kb = published kb", loaded_cap_deg=4.6),
}
#: The convention of a tier that does not name one.
DEFAULT_INDENTATION_CONVENTION = "bubblecal-v1"


def indentation_convention(name: str) -> IndentationConvention:
    """The named indentation convention.

    Parameters
    ----------
    name : str
        A key of :data:`INDENTATION_CONVENTIONS`.

    Returns
    -------
    IndentationConvention

    Raises
    ------
    ValueError
        If ``name`` is not a known convention (the message lists the allowed names).
    """
    if name not in INDENTATION_CONVENTIONS:
        raise ValueError(f"indentation_convention must be one of {sorted(INDENTATION_CONVENTIONS)}, got {name!r}")
    return INDENTATION_CONVENTIONS[name]
