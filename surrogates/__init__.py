"""bubblecal.surrogates: the fast maps the likelihood calls.

Calibration-side API (pure JAX/numpy; never imports torch or onnx)::

    from bubblecal.surrogates import load, load_bundle, AcousticSurrogate
    sur = load("compression_2.1um.npz")      # Surrogate: (params[..., 6], x[...]) -> y[...]
    y = sur(params, x)                       # params order ka, kb, b1, b2, a3, a4; DPD units
    mask = sur.in_training_box(params, x)    # never evaluate outside the box silently
    sur.check_domain(params, x)              # warns (or raises with action="raise")

Training side (imports torch): :mod:`.dataset` (data I/O, filtering), :mod:`.store` (campaign
store), :mod:`.train`, :mod:`.sweep`, :mod:`.export`, :mod:`.onnx_check`, :mod:`.synthetic`.
"""

from bubblecal.surrogates.acoustic import AcousticSurrogate, fit_ringdown
from bubblecal.surrogates.bundle import (
    Bundle,
    OutOfDomainError,
    Surrogate,
    SurrogateDomainWarning,
    SurrogateFormatError,
    load,
    load_bundle,
    write_bundle,
)

__all__ = ["load", "load_bundle", "write_bundle", "Surrogate", "Bundle", "SurrogateFormatError",
           "OutOfDomainError", "SurrogateDomainWarning", "AcousticSurrogate", "fit_ringdown"]
