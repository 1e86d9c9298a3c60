"""How much of the explicit tier's extra compression force past the buckling point do its pressures explain?

The explicit tier balances its water (DPD a = 100, number density 3) with a constant back pressure p_b = 91 plus
the enclosed ideal gas (p0 = 3): p_b + p0 = 94, whereas the water's measured equation of state gives 89.05
(docs/physics.md, check 1).  Its shell therefore starts with a net outward pressure of 4.95 (a membrane
pre-tension σ = Δp R / 2), which the quasi-static and implicit tiers, balanced by construction, do not have.  Its
water also fills a closed periodic box, so a shrinking bubble lowers the water pressure: a volume stiffness
K / V_water (K = ρ dp/dρ ≈ 175 from the same equation of state) beside the gas's p0 / V0.

For design points of one level of a design over the diameter (``--campaign``: compression by default, or the
indentation design, whose pole forces also shrink the bubble) this script runs

* ``balanced``     the quasi-static tier as the campaign ran it;
* ``overpressure`` the same with the explicit tier's reference imbalance (tier setting ``overpressure``);
* ``reservoir``    the same with the gas made as stiff as gas plus the explicit box's water (an ideal gas of
                   p0' = p0 + K V0 / V_water, balanced; the linear stiffness at the reference);
* ``both``         overpressure and reservoir;
* ``implicit``     the implicit tier (thermal, solvent-free) with the water pressure of the explicit tier's
                   equation of state (``p_water`` = 89.05), MD protocol scale ``--scale``;

and compares each curve with the explicit tier's stored gate curve (relative L2 = ||y - y_explicit|| /
||y_explicit||, the gate's measure).

Usage::

    python benchmarks/studies/reference_pressure.py --diameter 7.0 --points 13 \\
        --explicit benchmarks/figures/gate_diameter/curves_definity_compression_1.5-8um_7um_explicit.csv \\
        [--variants balanced,overpressure,reservoir,both,implicit] [--device cpu]
    python benchmarks/studies/reference_pressure.py --campaign sonovue_indentation_1.5-8um_mirheo --diameter 7.0 \\
        --points 8,22 --explicit benchmarks/figures/gate_diameter/curves_sonovue_indentation_1.5-8um_mirheo_7um.csv \\
        --variants balanced,reservoir

Prints one line per variant and point and one JSON line (``{"study": "reference_pressure", ...}``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from qs_kink import parse_selection  # the studies' folder is the script's (sys.path[0])

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for diameter_gate.py
from diameter_gate import stored_reference  # noqa: E402  (benchmark script)

CAMPAIGN = "definity_compression_1.5-8um"
VARIANTS = ("balanced", "overpressure", "reservoir", "both", "implicit")
#: DPD water at a = 100, number density 3, k_BT = 1: measured pressure (docs/physics.md, check 1)
P_WATER = 89.05
RHO_WATER = 3.0
P_BACK, P_GAS = 91.0, 3.0


def water_bulk_modulus(p: float = P_WATER, rho: float = RHO_WATER, kT: float = 1.0) -> float:
    """K = ρ dp/dρ of a DPD fluid p = ρ kT + α a ρ² (DPD pressure), from its pressure at ρ."""
    return rho * kT + 2.0 * (p - rho * kT)


def explicit_box(radius: float) -> tuple[float, float, float]:
    """The explicit tier's default periodic box (2R + 5, 2R + 5, 2R + 10) (DPD length)."""
    return (2 * radius + 5, 2 * radius + 5, 2 * radius + 10)


def run_variant(variant: str, diameter_um: float, points: list[int], device: str, scale: float,
                campaign: str = CAMPAIGN) -> np.ndarray:
    """The observable [R, P] of one variant: both-plate forces (DPD force) or indentation depths (DPD length)."""
    from bubblecal.campaigns import design_points, load_campaign_file
    from bubblecal.data import SHELL_PARAMETERS
    from bubblecal.sim.engine import mesh_for_diameter
    from bubblecal.sim.tiers import CurveRequest, get_tier

    cfg = load_campaign_file(campaign).config
    design = design_points(cfg)
    request = CurveRequest(protocol=cfg.protocol, diameter_um=diameter_um, grid=tuple(cfg.grid_for(diameter_um)),
                           params={k: np.asarray(design[k][points]) for k in SHELL_PARAMETERS},
                           seeds=tuple(int(s) for s in design["seed"][points]), subdivisions=cfg.subdivisions)
    if variant == "implicit":
        conv = cfg.tier_settings.get("indentation_convention")
        tier = get_tier("implicit", scale=scale, p_water=P_WATER, **({"indentation_convention": conv} if conv else {}))
        return np.asarray(tier.run(request, device).observable, dtype=float)
    settings = cfg.physics_tier_settings()
    if variant in ("overpressure", "both"):
        settings["overpressure"] = P_BACK + P_GAS - P_WATER
    if variant in ("reservoir", "both"):
        mesh = mesh_for_diameter(diameter_um, cfg.subdivisions or 4)
        v0 = mesh.volume()
        water = math.prod(explicit_box(mesh.radius_dpd)) - v0
        settings["gas_p0"] = P_GAS + water_bulk_modulus() * v0 / water
    return np.asarray(get_tier("quasistatic", **settings).run(request, device).observable, dtype=float)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--campaign", default=CAMPAIGN, help="shipped campaign over the diameter")
    ap.add_argument("--diameter", type=float, default=7.0, help="diameter level of the design [um]")
    ap.add_argument("--points", default="13", help="design point indices (comma-separated)")
    ap.add_argument("--explicit", required=True, help="the explicit tier's gate curves of the level (CSV)")
    ap.add_argument("--variants", default=",".join(VARIANTS), help=f"comma-separated, from {', '.join(VARIANTS)}")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--scale", type=float, default=0.25, help="MD protocol scale of the implicit variant")
    args = ap.parse_args()
    points, variants = parse_selection(args.points, args.variants, VARIANTS)
    from bubblecal.campaigns import load_campaign_file

    n_points = len(load_campaign_file(args.campaign).config.grid_for(args.diameter))
    explicit = dict(zip(points, stored_reference(args.explicit, points, n_points)["y"], strict=True))
    rows, curves = [], {}
    for v in variants:
        t0 = time.perf_counter()
        force = run_variant(v, args.diameter, points, args.device, args.scale, args.campaign)
        seconds = time.perf_counter() - t0
        curves[v] = force.tolist()
        for i, y in zip(points, force, strict=True):
            ref = explicit[i]
            rel = float(np.linalg.norm(y - ref) / np.linalg.norm(ref))
            rows.append({"variant": v, "point": i, "rel_l2": rel, "seconds": seconds})
            print(f"{v:<13s} point {i}: rel L2 vs explicit {100 * rel:5.1f} %  ({seconds:.0f} s)  "
                  + " ".join(f"{f:.4g}" for f in y), flush=True)
    print(json.dumps({"study": "reference_pressure", "campaign": args.campaign, "diameter_um": args.diameter,
                      "points": points, "overpressure": P_BACK + P_GAS - P_WATER,
                      "water_bulk_modulus": water_bulk_modulus(), "rows": rows, "curves": curves}))


if __name__ == "__main__":
    main()
