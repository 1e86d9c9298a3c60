"""Ringdown protocol (docs/physics.md section 5, check 7 of section 6): perturb the bubble radius, record R(t).

After equilibration every replica's shell is scaled radially by ``1 + perturbation`` about its
centroid and the free oscillation of R(t) = (3 V / 4 pi)^(1/3) (V: enclosed volume of the mesh, DPD
length^3) is recorded.  The fit R0 + c t + exp(-lam t)[A sin w_d t + B cos w_d t] lives in
:mod:`bubblecal.surrogates.acoustic` (``sim`` may not import ``surrogates``): the sweep pipeline
:mod:`bubblecal.workflows.acoustic_sweep` does the fitting and the unit conversion.

Mass scaling: the shell vertex mass is multiplied by ``mass_factor`` (160 in the published sweeps) so
that the breathing mode is slow and clean; a frequency converts back with f = f_dpd sqrt(mass_factor)
(:meth:`bubblecal.data.units.UnitSystem.frequency_to_physical`).  f ~ M^(-1/2) holds exactly only if
the shell's own inertia is the only one: :func:`breathing_mode_prediction` gives both the check-7
value (shell mass only) and an estimate with the water's added mass (explicit tier).

Tiers
-----
``explicit``: :class:`bubblecal.sim.engine.system.ParticleSystem` replicas
(:func:`bubblecal.sim.engine.bubble_spec`: shell + explicit water and ideal gas, bounce-back), R replicas
in the same launches.  The perturbation is a homothety about the shell's centroid with factor
1 + perturbation applied to the shell vertices, the gas inside (so its density follows the volume: p V stays
the isothermal N k_BT) and the water out to the largest vertex distance R_a; beyond it the water's radial
shift decays linearly to zero over ``water_layer`` (default 2 DPD lengths).  A homothety maps inside to inside
and outside to outside exactly, and the radial map is monotone (shift slope > -1), so no particle changes side,
no particle order is swapped, and nothing needs deleting; the price is a water density excess of
~ perturbation R_a / water_layer in that layer, which leaves as a pressure pulse.  Velocities are kept.

``implicit``: :class:`bubblecal.sim.engine.implicit.ImplicitShellSystem` (shell + ideal-gas pressure-volume
law + back and ambient pressure + vertex thermostat).  Only the vertices are scaled; the gas law follows
the volume by construction.

Status per replica is one of :data:`bubblecal.data.names.STATUSES` (explicit: from
:class:`bubblecal.sim.engine.health.HealthMonitor`, mapped by :data:`bubblecal.sim.protocols.STATUS_MAP`).

Modules: :mod:`.batch` (the front end :func:`ringdown_batch`), :mod:`.result` (:class:`RingdownBatch`),
:mod:`.prediction` (check 7 and the schedule), :mod:`.recording` (shared run steps), :mod:`.explicit` and
:mod:`.implicit` (the two runners).  Importing this package does not import Warp.
"""

from bubblecal.sim.protocols.ringdown.batch import RINGDOWN_TIERS, ringdown_batch
from bubblecal.sim.protocols.ringdown.prediction import (
    WATER_BULK_MODULUS_DPD,
    WATER_MASS_DENSITY_DPD,
    auto_schedule,
    breathing_mode_prediction,
)
from bubblecal.sim.protocols.ringdown.recording import radius_from_volume
from bubblecal.sim.protocols.ringdown.result import RingdownBatch

__all__ = [
    "RingdownBatch",
    "ringdown_batch",
    "breathing_mode_prediction",
    "auto_schedule",
    "radius_from_volume",
    "RINGDOWN_TIERS",
    "WATER_BULK_MODULUS_DPD",
    "WATER_MASS_DENSITY_DPD",
]
