"""Pure NumPy float64 reference of the shell energies and forces (docs/physics.md section 3).

One module per energy family (``lim``, ``bending``, ``constraints``, ``self_avoid``; ``total`` sums them,
``common`` holds the finite-difference helper).  Slow but transparent: the ground truth for the Warp kernels
in :mod:`bubblecal.sim.engine.kernels.shell` and for finite-difference tests.  Geometric conventions:
:mod:`bubblecal.sim.engine.mesh`.

Energy terms, in the order of :data:`bubblecal.sim.engine.ENERGY_TERMS` (also the columns of
``ShellForceField.energies``; the Lim area clamp is :data:`bubblecal.sim.engine.AREA_CLAMP`):

* ``in_plane``      Lim: sum_t A0 [(ka/2)(alpha^2 + a3 alpha^3 + a4 alpha^4) + mu (beta + b1 alpha beta + b2 beta^2)]
* ``bending``       Kantor kb sum_e [1 - cos(theta_e - theta0_e)]  or  Juelicher 2 kb sum_v A_v (H_v - c0/2)^2
* ``area``          ka_tot (A - A0)^2 / (2 A0)
* ``volume``        kv_tot (V - V0)^2 / (2 V0)
* ``back_pressure`` -p_back (V - V0)   (the work of the constant outward back pressure)
* ``self_avoid``    WCA Lennard-Jones between the vertices of one shell
"""

from bubblecal.sim.validation.shell_reference.bending import (
    dihedral_angle_gradients,
    juelicher_energy,
    juelicher_forces,
    kantor_energy,
    kantor_forces,
)
from bubblecal.sim.validation.shell_reference.common import finite_difference_forces
from bubblecal.sim.validation.shell_reference.constraints import (
    area_gradient,
    constraint_energies,
    constraint_forces,
    volume_gradient,
)
from bubblecal.sim.validation.shell_reference.lim import lim_energy, lim_forces, lim_triangle_forces
from bubblecal.sim.validation.shell_reference.self_avoid import self_avoid_energy, self_avoid_forces
from bubblecal.sim.validation.shell_reference.total import shell_energies, shell_forces

__all__ = [
    "lim_energy",
    "lim_triangle_forces",
    "lim_forces",
    "kantor_energy",
    "kantor_forces",
    "juelicher_energy",
    "juelicher_forces",
    "dihedral_angle_gradients",
    "area_gradient",
    "volume_gradient",
    "constraint_energies",
    "constraint_forces",
    "self_avoid_energy",
    "self_avoid_forces",
    "shell_energies",
    "shell_forces",
    "finite_difference_forces",
]
