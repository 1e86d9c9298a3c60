"""Athermal quasi-static fidelity tier for the two mechanical loading protocols (docs/physics.md sections 5, 7).

At every load point the shell (+ enclosed ideal gas) is relaxed to a force-balanced state with FIRE; load points
are chained (each starts from the previous minimum, or from the linear extrapolation of the last two).  R replicas
(one :class:`~bubblecal.sim.engine.kernels.shell.ShellParams` each, same mesh) are batched into one
:class:`~bubblecal.sim.engine.kernels.shell.ShellForceField` and minimised together, each with its own FIRE
state.  No solvent, no temperature: this is the cheap tier that is validated against the explicit one.  The
minimiser is the device-resident batched FIRE (:mod:`.backends`) on every Warp device, the CPU included;
``dtype=wp.float32`` is offered for GPU throughput (curves close to float64, see benchmarks/RESULTS.md).

Choices (stated once; also returned in ``result.settings``):

* **Gas** (:class:`IdealGas`): isothermal ideal gas p V = p0 V0 inside; default p0 = 3 DPD pressure
  (ideal gas at number density 3, k_BT = 1, as in the Reissner check of :mod:`bubblecal.sim.validation.checks`),
  balanced at the reference by a constant ambient pressure p_ambient (default = p0), so the stress-free sphere
  is force-free.  In the explicit model the water pressure (~89) is balanced by gas + back pressure p_b = 91;
  a *constant* pressure adds no stiffness, so only p0 (the gas bulk modulus) matters here.  ``gas=None``
  removes the gas (shell only).
* **Indentation**: the vertices of :func:`bubblecal.sim.engine.pole_patches` (default
  k = max(1, floor(0.01 N_v)) top-most and bottom-most reference vertices by z) carry -F/k and +F/k along z.
  Centre of mass pinned: the mean force over each replica's vertices is subtracted (all three components).
  Equator anchored in z: vertices with |z - z_c| < 0.25 l_min of the reference do not move in z.  Observable
  d(F) = H0 - H(F) with H = max z - min z of the shell (axial extent, "pole-to-pole distance"); the distance
  between the loaded patches' mean z is returned as well (``d_patch``).
* **Compression**: analytic plates z = z_c +- (h0 + gap - d/2), h0 = max_v |z_v - z_c| of the reference,
  ``gap`` default 1 = the LJ range, so the plates just touch at d = 0 (zero force in this athermal tier
  without the thermal contact; the published thermal curves have F(0) > 0).  Plate-vertex force: the capped
  WCA of :class:`bubblecal.sim.protocols.PlateContact`.  Centre of mass pinned in x, y (mean x, y force
  removed).  Observable F(d) = force on ONE plate: the sum of plate-vertex forces on the top plate (positive =
  compressive); the bottom plate's is returned too (``force_bottom``; equal at equilibrium).  The tier
  (:class:`QuasistaticTier`) reports the SUM of both, :data:`bubblecal.sim.tiers.DISPLACEMENT_CONVENTION`.
* **Status per replica**: ``'ok'``; ``'not_converged'`` (FIRE hit ``max_steps`` at some point; the chain goes
  on, or ends there with ``FireSettings.stop_at_max_steps``); ``'nonfinite'``; ``'ruptured'`` (max triangle area
  strain |A/A0 - 1| above ``rupture_strain``, default 1.0); indentation with ``max_depth_fall``: ``'collapsed'``
  (the depth fell under the rising force, :mod:`.collapse`).  After ``nonfinite`` / ``ruptured`` the replica is
  frozen and its later observables are NaN; a ``collapsed`` curve reports NaN from its collapse point on.
  ``point_status[r][j]`` holds the per-point verdict.

Modules: :mod:`.settings` (gas, FIRE, statuses, argument checks), :mod:`.thermal_contact` (the entropic plate
contact), :mod:`.backends` (the device chain), :mod:`.schedule` (lock-step and asynchronous schedules, slot
refill), :mod:`.grids` (sub-steps, first-load ramp), :mod:`.compression`, :mod:`.indentation`,
:mod:`.collapse`, :mod:`.results`
and :mod:`.tier` (:class:`QuasistaticTier`).  Importing this package does not import Warp.
"""

from bubblecal.sim.tiers.quasistatic.collapse import depth_collapse_point
from bubblecal.sim.tiers.quasistatic.compression import compression_pools, quasistatic_compression
from bubblecal.sim.tiers.quasistatic.indentation import quasistatic_indentation
from bubblecal.sim.tiers.quasistatic.results import CompressionResult, IndentationResult
from bubblecal.sim.tiers.quasistatic.settings import (
    MINIMIZERS,
    SCHEDULES,
    STATUS_COLLAPSED,
    STATUS_NONFINITE,
    STATUS_NOT_CONVERGED,
    STATUS_OK,
    STATUS_RUPTURED,
    FireSettings,
    IdealGas,
)
from bubblecal.sim.tiers.quasistatic.thermal_contact import (
    G_MIN,
    ThermalContact,
    hard_wall_distance,
    inverse_mills_ratio,
    psi_continuation,
    shell_fluctuation_sigma,
    thermal_plate_force,
    wall_force_psi,
)
from bubblecal.sim.tiers.quasistatic.tier import QuasistaticTier

__all__ = [
    "QuasistaticTier",
    "quasistatic_compression",
    "compression_pools",
    "quasistatic_indentation",
    "CompressionResult",
    "IndentationResult",
    "IdealGas",
    "FireSettings",
    "MINIMIZERS",
    "SCHEDULES",
    "STATUS_OK",
    "STATUS_NOT_CONVERGED",
    "STATUS_NONFINITE",
    "STATUS_RUPTURED",
    "STATUS_COLLAPSED",
    "depth_collapse_point",
    "ThermalContact",
    "hard_wall_distance",
    "shell_fluctuation_sigma",
    "thermal_plate_force",
    "wall_force_psi",
    "psi_continuation",
    "inverse_mills_ratio",
    "G_MIN",
]
