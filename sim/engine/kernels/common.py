"""Warp pieces shared by the engine's kernel families: the per-dtype kernel decorator and the
periodic minimum image (lengths in DPD units)."""

import functools

from bubblecal._extras import require

wp = require("warp", "sim")


def kernel_decorator(dtype, family: str):
    """``wp.kernel`` decorator for one scalar type; each (family, dtype) compiles as its own Warp module.

    Parameters
    ----------
    dtype : warp scalar type
        ``wp.float32`` or ``wp.float64``.
    family : str
        Kernel family; the Warp module is ``bubblecal_<family>_f32`` or ``_f64``.

    Returns
    -------
    callable
        The decorator (backward pass disabled).
    """
    suffix = "f64" if dtype is wp.float64 else "f32"
    return functools.partial(wp.kernel, enable_backward=False, module=f"bubblecal_{family}_{suffix}")


@wp.func
def min_image(d: wp.vec3f, L: wp.vec3f) -> wp.vec3f:
    """Minimum-image separation of ``d`` in a periodic box of edge lengths ``L`` (float32 overload).

    Parameters
    ----------
    d : wp.vec3f
        Separation (DPD length).
    L : wp.vec3f
        Box edge lengths (DPD length).

    Returns
    -------
    wp.vec3f
    """
    return wp.vec3f(d[0] - L[0] * wp.round(d[0] / L[0]),
                    d[1] - L[1] * wp.round(d[1] / L[1]),
                    d[2] - L[2] * wp.round(d[2] / L[2]))


@wp.func
def min_image(d: wp.vec3d, L: wp.vec3d) -> wp.vec3d:  # noqa: F811 (float64 overload)
    """Minimum-image separation of ``d`` in a periodic box of edge lengths ``L`` (float64 overload)."""
    return wp.vec3d(d[0] - L[0] * wp.round(d[0] / L[0]),
                    d[1] - L[1] * wp.round(d[1] / L[1]),
                    d[2] - L[2] * wp.round(d[2] / L[2]))
