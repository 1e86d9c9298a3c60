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

from bubblecal._lazy import lazy_exports

#: Exported name -> defining module: imported on first access, so that importing the package (the CLI, the
#: configuration layers) loads no JAX; every name keeps its one import path ``from bubblecal.surrogates import X``.
_LAZY = {
    "ACOUSTIC_FORMAT": "bubblecal.surrogates.acoustic", "ACOUSTIC_FORMAT_VERSION": "bubblecal.surrogates.acoustic",
    "AcousticFormatError": "bubblecal.surrogates.acoustic", "AcousticRangeError": "bubblecal.surrogates.acoustic",
    "AcousticRangeWarning": "bubblecal.surrogates.acoustic", "AcousticSurrogate": "bubblecal.surrogates.acoustic",
    "ACOUSTIC_LAW_FORMAT_VERSION": "bubblecal.surrogates.acoustic_law",
    "AcousticLawSurrogate": "bubblecal.surrogates.acoustic_law", "X_INFO": "bubblecal.surrogates.axes",
    "Y_INFO": "bubblecal.surrogates.axes", "BUNDLE_FORMAT": "bubblecal.surrogates.bundle",
    "BUNDLE_FORMAT_VERSION": "bubblecal.surrogates.bundle", "DIAMETER_ATOL_UM": "bubblecal.surrogates.bundle",
    "Bundle": "bubblecal.surrogates.bundle", "NoDefaultBundleError": "bubblecal.surrogates.bundle",
    "default_bundle_path": "bubblecal.surrogates.bundle", "load_bundle": "bubblecal.surrogates.bundle",
    "DEFAULT_NETWORK": "bubblecal.surrogates.bundle_networks",
    "NETWORK_ROLES": "bubblecal.surrogates.bundle_networks",
    "VALIDATION_FILE": "bubblecal.surrogates.bundle_validation",
    "load_validation": "bubblecal.surrogates.bundle_validation",
    "validation_lines": "bubblecal.surrogates.bundle_validation",
    "write_bundle": "bubblecal.surrogates.bundle_write", "classical_f0": "bubblecal.surrogates.classical_resonance",
    "diameter_exponent": "bubblecal.surrogates.classical_resonance",
    "DEFAULT_LOG_INPUTS": "bubblecal.surrogates.features", "INPUT_KINDS": "bubblecal.surrogates.features",
    "LOG_INPUT_CHOICES": "bubblecal.surrogates.features", "RESPONSE_SCALES": "bubblecal.surrogates.features",
    "check_log_inputs": "bubblecal.surrogates.features", "network_inputs": "bubblecal.surrogates.features",
    "radius_of_diameter": "bubblecal.surrogates.features", "response_scale": "bubblecal.surrogates.features",
    "x_per_size": "bubblecal.surrogates.features", "compare_forms": "bubblecal.surrogates.law_fit",
    "fit_law": "bubblecal.surrogates.law_fit", "leave_diameters_out": "bubblecal.surrogates.law_fit",
    "flops_per_point": "bubblecal.surrogates.mlp", "matmul_floor_forward": "bubblecal.surrogates.mlp",
    "mlp_forward": "bubblecal.surrogates.mlp", "standardised_forward": "bubblecal.surrogates.mlp",
    "surrogate_inputs": "bubblecal.surrogates.mlp", "xavier_uniform_weights": "bubblecal.surrogates.mlp",
    "DiameterFit": "bubblecal.surrogates.resonance", "fit_quadratic": "bubblecal.surrogates.resonance",
    "DEFAULT_LAW_FORM": "bubblecal.surrogates.resonance_law", "LAW_FORMS": "bubblecal.surrogates.resonance_law",
    "LawForm": "bubblecal.surrogates.resonance_law", "LawFormatError": "bubblecal.surrogates.resonance_law",
    "ResonanceLaw": "bubblecal.surrogates.resonance_law", "RingdownFit": "bubblecal.surrogates.ringdown",
    "damped_sine": "bubblecal.surrogates.ringdown", "fit_ringdown": "bubblecal.surrogates.ringdown",
    "OutOfDomainError": "bubblecal.surrogates.surrogate", "Surrogate": "bubblecal.surrogates.surrogate",
    "SurrogateDomainWarning": "bubblecal.surrogates.surrogate",
    "DIAMETER_METADATA": "bubblecal.surrogates.surrogate_file", "FORMAT": "bubblecal.surrogates.surrogate_file",
    "FORMAT_VERSION": "bubblecal.surrogates.surrogate_file",
    "FORMAT_VERSION_DIAMETER": "bubblecal.surrogates.surrogate_file",
    "FORMAT_VERSION_LOG_INPUTS": "bubblecal.surrogates.surrogate_file",
    "REQUIRED_METADATA": "bubblecal.surrogates.surrogate_file",
    "SurrogateFormatError": "bubblecal.surrogates.surrogate_file", "load": "bubblecal.surrogates.surrogate_file",
    "save_surrogate": "bubblecal.surrogates.surrogate_file",
    "ACOUSTIC_GRID_UM": "bubblecal.surrogates.synthetic_bundle",
    "ACOUSTIC_KA_RANGE": "bubblecal.surrogates.synthetic_bundle",
    "DEPTH_CAP_RADII": "bubblecal.surrogates.synthetic_bundle",
    "GAS_PRESSURE_DPD": "bubblecal.surrogates.synthetic_bundle",
    "LOG_PARAMETERS": "bubblecal.surrogates.synthetic_bundle",
    "RHO_SHELL_KG_M3": "bubblecal.surrogates.synthetic_bundle",
    "SYNTHETIC_NOTE": "bubblecal.surrogates.synthetic_bundle",
    "TRAINING_BOXES": "bubblecal.surrogates.synthetic_bundle", "X_MARGIN": "bubblecal.surrogates.synthetic_bundle",
    "development_bundle_path": "bubblecal.surrogates.synthetic_bundle",
    "is_synthetic_bundle": "bubblecal.surrogates.synthetic_bundle",
    "ringdown_frequency_MHz": "bubblecal.surrogates.synthetic_bundle",
    "write_synthetic_bundle": "bubblecal.surrogates.synthetic_bundle",
}

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

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
