"""bubblecal.surrogates: the fast maps the likelihood calls.

Calibration-side API (pure JAX/numpy; importing this package never imports torch or onnx)::

    from bubblecal.surrogates import load, load_bundle, AcousticSurrogate
    sur = load("compression_2.1um.npz")      # Surrogate: (params[..., 6], x[...]) -> y[...]
    y = sur(params, x)                       # params order ka, kb, b1, b2, a3, a4; DPD units
    mask = sur.in_training_box(params, x)    # never evaluate outside the box silently
    sur.check_domain(params, x)              # warns (or raises with action="raise")

Modules: :mod:`~bubblecal.surrogates.mlp` (JAX forward pass), :mod:`~bubblecal.surrogates.surrogate` (the
loaded :class:`Surrogate`), :mod:`~bubblecal.surrogates.surrogate_file` (the ``.npz`` format),
:mod:`~bubblecal.surrogates.bundle` (bundles, the shipped default; written by
:mod:`~bubblecal.surrogates.bundle_write`, roles of the networks over the diameter in
:mod:`~bubblecal.surrogates.bundle_networks`), :mod:`~bubblecal.surrogates.ringdown`
(ringdown fits), :mod:`~bubblecal.surrogates.resonance` (the f_res^2(k_a) quadratic at one diameter),
:mod:`~bubblecal.surrogates.acoustic` (the acoustic surrogate over diameters),
:mod:`~bubblecal.surrogates.resonance_law` and :mod:`~bubblecal.surrogates.law_fit` (a law continuous in the
diameter, its fit and leave-diameters-out errors), :mod:`~bubblecal.surrogates.acoustic_law` (its surrogate, file
format version 2), :mod:`~bubblecal.surrogates.classical_resonance` (the classical shelled-bubble f0),
:mod:`~bubblecal.surrogates.axes`
(loading coordinate and response per protocol), :mod:`~bubblecal.surrogates.synthetic_bundle` (the SYNTHETIC
development bundle). Training (dataset I/O, filtering, torch training, sweeps, export, ONNX) lives in
:mod:`bubblecal.surrogates.training`.
"""

from bubblecal.surrogates.acoustic import (
    ACOUSTIC_FORMAT,
    ACOUSTIC_FORMAT_VERSION,
    AcousticFormatError,
    AcousticRangeError,
    AcousticRangeWarning,
    AcousticSurrogate,
)
from bubblecal.surrogates.acoustic_law import ACOUSTIC_LAW_FORMAT_VERSION, AcousticLawSurrogate
from bubblecal.surrogates.axes import X_INFO, Y_INFO
from bubblecal.surrogates.bundle import (
    BUNDLE_FORMAT,
    BUNDLE_FORMAT_VERSION,
    DIAMETER_ATOL_UM,
    Bundle,
    NoDefaultBundleError,
    default_bundle_path,
    load_bundle,
)
from bubblecal.surrogates.bundle_networks import DEFAULT_NETWORK, NETWORK_ROLES
from bubblecal.surrogates.bundle_validation import VALIDATION_FILE, load_validation, validation_lines
from bubblecal.surrogates.bundle_write import write_bundle
from bubblecal.surrogates.classical_resonance import classical_f0, diameter_exponent
from bubblecal.surrogates.features import (
    DEFAULT_LOG_INPUTS,
    INPUT_KINDS,
    LOG_INPUT_CHOICES,
    RESPONSE_SCALES,
    check_log_inputs,
    network_inputs,
    radius_of_diameter,
    response_scale,
    x_per_size,
)
from bubblecal.surrogates.law_fit import compare_forms, fit_law, leave_diameters_out
from bubblecal.surrogates.mlp import (
    flops_per_point,
    matmul_floor_forward,
    mlp_forward,
    standardised_forward,
    surrogate_inputs,
    xavier_uniform_weights,
)
from bubblecal.surrogates.resonance import DiameterFit, fit_quadratic
from bubblecal.surrogates.resonance_law import DEFAULT_LAW_FORM, LAW_FORMS, LawForm, LawFormatError, ResonanceLaw
from bubblecal.surrogates.ringdown import RingdownFit, damped_sine, fit_ringdown
from bubblecal.surrogates.surrogate import OutOfDomainError, Surrogate, SurrogateDomainWarning
from bubblecal.surrogates.surrogate_file import (
    DIAMETER_METADATA,
    FORMAT,
    FORMAT_VERSION,
    FORMAT_VERSION_DIAMETER,
    FORMAT_VERSION_LOG_INPUTS,
    REQUIRED_METADATA,
    SurrogateFormatError,
    load,
    save_surrogate,
)
from bubblecal.surrogates.synthetic_bundle import (
    ACOUSTIC_GRID_UM,
    ACOUSTIC_KA_RANGE,
    DEPTH_CAP_RADII,
    GAS_PRESSURE_DPD,
    LOG_PARAMETERS,
    RHO_SHELL_KG_M3,
    SYNTHETIC_NOTE,
    TRAINING_BOXES,
    X_MARGIN,
    development_bundle_path,
    is_synthetic_bundle,
    ringdown_frequency_MHz,
    write_synthetic_bundle,
)

__all__ = [
    # mechanical surrogates and their files
    "Surrogate", "load", "save_surrogate", "SurrogateFormatError", "OutOfDomainError", "SurrogateDomainWarning",
    "FORMAT", "FORMAT_VERSION", "FORMAT_VERSION_DIAMETER", "FORMAT_VERSION_LOG_INPUTS", "REQUIRED_METADATA",
    "DIAMETER_METADATA", "X_INFO", "Y_INFO",
    # network inputs: per diameter or over the diameter
    "INPUT_KINDS", "RESPONSE_SCALES", "network_inputs", "response_scale", "x_per_size", "radius_of_diameter",
    "LOG_INPUT_CHOICES", "DEFAULT_LOG_INPUTS", "check_log_inputs",
    # bundles
    "Bundle", "load_bundle", "write_bundle", "default_bundle_path", "NoDefaultBundleError", "BUNDLE_FORMAT",
    "BUNDLE_FORMAT_VERSION", "DIAMETER_ATOL_UM", "NETWORK_ROLES", "DEFAULT_NETWORK", "VALIDATION_FILE",
    "load_validation", "validation_lines",
    # acoustics
    "AcousticSurrogate", "DiameterFit", "fit_quadratic", "AcousticFormatError", "AcousticRangeError",
    "AcousticRangeWarning", "ACOUSTIC_FORMAT", "ACOUSTIC_FORMAT_VERSION", "fit_ringdown", "RingdownFit",
    "damped_sine",
    # the acoustic law continuous in the diameter, and the classical baseline
    "AcousticLawSurrogate", "ACOUSTIC_LAW_FORMAT_VERSION", "ResonanceLaw", "LawForm", "LAW_FORMS", "DEFAULT_LAW_FORM",
    "LawFormatError", "fit_law", "leave_diameters_out", "compare_forms", "classical_f0", "diameter_exponent",
    # the JAX forward pass
    "surrogate_inputs", "mlp_forward", "standardised_forward", "matmul_floor_forward", "flops_per_point",
    "xavier_uniform_weights",
    # the SYNTHETIC development bundle
    "write_synthetic_bundle", "development_bundle_path", "is_synthetic_bundle", "SYNTHETIC_NOTE", "TRAINING_BOXES",
    "ringdown_frequency_MHz", "LOG_PARAMETERS", "X_MARGIN", "DEPTH_CAP_RADII", "GAS_PRESSURE_DPD", "RHO_SHELL_KG_M3",
    "ACOUSTIC_KA_RANGE", "ACOUSTIC_GRID_UM",
]
