"""bubblecal.sim: the Warp DPD simulator of a microbubble shell (docs/physics.md).

The public face: what a user needs to run a tier or a protocol.

* Tiers (:mod:`bubblecal.sim.tiers`): ``get_tier(name, **settings).run(CurveRequest(...))`` -> :class:`CurveBatch`,
  for ``name`` in :data:`TIER_NAMES` (explicit, implicit, quasistatic), with the published conventions
  (:data:`DISPLACEMENT_CONVENTION`, :data:`KB_KERNEL_SCALE`, :data:`INDENTATION_CONVENTIONS`).
* Protocols (:mod:`bubblecal.sim.protocols`): the published loading grids, the compression plates
  (:class:`PlateContact`), the MD step counts (:class:`ProtocolSteps`), the ringdown (:func:`ringdown_batch`) and
  the breathing-mode PCA (:func:`breathing_mode_pca`).

The engine (mesh, particle systems, kernels, minimisers) is :mod:`bubblecal.sim.engine`; the physics checks are
:mod:`bubblecal.sim.validation`.  Importing this package is cheap: it neither imports Warp nor compiles
kernels; a tier or protocol does when it runs.
"""

from bubblecal.sim.protocols import (
    BreathingModePCA,
    CompressionProtocol,
    IndentationProtocol,
    PlateContact,
    ProtocolSteps,
    RingdownBatch,
    breathing_mode_pca,
    breathing_mode_prediction,
    published_compression_protocol,
    published_indentation_protocol,
    ringdown_batch,
    steps_per_curve,
)
from bubblecal.sim.tiers import (
    DEFAULT_INDENTATION_CONVENTION,
    DISPLACEMENT_CONVENTION,
    INDENTATION_CONVENTIONS,
    KB_KERNEL_SCALE,
    TIER_NAMES,
    CurveBatch,
    CurveRequest,
    ExplicitTier,
    ImplicitTier,
    IndentationConvention,
    QuasistaticTier,
    Tier,
    get_tier,
    indentation_convention,
    register_tier,
)

__all__ = [
    # tiers
    "TIER_NAMES",
    "CurveRequest",
    "CurveBatch",
    "Tier",
    "get_tier",
    "register_tier",
    "ExplicitTier",
    "ImplicitTier",
    "QuasistaticTier",
    # conventions
    "DISPLACEMENT_CONVENTION",
    "KB_KERNEL_SCALE",
    "IndentationConvention",
    "INDENTATION_CONVENTIONS",
    "DEFAULT_INDENTATION_CONVENTION",
    "indentation_convention",
    # protocols
    "CompressionProtocol",
    "IndentationProtocol",
    "published_compression_protocol",
    "published_indentation_protocol",
    "PlateContact",
    "ProtocolSteps",
    "steps_per_curve",
    "RingdownBatch",
    "ringdown_batch",
    "breathing_mode_prediction",
    "BreathingModePCA",
    "breathing_mode_pca",
]
