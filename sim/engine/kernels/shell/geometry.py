"""Warp functions of the shell's dihedral geometry, shared by the bending and diagnostic kernels.

Dihedral convention (:mod:`bubblecal.sim.engine.mesh`): edge ``(a, b)`` with the faces ``(a, b, c)`` and
``(b, a, d)``; ``theta`` is the angle between the outward normals, positive where the surface is convex.
Lengths are DPD lengths (r_c = 250 nm); angles in radians.
"""

# (no "from __future__ import annotations": Warp must see the closure types of the function signatures)

import functools

from bubblecal._extras import require

wp = require("warp", "sim")

__all__ = ["geometry_funcs"]


@functools.cache
def geometry_funcs(dtype) -> dict:
    """Build (once per scalar type) the dihedral Warp functions; ``dtype`` is ``wp.float32`` or ``wp.float64``.
    Returns a dict: ``"dihedral_terms"``: ``(xa, xb, xc, xd) -> (y, x, ga, gb, gc, gd)`` with theta = atan2(y, x)
    and the gradients of theta with respect to the four vertices [1 / DPD length]; ``"dihedral"``: ``(xa, xb, xc,
    xd) -> (theta, ga, gb, gc, gd)``.
    """
    T = dtype
    V = wp.vec3d if T is wp.float64 else wp.vec3f

    @wp.func
    def dihedral_terms(xa: V, xb: V, xc: V, xd: V):
        """(y, x) with theta = atan2(y, x), and the gradients of theta with respect to a, b, c, d (mesh.py
        convention): y = ((n1 x n2) . e) / |e|, x = n1 . n2, so sin / cos theta need no atan2."""
        e = xb - xa
        n1 = wp.cross(e, xc - xa)
        n2 = wp.cross(xd - xb, e)
        el2 = wp.dot(e, e)
        el = wp.sqrt(el2)
        n1sq = wp.max(wp.dot(n1, n1), T(1.0e-30))
        n2sq = wp.max(wp.dot(n2, n2), T(1.0e-30))
        ys = wp.dot(wp.cross(n1, n2), e) / el
        xs = wp.dot(n1, n2)
        gc = -(el / n1sq) * n1
        gd = -(el / n2sq) * n2
        sc = wp.dot(xc - xa, e) / el2
        sd = wp.dot(xd - xa, e) / el2
        one = T(1.0)
        ga = -(one - sc) * gc - (one - sd) * gd
        gb = -sc * gc - sd * gd
        return ys, xs, ga, gb, gc, gd

    @wp.func
    def dihedral(xa: V, xb: V, xc: V, xd: V):
        """theta and its gradients with respect to a, b, c, d (mesh.py convention)."""
        ys, xs, ga, gb, gc, gd = dihedral_terms(xa, xb, xc, xd)
        return wp.atan2(ys, xs), ga, gb, gc, gd

    return {"dihedral_terms": dihedral_terms, "dihedral": dihedral}
