"""Is the quasi-static compression kink of large shells the equilibrium path or an artefact of the minimiser?

Design points of one diameter level of the compression design over the diameter are compressed with the
quasi-static tier's compression function (the campaign's settings: thermal plate contact, ideal gas, float64,
the campaign's mesh level) under variants of the minimisation:

* ``default``    the campaign's settings (reproduces the stored curves);
* ``selfavoid``  the shell's self-avoidance on (the MD tiers' default);
* ``smallstep``  plate sub-steps of at most 0.01 DPD length between minimisations instead of 0.06;
* ``lowinertia`` FIRE with max move 0.002 and dt_max 0.01 (less momentum to carry a shell over a barrier);
* ``noextrap``   each point starts from the last minimum instead of the linear extrapolation of the last two;
* ``step<X>``    plate sub-steps of at most X DPD length (e.g. ``step0.24``): fewer, longer minimisations.

A kink that survives every variant is the athermal equilibrium path of the shell, not the minimiser's choice.

Usage::

    python benchmarks/studies/qs_kink.py --diameter 7.0 --points 13,285 \
        --variants default,selfavoid,smallstep,lowinertia [--device cpu] [--out qs_kink.json]

Prints each variant's curves (both-plate force per load point, DPD force), the largest relative deviation from
``default`` and one JSON line (``{"study": "qs_kink", ...}``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import numpy as np

CAMPAIGN = "definity_compression_1.5-8um"
VARIANTS = ("default", "selfavoid", "smallstep", "lowinertia", "noextrap")


def run_variant(variant: str, diameter_um: float, points: list[int], device: str) -> tuple[np.ndarray, list, float]:
    """Both-plate forces [R, P] (DPD force), statuses and seconds of one variant."""
    from bubblecal.campaigns import design_points, load_campaign_file
    from bubblecal.data import SHELL_PARAMETERS
    from bubblecal.sim.engine.mesh import mesh_for_diameter
    from bubblecal.sim.engine.system import resolve_dtype
    from bubblecal.sim.tiers import CurveRequest, get_tier
    from bubblecal.sim.tiers.quasistatic import FireSettings, IdealGas, ThermalContact, quasistatic_compression

    cfg = load_campaign_file(CAMPAIGN).config
    design = design_points(cfg)
    grid = np.asarray(cfg.grid_for(diameter_um))
    tier = get_tier("quasistatic", **cfg.physics_tier_settings())
    request = CurveRequest(protocol="compression", diameter_um=diameter_um, grid=tuple(grid),
                           params={k: np.asarray(design[k][points]) for k in SHELL_PARAMETERS},
                           seeds=tuple(int(s) for s in design["seed"][points]), subdivisions=cfg.subdivisions)
    params = [dataclasses.replace(p, self_avoid=variant == "selfavoid")
              for p in request.shell_params(tier.indentation_convention)]
    fire = FireSettings(ftol=tier.ftol, max_steps=tier.max_steps)
    if variant == "lowinertia":
        fire = dataclasses.replace(fire, max_move=0.002, dt_max=0.01)
    t0 = time.perf_counter()
    res = quasistatic_compression(
        params, mesh_for_diameter(diameter_um, cfg.subdivisions or 4), grid, gas=IdealGas(p0=tier.gas_p0),
        thermal=ThermalContact(kT=tier.kT) if tier.thermal_contact else None, device=device,
        dtype=resolve_dtype(tier.dtype or "float64"), fire=fire,
        max_plate_step=plate_step(variant), extrapolate=variant != "noextrap")
    return np.asarray(res.force + res.force_bottom), list(res.status), time.perf_counter() - t0


def plate_step(variant: str) -> float:
    """Largest plate sub-step of a variant [DPD length]: 0.01 for ``smallstep``, X for ``step<X>``, else 0.06."""
    if variant == "smallstep":
        return 0.01
    step = _step_size(variant)
    return 0.06 if step is None else step


def _step_size(variant: str) -> float | None:
    """X of a ``step<X>`` variant [DPD length], None for another name; ValueError if X is not a number."""
    return float(variant[4:]) if variant.startswith("step") else None


def parse_selection(points: str, variants: str, allowed: tuple[str, ...]) -> tuple[list[int], list[str]]:
    """Comma-separated design point indices and variant names; exits naming unknown variants."""
    chosen = [v for v in variants.split(",") if v]
    bad = sorted(v for v in set(chosen) - set(allowed) if not _is_step(v))
    if bad:
        raise SystemExit(f"--variants: unknown {bad}; allowed {allowed}")
    return [int(v) for v in points.split(",") if v], chosen


def _is_step(variant: str) -> bool:
    """A ``step<X>`` variant with a number X > 0."""
    try:
        step = _step_size(variant)
    except ValueError:
        return False
    return step is not None and step > 0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--diameter", type=float, default=7.0, help="diameter level of the design [um]")
    ap.add_argument("--points", default="13,285", help="design point indices (comma-separated)")
    ap.add_argument("--variants", default="default,selfavoid,smallstep,lowinertia",
                    help=f"comma-separated, from {', '.join(VARIANTS)} or step<X>")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--out", type=Path, default=None, help="JSON file of every curve")
    args = ap.parse_args()
    points, variants = parse_selection(args.points, args.variants, VARIANTS)
    curves, rows = {}, []
    for v in variants:
        force, status, seconds = run_variant(v, args.diameter, points, args.device)
        curves[v] = force.tolist()
        dev = (float(np.nanmax(np.abs(force - curves["default"]) / np.abs(curves["default"])))
               if "default" in curves and v != "default" else None)
        rows.append({"variant": v, "status": status, "seconds": seconds, "max_rel_dev_from_default": dev})
        print(f"{v:<11s} {seconds:7.1f} s  {status}  max |F - F_default| / F_default = "
              f"{'-' if dev is None else f'{100 * dev:.2f} %'}", flush=True)
        for i, row in zip(points, force, strict=True):
            print(f"  point {i}: " + " ".join(f"{f:.0f}" for f in row), flush=True)
    line = {"study": "qs_kink", "campaign": CAMPAIGN, "diameter_um": args.diameter, "points": points, "rows": rows}
    if args.out:
        args.out.write_text(json.dumps({**line, "curves": curves}, indent=1))
    print(json.dumps(line))


if __name__ == "__main__":
    main()
