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

from bubblecal._lazy import by_module, lazy_exports

#: Exported name -> defining module: imported on first access, so that importing the package (the CLI, the
#: configuration layers) loads no JAX; every name keeps its one import path ``from bubblecal.surrogates import X``.
_LAZY = by_module({
    "bubblecal.surrogates.acoustic": ("ACOUSTIC_FORMAT", "ACOUSTIC_FORMAT_VERSION", "AcousticFormatError",
        "AcousticRangeError", "AcousticRangeWarning", "AcousticSurrogate"),
    "bubblecal.surrogates.acoustic_law": ("ACOUSTIC_LAW_FORMAT_VERSION", "AcousticLawSurrogate"),
    "bubblecal.surrogates.axes": ("X_INFO", "Y_INFO"),
    "bubblecal.surrogates.bundle": ("BUNDLE_FORMAT", "BUNDLE_FORMAT_VERSION", "DIAMETER_ATOL_UM", "Bundle",
        "NoDefaultBundleError", "default_bundle_path", "load_bundle"),
    "bubblecal.surrogates.bundle_networks": ("DEFAULT_NETWORK", "NETWORK_ROLES"),
    "bubblecal.surrogates.bundle_validation": ("VALIDATION_FILE", "load_validation", "validation_lines"),
    "bubblecal.surrogates.bundle_write": ("write_bundle",),
    "bubblecal.surrogates.classical_resonance": ("classical_f0", "diameter_exponent"),
    "bubblecal.surrogates.features": ("DEFAULT_LOG_INPUTS", "INPUT_KINDS", "LOG_INPUT_CHOICES", "RESPONSE_SCALES",
        "check_log_inputs", "network_inputs", "radius_of_diameter", "response_scale", "x_per_size"),
    "bubblecal.surrogates.law_fit": ("compare_forms", "fit_law", "leave_diameters_out"),
    "bubblecal.surrogates.mlp": ("flops_per_point", "matmul_floor_forward", "mlp_forward", "standardised_forward",
        "xavier_uniform_weights"),
    "bubblecal.surrogates.resonance": ("DiameterFit", "fit_quadratic"),
    "bubblecal.surrogates.resonance_law": ("DEFAULT_LAW_FORM", "LAW_FORMS", "LawForm", "LawFormatError",
        "ResonanceLaw"),
    "bubblecal.surrogates.ringdown": ("RingdownFit", "damped_sine", "fit_ringdown"),
    "bubblecal.surrogates.surrogate": ("OutOfDomainError", "Surrogate", "SurrogateDomainWarning"),
    "bubblecal.surrogates.surrogate_file": ("DIAMETER_METADATA", "FORMAT", "FORMAT_VERSION",
        "FORMAT_VERSION_DIAMETER", "FORMAT_VERSION_LOG_INPUTS", "REQUIRED_METADATA", "SurrogateFormatError", "load",
        "save_surrogate"),
    "bubblecal.surrogates.synthetic_bundle": ("ACOUSTIC_GRID_UM", "ACOUSTIC_KA_RANGE", "DEPTH_CAP_RADII",
        "GAS_PRESSURE_DPD", "LOG_PARAMETERS", "RHO_SHELL_KG_M3", "SYNTHETIC_NOTE", "TRAINING_BOXES", "X_MARGIN",
        "development_bundle_path", "is_synthetic_bundle", "ringdown_frequency_MHz", "write_synthetic_bundle"),
})

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
    "mlp_forward", "standardised_forward", "matmul_floor_forward", "flops_per_point",
    "xavier_uniform_weights",
    # the SYNTHETIC development bundle
    "write_synthetic_bundle", "development_bundle_path", "is_synthetic_bundle", "SYNTHETIC_NOTE", "TRAINING_BOXES",
    "ringdown_frequency_MHz", "LOG_PARAMETERS", "X_MARGIN", "DEPTH_CAP_RADII", "GAS_PRESSURE_DPD", "RHO_SHELL_KG_M3",
    "ACOUSTIC_KA_RANGE", "ACOUSTIC_GRID_UM",
]

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
