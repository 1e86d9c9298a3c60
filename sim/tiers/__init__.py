"""Fidelity tiers behind one interface (docs/physics.md section 7).

A *tier* turns a batch of shell parameter sets into loading curves on one grid::

    tier = get_tier("quasistatic", subdivisions=3)
    batch = tier.run(CurveRequest(protocol="compression", diameter_um=2.1, grid=..., params=..., seeds=...))
    batch.observable  # [R, P]: F(d) for compression (DPD force), d(F) for indentation (DPD length)

Tiers, side by side: ``explicit`` (:class:`ExplicitTier`: shell + explicit water and gas, the reference),
``implicit`` (:class:`ImplicitTier`: shell + ideal-gas pressure-volume law + back pressure + Langevin
thermostat on the vertices) and ``quasistatic`` (:class:`QuasistaticTier`: athermal energy minimisation at
each load point, :mod:`bubblecal.sim.tiers.quasistatic`).  Every tier batches its R replicas into the same
kernel launches and reports one status per replica from :data:`bubblecal.data.names.STATUSES`.  The MD tiers
run the protocols of :mod:`bubblecal.sim.protocols.md_loading`.

Every tier applies the published conventions of :mod:`bubblecal.sim.tiers.conventions` (compression's
total displacement and both-plate force, the per-protocol kb scale, the indentation conventions).

Importing this package registers the three tiers and imports no Warp: a tier compiles its kernels when it runs.
"""

from bubblecal.sim.tiers.base import TIER_NAMES, CurveBatch, CurveRequest, Tier, get_tier, register_tier
from bubblecal.sim.tiers.conventions import (
    DEFAULT_INDENTATION_CONVENTION,
    DISPLACEMENT_CONVENTION,
    INDENTATION_CONVENTIONS,
    KB_KERNEL_SCALE,
    IndentationConvention,
    indentation_convention,
)
from bubblecal.sim.tiers.explicit import ExplicitTier
from bubblecal.sim.tiers.implicit import ImplicitTier
from bubblecal.sim.tiers.quasistatic import QuasistaticTier

__all__ = [
    "TIER_NAMES",
    "CurveRequest",
    "CurveBatch",
    "Tier",
    "register_tier",
    "get_tier",
    "ExplicitTier",
    "ImplicitTier",
    "QuasistaticTier",
    "DISPLACEMENT_CONVENTION",
    "KB_KERNEL_SCALE",
    "IndentationConvention",
    "INDENTATION_CONVENTIONS",
    "DEFAULT_INDENTATION_CONVENTION",
    "indentation_convention",
]
