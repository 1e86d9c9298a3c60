"""bubblecal.sim.engine.kernels.shell: the shell (membrane) forces, one module per force family.

:class:`ShellForceField` (``field``) adds the forces of R replicas' shells in a handful of launches
(docs/physics.md section 3); :class:`ShellParams` (``params``) holds one replica's membrane parameters.  The
families: ``lim`` (Lim in-plane triangle forces with the global constraints and inside pressures),
``constraints`` (area / volume totals, gas pressure), ``bending`` (Kantor, Juelicher), ``gather`` (per-vertex
Lim + Kantor), ``self_avoid`` (vertex WCA), ``viscosity`` (bond viscosity), ``diagnostics`` (health
indicators); ``geometry`` holds the shared dihedral functions, ``layout`` the device-table columns,
``topology`` the host-side packing, ``launch`` the launch sequence and ``measure`` the field's measurement
methods (energies, areas / volumes, health, NumPy interface).

Importing this package loads no Warp: :class:`ShellForceField` is imported on first access, so configuration
code can use :class:`ShellParams` cheaply.
"""

from bubblecal._lazy import lazy_exports
from bubblecal.sim.engine.kernels.shell.layout import AREA_CLAMP, ENERGY_TERMS
from bubblecal.sim.engine.kernels.shell.params import (
    BENDING_MODELS,
    FORCE_MODES,
    ShellParams,
    shell_params_from_arrays,
)

__all__ = ["ShellForceField", "ShellParams", "FORCE_MODES", "BENDING_MODELS", "shell_params_from_arrays",
           "ENERGY_TERMS", "AREA_CLAMP"]

_LAZY = {"ShellForceField": "bubblecal.sim.engine.kernels.shell.field"}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
