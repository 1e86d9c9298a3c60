"""bubblecal.sim.engine: the Warp DPD engine (docs/physics.md sections 2-4 and 7).

What lives where:

* meshes and their stress-free reference: :mod:`~bubblecal.sim.engine.mesh` (geometry helpers in
  :mod:`~bubblecal.sim.engine.geometry`, the indentation pole patches in :mod:`~bubblecal.sim.engine.poles`);
* particle types, DPD pair tables and published constants: :mod:`~bubblecal.sim.engine.particles`;
* shell forces: :mod:`~bubblecal.sim.engine.kernels.shell` (:class:`ShellForceField`, :class:`ShellParams`);
* the explicit-solvent engine: replica descriptions (:mod:`~bubblecal.sim.engine.replicas`), the system
  (:mod:`~bubblecal.sim.engine.system`), its neighbour lists (:mod:`~bubblecal.sim.engine.neighbors`),
  measurements (:mod:`~bubblecal.sim.engine.system_observables`) and health checks
  (:mod:`~bubblecal.sim.engine.health`);
* the implicit-solvent shell system: :mod:`~bubblecal.sim.engine.implicit` (settings, observables beside it);
* minimisers: FIRE (:func:`fire_minimize`, the NumPy reference, and :class:`DeviceFire`, device-resident and
  batched) and a force-only nonlinear conjugate gradient (:func:`cg_minimize` and :class:`DeviceCG`), both device
  minimisers on :mod:`~bubblecal.sim.engine.minimize_device_base`;
* CUDA-graph chunks: :mod:`~bubblecal.sim.engine.graphs`; Warp kernels: :mod:`~bubblecal.sim.engine.kernels`.

Importing this package loads no Warp and compiles nothing: the Warp-backed classes are imported on first
access.  Units: DPD (length r_c = 250 nm, energy k_BT, water bead mass 1; :mod:`bubblecal.data.units`).
"""

from bubblecal._lazy import lazy_exports
from bubblecal.sim.engine.geometry import dihedral_angles, lim_reference, mesh_volume, triangle_areas
from bubblecal.sim.engine.implicit_settings import GAS_P0_DEFAULT, default_vertex_friction
from bubblecal.sim.engine.kernels.shell import (
    AREA_CLAMP,
    BENDING_MODELS,
    ENERGY_TERMS,
    FORCE_MODES,
    ShellParams,
    shell_params_from_arrays,
)
from bubblecal.sim.engine.mesh import (
    ShellMesh,
    build_shell_mesh,
    diameter_to_radius_dpd,
    icosphere,
    mesh_for_diameter,
    n_vertices_for_subdivisions,
)
from bubblecal.sim.engine.minimize import (
    STATUS_CONVERGED,
    STATUS_MAX_STEPS,
    STATUS_NONFINITE,
    FireResult,
    fire_minimize,
)
from bubblecal.sim.engine.minimize_cg import CG_DEFAULTS, CgResult, cg_minimize
from bubblecal.sim.engine.particles import (
    GAS,
    N_TYPES,
    P_BACK_DEFAULT,
    RHO_SHELL_KG_M3,
    TYPE_NAMES,
    VERTEX,
    WALL,
    WATER,
    PairTable,
    fluid_pair_table,
    gamma_fsi,
    published_pair_table,
)
from bubblecal.sim.engine.poles import pole_patches
from bubblecal.sim.engine.replicas import ReplicaSpec, bubble_spec, inside_convex_mesh

# Warp-backed exports, imported on first access (name -> module)
_LAZY = {
    "ShellForceField": "bubblecal.sim.engine.kernels.shell.field",
    "ParticleSystem": "bubblecal.sim.engine.system",
    "resolve_dtype": "bubblecal.sim.engine.system",
    "ImplicitShellSystem": "bubblecal.sim.engine.implicit",
    "HealthThresholds": "bubblecal.sim.engine.implicit_observables",
    "Status": "bubblecal.sim.engine.health",
    "HealthConfig": "bubblecal.sim.engine.health",
    "HealthReport": "bubblecal.sim.engine.health",
    "HealthMonitor": "bubblecal.sim.engine.health",
    "DeviceFire": "bubblecal.sim.engine.minimize_device",
    "DeviceCG": "bubblecal.sim.engine.minimize_device_cg",
    "DeviceMinimizer": "bubblecal.sim.engine.minimize_device_base",
    "DeviceMinimizeResult": "bubblecal.sim.engine.minimize_device_base",
    "numpy_force_fn": "bubblecal.sim.engine.minimize_device",
    "cuda_threads_per_replica": "bubblecal.sim.engine.minimize_device_base",
    "ChunkGraph": "bubblecal.sim.engine.graphs",
}

__all__ = [
    # meshes
    "ShellMesh", "icosphere", "mesh_for_diameter", "build_shell_mesh", "pole_patches", "diameter_to_radius_dpd",
    "n_vertices_for_subdivisions", "triangle_areas", "mesh_volume", "dihedral_angles", "lim_reference",
    # particles and published constants
    "WATER", "GAS", "VERTEX", "WALL", "N_TYPES", "TYPE_NAMES", "PairTable", "published_pair_table",
    "fluid_pair_table", "gamma_fsi", "RHO_SHELL_KG_M3", "P_BACK_DEFAULT",
    # shell forces
    "ShellForceField", "ShellParams", "FORCE_MODES", "BENDING_MODELS", "ENERGY_TERMS", "AREA_CLAMP",
    "shell_params_from_arrays",
    # explicit-solvent engine
    "ReplicaSpec", "bubble_spec", "inside_convex_mesh", "ParticleSystem", "resolve_dtype",
    "Status", "HealthConfig", "HealthReport", "HealthMonitor",
    # implicit-solvent shell system
    "ImplicitShellSystem", "HealthThresholds", "default_vertex_friction", "GAS_P0_DEFAULT",
    # minimisers and CUDA graphs
    "fire_minimize", "FireResult", "STATUS_CONVERGED", "STATUS_MAX_STEPS", "STATUS_NONFINITE",
    "cg_minimize", "CgResult", "CG_DEFAULTS",
    "DeviceFire", "DeviceCG", "DeviceMinimizer", "DeviceMinimizeResult", "numpy_force_fn", "cuda_threads_per_replica",
    "ChunkGraph",
]

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
