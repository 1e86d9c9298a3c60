"""bubblecal.data: the bottom layer - units, names, curves, acoustic observations, the campaign store, files.

Every public object of the layer is imported from here, e.g.::

    from bubblecal.data import DEFAULT_UNITS, SHELL_PARAMETERS, load_reference, reference_curves

* units (:mod:`~bubblecal.data.units`): :class:`UnitSystem`, the only place that knows a conversion factor;
* names defined once (:mod:`~bubblecal.data.names`): parameters, agents, protocols, statuses, code version;
* loading curves: the types (:mod:`~bubblecal.data.curves`), the CSV reader (:mod:`~bubblecal.data.readers`)
  and the shipped reference curves (:mod:`~bubblecal.data.reference`);
* the tidy format for measured bubbles (:mod:`~bubblecal.data.tidy`, :mod:`~bubblecal.data.tidy_read`,
  :mod:`~bubblecal.data.tidy_units`) and the published study in it (:mod:`~bubblecal.data.tidy_published`);
* acoustic resonance observations (:mod:`~bubblecal.data.acoustic`);
* physical plausibility bounds of every measured quantity (:mod:`~bubblecal.data.plausibility`);
* the append-only campaign store (:mod:`~bubblecal.data.records`, :mod:`~bubblecal.data.store`);
* atomic file writes and JSON conversion (:mod:`~bubblecal.data.files`);
* the layer's errors (:mod:`~bubblecal.data.errors`).

Importing it needs NumPy only.
"""

from bubblecal.data.acoustic import (
    AcousticDataset,
    AcousticObservation,
    acoustic_datasets,
    acoustic_observations,
    load_acoustic_table,
)
from bubblecal.data.curves import KINDS, UNITS, LoadingCurve, SourceCurve, expected_columns
from bubblecal.data.errors import DataError, StoreError
from bubblecal.data.files import atomic_write, current_umask, jsonable
from bubblecal.data.names import (
    AGENTS,
    LOADING_PROTOCOLS,
    MODEL_PARAMETERS,
    NOISE_PARAMETERS,
    NONLINEAR_PARAMETERS,
    PARAMETER_UNITS,
    POSITIVE_PARAMETERS,
    PROTOCOLS,
    PUBLISHED_AGENT_OF_PROTOCOL,
    RECORD_STATUSES,
    RETRY_STATUSES,
    SHELL_PARAMETERS,
    STATUSES,
    code_version,
)
from bubblecal.data.plausibility import PLAUSIBLE_RANGES, PlausibleRange, plausibility_problems
from bubblecal.data.readers import MIN_POINTS, RETAINED_COLUMN, load_curve, read_csv_rows, separator_hint
from bubblecal.data.records import RECORD_VERSION, REQUIRED_FIELDS, make_record, validate_record
from bubblecal.data.reference import (
    REFERENCE_CURVES,
    load_reference,
    reference_curves,
    reference_names,
    resolve_reference_name,
)
from bubblecal.data.store import STORE_FORMAT, STORE_FORMAT_VERSION, CampaignStore, export_compressed
from bubblecal.data.tidy import (
    CURVE_COLUMNS,
    CURVE_OPTIONAL,
    RESONANCE_COLUMNS,
    RESONANCE_OPTIONAL,
    BubbleCurve,
    BubbleCurveSet,
    ResonanceSet,
    TidyDataError,
)
from bubblecal.data.tidy_published import (
    PUBLISHED_CURVES_FILE,
    PUBLISHED_RESONANCE_FILE,
    published_tidy_paths,
    write_published_tidy,
)
from bubblecal.data.tidy_read import check_consistency, read_bubble_curves, read_resonance, tidy_kind
from bubblecal.data.units import DEFAULT_UNITS, K_BOLTZMANN, UnitSystem, radius_dpd_from_diameter_um

__all__ = [
    # units
    "DEFAULT_UNITS", "K_BOLTZMANN", "UnitSystem", "radius_dpd_from_diameter_um",
    # names
    "SHELL_PARAMETERS", "NONLINEAR_PARAMETERS", "MODEL_PARAMETERS", "NOISE_PARAMETERS", "PARAMETER_UNITS",
    "POSITIVE_PARAMETERS", "AGENTS", "LOADING_PROTOCOLS", "PROTOCOLS", "PUBLISHED_AGENT_OF_PROTOCOL", "STATUSES",
    "RECORD_STATUSES", "RETRY_STATUSES", "code_version",
    # errors
    "DataError", "StoreError",
    # loading curves
    "KINDS", "UNITS", "LoadingCurve", "SourceCurve", "expected_columns", "RETAINED_COLUMN", "MIN_POINTS",
    "load_curve", "read_csv_rows", "separator_hint", "REFERENCE_CURVES", "reference_names", "resolve_reference_name",
    "load_reference",
    "reference_curves",
    # the tidy format for measured bubbles
    "CURVE_COLUMNS", "CURVE_OPTIONAL", "RESONANCE_COLUMNS", "RESONANCE_OPTIONAL", "TidyDataError", "BubbleCurve",
    "BubbleCurveSet", "ResonanceSet", "read_bubble_curves", "read_resonance", "check_consistency", "tidy_kind",
    "PUBLISHED_CURVES_FILE", "PUBLISHED_RESONANCE_FILE", "published_tidy_paths", "write_published_tidy",
    # plausibility bounds of measured quantities
    "PLAUSIBLE_RANGES", "PlausibleRange", "plausibility_problems",
    # acoustic observations
    "AcousticObservation", "AcousticDataset", "acoustic_observations", "acoustic_datasets", "load_acoustic_table",
    # campaign store
    "RECORD_VERSION", "REQUIRED_FIELDS", "make_record", "validate_record", "STORE_FORMAT", "STORE_FORMAT_VERSION",
    "CampaignStore", "export_compressed",
    # files
    "atomic_write", "current_umask", "jsonable",
]
