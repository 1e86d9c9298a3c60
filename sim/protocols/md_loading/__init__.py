"""MD loading protocols (docs/physics.md section 5) run by the two thermal tiers, ``explicit`` and ``implicit``
(:mod:`bubblecal.sim.tiers`); same grids and conventions as the quasi-static tier.

* **Compression**: two analytic plates z = z_c +- g, g = h0 + gap - d/2 (h0 = max |z - z_c| of the reference
  mesh = R, ``gap`` = 1 = the LJ range: the plates just touch the reference at d = 0), acting on shell
  vertices only through the capped repulsive LJ of :class:`bubblecal.sim.protocols.PlateContact` (evaluated
  in a Warp kernel).  For each grid point the plates move symmetrically (each by half of the increment of the
  TOTAL displacement d) linearly over ``ramp_steps``, then stay for ``hold_steps``; the reaction forces on both
  plates are accumulated every step and read every ``sample_every`` steps (block means).  Observable
  F(d) = mean over the hold of (top + bottom) plate force (positive = compressive; the SUM of both plates,
  :data:`bubblecal.sim.tiers.DISPLACEMENT_CONVENTION`).  The bubble's centre-of-mass velocity is pinned.
* **Indentation**: a force -F/k (top) and +F/k (bottom) along z on each of the k loaded vertices of each pole
  (:func:`bubblecal.sim.engine.pole_patches`; default k = max(1, floor(0.01 N_v)) top-most / bottom-most
  reference vertices), ramped linearly between grid points over ``ramp_steps`` and held ``hold_steps``; centre
  of mass pinned; equator vertices (|z - z_c| < 0.25 l_min of the reference) anchored in z.  Axial extent
  H = max z - min z over the vertices, sampled every ``sample_every`` steps; observable
  d(F) = 2 R - mean(H over the last 90 % of the hold's samples), with R the mesh's nominal radius
  (``radius_dpd`` = D/0.5): the published training tables define the initial diameter as 2 * radius
  (docs/data-formats.md; :func:`bubblecal.surrogates.training.read_published`), not as the measured H(0).
* Points are chained (each starts from the previous state); a grid point equal to the previous load (the
  first point at 0) is held without a ramp.  Before the first point the system is equilibrated for
  ``equilibration_steps``.
* Status per replica: health checks after the equilibration and after every point
  (:mod:`bubblecal.sim.engine.health` for the explicit tier: non-finite, escape, inversion, rupture by area
  strain, leaks; :meth:`bubblecal.sim.engine.implicit.ImplicitShellSystem.check_health` for the implicit tier)
  mapped to :data:`bubblecal.data.names.STATUSES` by :data:`bubblecal.sim.protocols.STATUS_MAP`; a failed
  replica is frozen and its later observables are NaN.  ``max_seconds`` turns the replicas still running into
  'timeout'.

Defaults = the published protocol (40,000 ramp + 20,000 hold steps per point, samples every 400 steps,
dt = 1e-4); a ``scale`` multiplies every step count (tests and smoke runs), see :class:`ProtocolSteps`.

Anchoring in the explicit tier is done through the force: an anchored vertex gets F_z = -m (v_z +
beta (z - z_ref)/dt)/dt, which zeroes its z velocity at the next kick and pulls it back to z_ref
(beta = 0.1); the implicit system anchors natively.

Modules: :mod:`.steps` (step counts), :mod:`.protocol` (the chained protocol), :mod:`.adapters` (one interface
over the explicit and implicit systems), :mod:`.kernels` (Warp kernels).  Importing this package does not
import Warp.
"""

from bubblecal.sim.protocols.md_loading.protocol import run_md_protocol
from bubblecal.sim.protocols.md_loading.steps import ProtocolSteps, steps_per_curve

__all__ = ["ProtocolSteps", "steps_per_curve", "run_md_protocol"]
