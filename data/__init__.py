"""bubblecal.data: the bottom layer — units, reference curves, acoustic observations, loaders.

Public API::

    from bubblecal.data import DEFAULT_UNITS, load_reference, reference_curves, acoustic_observations
"""

from bubblecal.data.acoustic import (
    AcousticDataset,
    AcousticObservation,
    acoustic_datasets,
    acoustic_observations,
    load_acoustic_table,
)
from bubblecal.data.curves import (
    DataError,
    LoadingCurve,
    SourceCurve,
    expected_columns,
    load_curve,
    load_reference,
    reference_curves,
    reference_names,
)
from bubblecal.data.units import DEFAULT_UNITS, UnitSystem

__all__ = [
    "DEFAULT_UNITS", "UnitSystem", "DataError", "LoadingCurve", "SourceCurve", "expected_columns",
    "load_curve", "load_reference", "reference_curves", "reference_names", "AcousticDataset",
    "AcousticObservation", "acoustic_datasets", "acoustic_observations", "load_acoustic_table",
]
