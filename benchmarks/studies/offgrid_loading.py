"""Do the networks over the diameter hold between the loading points they were trained on?

The designs over the diameter load every curve on one grid of fractions of the diameter (compression: plate travel
0, 0.015, ..., 0.21 D), and the sweeps score a network on held-out curves at those same fractions.  A measured curve
has its own depths, so the likelihood evaluates the network between the grid's fractions too.  This study runs the
quasi-static tier (the campaign's settings) on design points of a few diameter levels with the grid refined by its
midpoints, and scores each network separately at the grid's fractions and at the midpoints: a network that wiggles
between its training fractions is accurate on the first and not on the second.

Usage::

    python benchmarks/studies/offgrid_loading.py --diameters 2.0,3.8,5.0,5.8,7.0,8.0 --n 4 \
        --surrogate surrogates/bundle/compression_1.5-8um.npz \
        --surrogate surrogates/bundle/compression_1.5-8um_fast.npz --device cpu --out offgrid.json
    python benchmarks/studies/offgrid_loading.py --curves offgrid.json --surrogate OTHER.npz    # score only
    python benchmarks/studies/offgrid_loading.py --curves offgrid.json --store-out midpoints.jsonl.gz

``--store-out`` writes the midpoint curves as a campaign store (one record per curve, the midpoints only), the file
``bubblecal surrogates train ... --offgrid FILE`` scores every architecture of a sweep on.

Prints, per network, the median and 90th percentile of the pointwise relative error |y_net - y_qs| / y_qs at the grid
fractions and at the midpoints (points from ``--from-fraction`` of the largest loading on, away from the zero
response), and one JSON line (``{"study": "offgrid_loading", ...}``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np


def refined(grid: np.ndarray) -> np.ndarray:
    """The grid with the midpoint of every interval inserted (even indices: the grid, odd: midpoints)."""
    out = np.empty(2 * len(grid) - 1)
    out[0::2] = grid
    out[1::2] = 0.5 * (grid[:-1] + grid[1:])
    return out


def simulate(campaign: str, diameters: list[float], n: int, start: int, device: str) -> list[dict]:
    """Quasi-static curves of ``n`` design points per diameter level on the refined grid."""
    from bubblecal.campaigns import design_points, load_campaign_file
    from bubblecal.data import SHELL_PARAMETERS
    from bubblecal.sim.tiers import CurveRequest, get_tier

    cfg = load_campaign_file(campaign).config
    design = design_points(cfg)
    tier = get_tier("quasistatic", **cfg.tier_settings)  # the campaign's own settings, its pool size included
    levels = []
    for d in diameters:
        idx = np.nonzero(np.isclose(design["diameter_um"], d))[0][start:start + n]
        if len(idx) == 0:
            raise SystemExit(f"{campaign}: no design point at {d} um")
        grid = refined(np.asarray(cfg.grid_for(d), dtype=float))
        params = {k: np.asarray(design[k][idx]) for k in SHELL_PARAMETERS}
        request = CurveRequest(protocol=cfg.protocol, diameter_um=d, grid=tuple(grid), params=params,
                               seeds=tuple(int(s) for s in design["seed"][idx]), subdivisions=cfg.subdivisions)
        t0 = time.perf_counter()
        batch = tier.run(request, device)
        print(f"{d:g} um: {len(idx)} curves in {time.perf_counter() - t0:.1f} s, {list(batch.status)}", flush=True)
        levels.append({"diameter_um": d, "points": idx.tolist(), "grid": grid.tolist(),
                       "seeds": [int(v) for v in design["seed"][idx]],
                       "params": {k: v.tolist() for k, v in params.items()},
                       "y": np.asarray(batch.observable, float).tolist(), "status": list(batch.status)})
    return levels


def write_store(levels: list[dict], path: Path, campaign: str, setup: str) -> None:
    """The midpoint curves (odd grid indices) as a compressed campaign store, one ``ok`` record per curve."""
    import tempfile

    from bubblecal.data import CampaignStore, export_compressed, make_record
    from bubblecal.surrogates import radius_of_diameter

    with tempfile.TemporaryDirectory() as tmp:
        store = CampaignStore.create(Path(tmp) / "offgrid.jsonl")
        for lev in levels:
            grid = np.asarray(lev["grid"])
            for k, (i, status) in enumerate(zip(lev["points"], lev["status"], strict=True)):
                if status != "ok":
                    continue
                params = {name: float(v[k]) for name, v in lev["params"].items()}
                store.append(make_record(sample_id=f"{campaign}-{i:06d}-midpoints", setup=setup, params=params,
                                         radius_dpd=float(radius_of_diameter(lev["diameter_um"])),
                                         x=grid[1::2].tolist(), y=np.asarray(lev["y"][k])[1::2].tolist(),
                                         status="ok", seed=int(lev["seeds"][k]),
                                         tier="quasistatic", provenance={"study": "offgrid_loading"}))
        export_compressed(store, path)


def score(path: str, levels: list[dict], from_fraction: float) -> dict:
    """Pointwise relative errors of one network at the grid fractions and at the midpoints."""
    from bubblecal.data import SHELL_PARAMETERS
    from bubblecal.surrogates import load

    sur = load(path)
    on, mid = [], []
    for lev in levels:
        grid = np.asarray(lev["grid"])
        ok = np.array([s == "ok" for s in lev["status"]])
        y = np.asarray(lev["y"], float)[ok]
        p = np.stack([np.asarray(lev["params"][k], float) for k in SHELL_PARAMETERS], axis=1)[ok]
        x = np.broadcast_to(grid, y.shape)
        y_hat = np.asarray(sur.at_diameter(lev["diameter_um"])(p[:, None, :], x), float)
        keep = grid >= from_fraction * grid[-1]
        with np.errstate(divide="ignore", invalid="ignore"):  # the zero response at x = 0 is never scored
            rel = np.abs(y_hat - y) / np.abs(y)
        on_grid = np.arange(len(grid)) % 2 == 0
        on.append(rel[:, on_grid & keep].ravel())
        mid.append(rel[:, ~on_grid & keep].ravel())
    on, mid = np.concatenate(on), np.concatenate(mid)
    return {"surrogate": path, "grid_median": float(np.nanmedian(on)), "grid_p90": float(np.nanpercentile(on, 90)),
            "mid_median": float(np.nanmedian(mid)), "mid_p90": float(np.nanpercentile(mid, 90)),
            "n_grid": int(np.isfinite(on).sum()), "n_mid": int(np.isfinite(mid).sum())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--campaign", default="definity_compression_1.5-8um")
    ap.add_argument("--diameters", default="2.0,3.8,5.0,5.8,7.0,8.0", help="diameter levels [um] (comma-separated)")
    ap.add_argument("--n", type=int, default=4, help="design points per level")
    ap.add_argument("--start", type=int, default=0, help="first design point of each level")
    ap.add_argument("--surrogate", action="append", default=[], help="a network over the diameter (.npz); repeatable")
    ap.add_argument("--from-fraction", type=float, default=0.2, help="score points from this fraction of the grid on")
    ap.add_argument("--curves", type=Path, default=None, help="score the curves of an earlier --out instead")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--out", type=Path, default=None, help="JSON file of the curves and scores")
    ap.add_argument("--store-out", type=Path, default=None, help="the midpoint curves as a store (.jsonl.gz)")
    args = ap.parse_args()
    if args.curves:
        levels = json.loads(args.curves.read_text())["levels"]
    else:
        levels = simulate(args.campaign, [float(v) for v in args.diameters.split(",") if v], args.n, args.start,
                          args.device)
    if args.store_out:
        from bubblecal.campaigns import load_campaign_file

        write_store(levels, args.store_out, args.campaign, load_campaign_file(args.campaign).config.protocol)
    rows = [score(s, levels, args.from_fraction) for s in args.surrogate]
    print(f"{'network':<48s} {'grid median':>11s} {'grid p90':>9s} {'mid median':>10s} {'mid p90':>8s}")
    for r in rows:
        print(f"{r['surrogate'][-48:]:<48s} {100 * r['grid_median']:10.3f}% {100 * r['grid_p90']:8.3f}% "
              f"{100 * r['mid_median']:9.3f}% {100 * r['mid_p90']:7.3f}%")
    line = {"study": "offgrid_loading", "campaign": args.campaign,
            "diameters_um": [lev["diameter_um"] for lev in levels], "from_fraction": args.from_fraction,
            "rows": rows}
    if args.out:
        args.out.write_text(json.dumps({**line, "levels": levels}))
    print(json.dumps(line))


if __name__ == "__main__":
    main()
