"""The pole patches of the indentation protocol: which shell vertices carry the two opposite pole forces.

Lengths in DPD units; see docs/physics.md section 5 for the protocol.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["pole_patches"]


def pole_patches(vertices: np.ndarray, *, fraction: float | None = None,
                 cap_deg: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Vertex indices (top, bottom) that carry the indentation pole forces, each sorted by distance to its pole.

    Poles lie on the z axis through the vertices' mean.  Exactly one of ``fraction`` and ``cap_deg`` is given.
    Both patches have the same size (the callers weight every loaded vertex by 1/k).

    Parameters
    ----------
    vertices : numpy.ndarray
        [N_v, 3] reference positions (DPD length).
    fraction : float, optional
        The k = max(1, floor(fraction N_v)) top-most and bottom-most vertices by z, fraction in (0, 0.5)
        (docs/physics.md's convention).
    cap_deg : float, optional
        Every vertex within ``cap_deg`` degrees of polar angle from a pole (at least the pole-most one), in
        [0, 90): a patch of the same size on every mesh level (4.6 deg = the pole vertex and its first ring at
        subdivision 4, two rings at 5), where a vertex fraction grows a partial ring on finer meshes.

    Returns
    -------
    top, bottom : numpy.ndarray
        Vertex indices.

    Raises
    ------
    ValueError
        When both or neither selector is given, a selector is out of range, or the caps differ in size.
    """
    if (fraction is None) == (cap_deg is None):
        raise ValueError("give exactly one of fraction (loaded vertices / N_v) and cap_deg (polar cap, degrees)")
    v = np.asarray(vertices, dtype=np.float64)
    z = v[:, 2]
    if fraction is not None:
        if not (0 < fraction < 0.5):
            raise ValueError(f"fraction must lie in (0, 0.5), got {fraction!r}")
        k = max(1, int(math.floor(fraction * len(v))))
        order = np.argsort(z, kind="stable")  # stable: the published convention's vertex choice, bit for bit
        return order[::-1][:k], order[:k]
    if not (math.isfinite(cap_deg) and 0 <= cap_deg < 90):
        raise ValueError(f"cap_deg must lie in [0, 90) degrees, got {cap_deg!r}")
    u = v - v.mean(axis=0)
    cos_polar = u[:, 2] / np.linalg.norm(u, axis=1)
    cos_cap = math.cos(math.radians(cap_deg))
    out = []
    for sign in (1.0, -1.0):
        c = sign * cos_polar
        idx = np.nonzero(c >= cos_cap - 1e-12)[0]
        if idx.size == 0:  # a coarse mesh without a vertex in the cap: the pole-most vertex alone
            idx = np.array([int(np.argmax(c))])
        out.append(idx[np.argsort(-c[idx], kind="stable")])
    if len(out[0]) != len(out[1]):
        raise ValueError(f"the pole patches differ in size ({len(out[0])} top, {len(out[1])} bottom vertices)")
    return out[0], out[1]
