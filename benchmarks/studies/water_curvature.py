"""Does the explicit water's load on an offset surface explain the explicit tier's extra compression force past the
bend at large sizes?

The explicit water presses on a surface offset from the shell by its excluded layer delta, so its work is
p V_ex = p (V + delta A + delta^2 M + ...) with M the integrated mean curvature, while the back pressure works on V
alone.  The delta A part is a constant tension, balanced statically by the shell's own stress; the delta^2 M part is
tested here: the quasi-static gate (``../diameter_gate.py`` with ``--reference-curves``, the explicit curves of an
earlier GPU run) runs with an added energy ``lam * M``, lam = p delta^2 (DPD energy / length).

The term enters through the shell's Juelicher bending, whose energy 2 kb_j sum_v A_v (H_v - c0 / 2)^2 holds the
linear term -2 kb_j c0 M: a small kb_j (``--kb-j``) with c0 = -lam / (2 kb_j) gives lam M.  Its area term
kb_j c0^2 / 2 (a tension tau) is cancelled by a global area term of modulus 2 tau and reference area 2 A0 (a tension
-tau at the reference area).  Both are written into the device parameter table, on top of the Kantor bending of the
design: the study is the only place that sets both bending terms at once.

Usage::

    python benchmarks/studies/water_curvature.py --lam 94 -- --campaign definity_compression_1.5-8um \
        --diameters 7.0 --n 8 --device cpu --qs-setting minimizer=cg \
        --reference-curves benchmarks/figures/gate_diameter/curves_definity_compression_1.5-8um_7um_explicit.csv \
        --out OUT

Everything after ``--`` goes to ``diameter_gate.py``, which prints its table and JSON line.
"""

from __future__ import annotations

import argparse
import runpy
import sys
from pathlib import Path

import numpy as np

GATE = Path(__file__).resolve().parents[1] / "diameter_gate.py"


def curvature_row(row: np.ndarray, area0: float, lam: float, kb_j: float) -> np.ndarray:
    """A device parameter row with the energy ``lam * M`` added (M: integrated mean curvature, DPD length).

    Parameters
    ----------
    row : numpy.ndarray
        The replica's row of the shell parameter table (its Juelicher and global area columns unused).
    area0 : float
        The replica's reference area (DPD length^2).
    lam : float
        Coefficient of M (DPD energy / length; p delta^2 of a water at pressure p with excluded layer delta).
    kb_j : float
        Juelicher constant carrying the term (> 0, DPD energy); its own bending 2 kb_j sum A_v H_v^2 comes along.

    Returns
    -------
    numpy.ndarray
        A copy with the Juelicher constant, c0 = -lam / (2 kb_j) and, when lam != 0, the cancelling area term.

    Raises
    ------
    ValueError
        If ``kb_j`` is not positive or the row already uses the Juelicher or global area columns.
    """
    from bubblecal.sim.engine.kernels.shell.layout import P_A0TOT, P_C0, P_KATOT, P_KB_JUL

    if not kb_j > 0:
        raise ValueError(f"kb_j must be > 0, got {kb_j!r}")
    if row[P_KB_JUL] != 0 or row[P_KATOT] != 0:
        raise ValueError("the row already uses the Juelicher or the global area term")
    out = np.array(row, dtype=float, copy=True)
    c0 = -lam / (2.0 * kb_j)
    tau = kb_j * c0 * c0 / 2.0
    out[P_KB_JUL] = kb_j
    out[P_C0] = c0
    if tau > 0:
        out[P_KATOT] = 2.0 * tau
        out[P_A0TOT] = 2.0 * area0
    return out


def install(lam: float, kb_j: float) -> None:
    """Make every shell force field built from now on carry ``lam * M`` (see :func:`curvature_row`)."""
    import bubblecal.sim.engine.kernels.shell.field as field

    base = field.param_row

    def param_row(p, mesh, area0, volume0):
        return curvature_row(base(p, mesh, area0, volume0), area0, lam, kb_j)

    field.param_row = param_row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lam", type=float, required=True, help="coefficient of M, p delta^2 (DPD energy / length)")
    ap.add_argument("--kb-j", type=float, default=5.0, help="Juelicher constant carrying the term (DPD energy)")
    ap.add_argument("gate_args", nargs=argparse.REMAINDER, help="-- then the arguments of diameter_gate.py")
    args = ap.parse_args()
    install(args.lam, args.kb_j)
    rest = args.gate_args[1:] if args.gate_args[:1] == ["--"] else args.gate_args
    sys.argv = [str(GATE), *rest]
    runpy.run_path(str(GATE), run_name="__main__")


if __name__ == "__main__":
    main()
