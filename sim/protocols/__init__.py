"""bubblecal.sim.protocols: what is done to a bubble and what is measured (docs/physics.md section 5).

* loading grids (:mod:`.loading`): the published compression displacements and indentation forces;
* the compression plates' contact law (:mod:`.plates`), shared by every tier;
* the MD loading protocols of the explicit and implicit tiers (:mod:`.md_loading`);
* the ringdown protocol (:mod:`.ringdown`) and the breathing-mode PCA of its vertex trajectories (:mod:`.pca`);
* the map from the MD engines' health verdicts to replica statuses (:mod:`.health_status`).

The tiers that run these protocols live in :mod:`bubblecal.sim.tiers`.  Importing this package does not import
Warp: the MD protocols import it when they run.
"""

from bubblecal.sim.protocols.health_status import STATUS_MAP
from bubblecal.sim.protocols.loading import (
    PUBLISHED_DISPLACEMENT_STEP_DPD,
    PUBLISHED_INDENTATION_FMAX_DPD,
    PUBLISHED_N_POINTS,
    CompressionProtocol,
    IndentationProtocol,
    published_compression_protocol,
    published_indentation_protocol,
    validate_grid,
)
from bubblecal.sim.protocols.md_loading import ProtocolSteps, run_md_protocol, steps_per_curve
from bubblecal.sim.protocols.pca import (
    BreathingModePCA,
    breathing_mode_pca,
    remove_rigid_motion,
    spectral_peak,
)
from bubblecal.sim.protocols.plates import PlateContact, plate_cap_distance, plate_force_energy
from bubblecal.sim.protocols.ringdown import (
    RINGDOWN_TIERS,
    WATER_BULK_MODULUS_DPD,
    WATER_MASS_DENSITY_DPD,
    RingdownBatch,
    auto_schedule,
    breathing_mode_prediction,
    radius_from_volume,
    ringdown_batch,
)

__all__ = [
    # loading grids
    "CompressionProtocol",
    "IndentationProtocol",
    "validate_grid",
    "published_compression_protocol",
    "published_indentation_protocol",
    "PUBLISHED_DISPLACEMENT_STEP_DPD",
    "PUBLISHED_N_POINTS",
    "PUBLISHED_INDENTATION_FMAX_DPD",
    # compression plates
    "PlateContact",
    "plate_force_energy",
    "plate_cap_distance",
    # MD loading
    "ProtocolSteps",
    "steps_per_curve",
    "run_md_protocol",
    "STATUS_MAP",
    # ringdown and its PCA
    "RingdownBatch",
    "ringdown_batch",
    "breathing_mode_prediction",
    "auto_schedule",
    "radius_from_volume",
    "RINGDOWN_TIERS",
    "WATER_BULK_MODULUS_DPD",
    "WATER_MASS_DENSITY_DPD",
    "BreathingModePCA",
    "breathing_mode_pca",
    "remove_rigid_motion",
    "spectral_peak",
]
