"""Warp set-up shared by the shell checks: a quiet Warp, float64 shell fields and device positions."""

from __future__ import annotations

import numpy as np

from bubblecal._extras import require

__all__ = ["warp_quiet", "float64_field", "to_device"]


def warp_quiet():
    """Warp, with its messages off and initialised (imported on first use)."""
    wp = require("warp", "sim")

    wp.config.quiet = True
    wp.init()
    return wp


def float64_field(mesh, params, device: str, dtype=None):
    """A shell force field with one replica per parameter set on one mesh.

    Parameters
    ----------
    mesh : ShellMesh
        The shell (DPD length).
    params : ShellParams or list of ShellParams
        One parameter set per replica (DPD units).
    device : str
        Warp device.
    dtype : warp scalar type, optional
        Default ``wp.float64``.

    Returns
    -------
    ShellForceField
    """
    wp = warp_quiet()
    from bubblecal.sim.engine import ShellForceField

    return ShellForceField(mesh, params if isinstance(params, list) else [params], device=device,
                           dtype=wp.float64 if dtype is None else dtype)


def to_device(ff, x):
    """NumPy positions as a device array of the field's vector type and device.

    Parameters
    ----------
    ff : ShellForceField
        The field (its dtype and device).
    x : numpy.ndarray
        [N, 3] positions (DPD length).

    Returns
    -------
    wp.array
    """
    wp = warp_quiet()
    return wp.array(np.ascontiguousarray(x), dtype=ff.vec3, device=ff.device)
