"""The SonoVue indentation fits: quasi-static simulation vs surrogate vs data at the phase-3 posterior.

For every indentation curve of finished calibration runs (``RUN`` = an output root or a run folder
OUT/<agent>/<workflow>), the run's own plan is rebuilt from its ``manifest.json`` (the same curves and the same
surrogates: the published per-diameter networks, or a network over the diameter bound to the bubble's size), and

* the phase-3 MAP and K posterior draws are re-simulated with the quasi-static tier on the CPU, on the curve's
  force grid, with the tier settings of the campaign file that made the surrogate's training set
  (``campaigns/shipped/sonovue_indentation_<D>um_mirheo.toml`` for a per-diameter network,
  ``sonovue_indentation_1.5-8um_mirheo.toml`` for the network over the diameter); the MAP also under the other
  indentation convention (``bubblecal-v1``) and on the training set's own loading grid (interpolated at the
  data's forces: the loading path of the training curves);
* reported per curve: CRPS of the posterior predictive against the data (nm), the relative noise amplitude
  (posterior median), relative L2 of data vs predictive median, surrogate vs simulation at the MAP (and the
  median over the draws), simulation vs data, the residuals' lag-1 autocorrelation (≈ 0 for noise, → 1 for a
  systematic pattern) and the residual pattern per depth bin (data − predictive median, surrogate − simulation
  at the MAP, in nm).  Relative L2 = ||a − b||_2 / ||b||_2 over the curve's points; depths include d0.

    python benchmarks/studies/sonovue_fits.py before=/tmp/sv_before after=/tmp/sv_after [--draws 8] [--seed 0]
        [--simulate 3.2um,3.4um] [--checks convention,grid] [--figures benchmarks/figures] [--csv OUT.csv]
        [--dump ROWS.pkl] [--merge ROWS.pkl ...] [--tier explicit --device cuda --tier-setting scale=0.25]

``LABEL=RUN`` names a run in the table (default: the folder name).  Figures (with ``--figures DIR``):
``DIR/sonovue_fits_<D>um.png``, one column per run: data, 90 % predictive band, surrogate and simulation at the
MAP, simulation at the draws; below, the residuals along the curve.  Prints a table and a final JSON line.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

#: Depth bins of the residual pattern [nm].
BIN_NM = 50.0
#: Posterior draws of the predictive band and the CRPS.
PREDICTIVE_DRAWS = 2000


def rel_l2(a, b) -> float:
    """||a − b||_2 / ||b||_2 over the points where both are finite (NaN when none is)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    ok = np.isfinite(a) & np.isfinite(b)
    return float(np.linalg.norm(a[ok] - b[ok]) / np.linalg.norm(b[ok])) if ok.any() else math.nan


def lag1(r) -> float:
    """Lag-1 autocorrelation of a residual sequence (NaN for fewer than 3 finite points)."""
    r = np.asarray(r, float)
    r = r[np.isfinite(r)]
    if r.size < 3:
        return math.nan
    r = r - r.mean()
    return float(np.sum(r[1:] * r[:-1]) / np.sum(r * r))


def binned(depth_nm, values, width: float = BIN_NM) -> dict[str, float]:
    """Mean of ``values`` per depth bin ``[k w, (k + 1) w)`` nm, keyed by the bin's lower edge."""
    depth_nm, values = np.asarray(depth_nm, float), np.asarray(values, float)
    out = {}
    for k in np.unique(np.floor(depth_nm / width)):
        m = (np.floor(depth_nm / width) == k) & np.isfinite(values)
        if m.any():
            out[f"{int(k * width)}"] = round(float(values[m].mean()), 2)
    return out


def campaign_settings(surrogate, diameter_um: float) -> tuple[str, dict, tuple]:
    """(campaign name, quasi-static tier settings, training loading grid) of the set behind ``surrogate``."""
    from bubblecal.campaigns import load_campaign_file

    name = ("sonovue_indentation_1.5-8um_mirheo" if surrogate.over_diameter
            else f"sonovue_indentation_{surrogate.diameter_um:.1f}um_mirheo")
    cfg = load_campaign_file(name).config
    settings = cfg.physics_tier_settings()  # without the scheduling-only settings
    settings["subdivisions"] = cfg.subdivisions or 4
    grid = tuple(cfg.grid_for(cfg.diameter_um if cfg.diameter_um is not None else diameter_um))
    return name, settings, grid


#: The tier and device of the re-simulations (``--tier``, ``--device``); settings not of the quasi-static tier
#: keep only these keys of the campaign's (the others are FIRE settings), plus ``--tier-setting`` ones.
TIER = {"name": "quasistatic", "device": "cpu", "extra": {}}
_SHARED_SETTINGS = ("indentation_convention", "subdivisions")


def simulate(settings: dict, diameter_um: float, grid, thetas: list[dict], say) -> tuple[np.ndarray, list, float]:
    """Depths [DPD length] of parameter sets on a force grid from the tier of :data:`TIER`: ([R, P], statuses, s)."""
    from bubblecal.data import SHELL_PARAMETERS
    from bubblecal.sim.tiers import CurveRequest, get_tier

    grid = np.asarray(grid, float)
    full = grid if grid[0] == 0.0 else np.concatenate([[0.0], grid])  # the tier reports d(0) = 0 at F = 0
    req = CurveRequest(protocol="indentation", diameter_um=float(diameter_um), grid=tuple(full),
                       params={k: np.array([t[k] for t in thetas]) for k in SHELL_PARAMETERS},
                       seeds=tuple(range(len(thetas))), subdivisions=settings.get("subdivisions"))
    if TIER["name"] != "quasistatic":
        settings = {k: v for k, v in settings.items() if k in _SHARED_SETTINGS}
    t0 = time.perf_counter()
    batch = get_tier(TIER["name"], **{**settings, **TIER["extra"]}).run(req, device=TIER["device"])
    obs = np.asarray(batch.observable, float)[:, full.size - grid.size:]
    say(f"    {len(thetas)} curve(s) x {full.size} forces: {time.perf_counter() - t0:.1f} s, {list(batch.status)}")
    return obs, list(batch.status), time.perf_counter() - t0


def study_curve(ap, curve, sur, run_dir: Path, k: int, seed: int, checks: set, say) -> dict:
    """Every figure of one indentation curve of one run (module docstring); DPD inside, nm / nN out."""
    from bubblecal.data import DEFAULT_UNITS, SHELL_PARAMETERS
    from bubblecal.inference import map_index, predictive_band, predictive_crps
    from bubblecal.models import mechanical_prediction
    from bubblecal.workflows.calibrate import read_phase

    spec = ap.spec
    noise = spec.mechanical_noise_name
    path = next(p for p in (run_dir / f"phase3_{curve.name}.nc", run_dir / f"phase3_{curve.name}.npz") if p.is_file())
    result, loglik = read_phase(path)
    samples = {n: np.asarray(v, float) for n, v in result.samples.items() if np.ndim(v) == 1}
    n = next(iter(samples.values())).size
    rng = np.random.default_rng(seed)
    x, y = np.asarray(curve.x, float), np.asarray(curve.y, float)
    nm = DEFAULT_UNITS.dpd_to_nm

    thin = rng.choice(n, size=min(n, PREDICTIVE_DRAWS), replace=False)
    mu, sd = mechanical_prediction({kk: v[thin] for kk, v in samples.items()}, sur, spec, x,
                                   y_scale=float(np.max(np.abs(y))))
    mu, sd = np.asarray(mu, float), np.asarray(sd, float)
    band = predictive_band(mu, sd, 0.9)
    crps = predictive_crps(mu, sd, y, replicates=5, seed=rng)

    imap = map_index(loglik)
    picks = [int(imap), *rng.choice(n, size=k, replace=False).tolist()]
    full = [{kk: float(samples[kk][i]) if kk in samples else float(spec.fixed.get(kk, 0.0))
             for kk in (*SHELL_PARAMETERS, "d0")} for i in picks]
    d0 = np.array([t["d0"] for t in full])
    params = np.array([[t[kk] for kk in SHELL_PARAMETERS] for t in full])
    surr = np.asarray(sur(params[:, None, :], x[None, :]), float) + d0[:, None]

    campaign, settings, train_grid = campaign_settings(sur, sur.diameter_um)
    diameter = float(sur.diameter_um)
    prior = spec.noise[noise].prior.as_tuple() if hasattr(spec, "noise") else (math.nan, math.nan)
    depth = nm(y)
    out = {"curve": curve.name, "diameter_um": diameter, "campaign": campaign, "tier_settings": settings,
           "n_points": int(x.size), "crps_nm": float(nm(crps.mean)),
           "crps_mc_nm": float(nm(crps.mc_error)), "noise_median": float(np.median(samples[noise])),
           "noise_90": [float(v) for v in np.quantile(samples[noise], [0.05, 0.95])],
           "noise_prior": [float(v) for v in prior], "coverage_90": float(band.coverage(y)),
           "map": {kk: round(v, 6) for kk, v in full[0].items()},
           "rel_l2_data_vs_median": rel_l2(y, band.median), "rel_l2_surrogate_map_vs_data": rel_l2(surr[0], y),
           "lag1_data_minus_median": lag1(y - band.median),
           # the relative noise the residuals alone support (max-likelihood sigma at the median, no prior bound)
           "sigma_hat_at_median": float(np.sqrt(np.mean(((y - band.median) / band.median) ** 2))),
           "sigma_hat_at_surrogate_map": float(np.sqrt(np.mean(((y - surr[0]) / surr[0]) ** 2))),
           "pattern_data_minus_median_nm": binned(depth, nm(y - band.median))}
    arrays = {"force_nN": DEFAULT_UNITS.dpd_to_nN(x), "data_nm": depth, "median_nm": nm(band.median),
              "lower_nm": nm(band.lower), "upper_nm": nm(band.upper), "surrogate_nm": nm(surr)}
    out["_arrays"] = arrays
    if "qs" not in checks:
        return out
    say(f"  {curve.name}: {campaign} settings {settings}, D = {diameter:g} um, MAP + {k} draws")
    obs, status, secs = simulate(settings, diameter, x, full, say)
    sim = obs + d0[:, None]
    arrays["qs_nm"] = nm(sim)
    out |= {"rel_l2_surrogate_vs_qs_map": rel_l2(surr[0], sim[0]),
           "rel_l2_surrogate_vs_qs_draws_median": float(np.nanmedian([rel_l2(surr[i], sim[i])
                                                                     for i in range(1, len(full))])),
           "rel_l2_qs_map_vs_data": rel_l2(sim[0], y), "qs_status": status, "qs_seconds": round(secs, 1),
           "lag1_data_minus_qs_map": lag1(y - sim[0]), "lag1_surrogate_minus_qs_map": lag1(surr[0] - sim[0]),
           "pattern_surrogate_minus_qs_map_nm": binned(depth, nm(surr[0] - sim[0])),
           "pattern_data_minus_qs_map_nm": binned(depth, nm(y - sim[0]))}
    if "convention" in checks:
        other = {**settings, "indentation_convention": "bubblecal-v1"}
        say("    MAP in the other convention (bubblecal-v1):")
        o, _, _ = simulate(other, diameter, x, full[:1], say)
        out["rel_l2_qs_map_v1_vs_mirheo"] = rel_l2(o[0] + d0[0], sim[0])
        out["rel_l2_qs_map_v1_vs_data"] = rel_l2(o[0] + d0[0], y)
        arrays["qs_v1_nm"] = nm(o[0] + d0[0])
    if "grid" in checks:
        g = np.asarray(train_grid, float)
        inside = x <= g[-1]
        say(f"    MAP on the training grid ({g.size} forces to {g[-1]:g}):")
        t, _, _ = simulate(settings, diameter, g, full[:1], say)
        on_grid = np.interp(x[inside], g, t[0]) + d0[0]
        out["rel_l2_qs_map_training_grid_vs_data_grid"] = rel_l2(on_grid, sim[0][inside])
        out["rel_l2_surrogate_vs_qs_map_training_grid"] = rel_l2(surr[0][inside], on_grid)
        out["pattern_surrogate_minus_qs_training_grid_nm"] = binned(depth[inside], nm(surr[0][inside] - on_grid))
        sg = np.asarray(sur(params[:1, None, :], g[None, :]), float)[0]
        out["rel_l2_surrogate_vs_qs_on_training_grid_points"] = rel_l2(sg[1:], t[0][1:])
        arrays["qs_training_grid"] = (DEFAULT_UNITS.dpd_to_nN(g), nm(t[0] + d0[0]), nm(sg + d0[0]))
    return out


def fmt(v, spec=".3f") -> str:
    """A number for the table ('–' when missing)."""
    return "–" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, spec)


def main(argv=None) -> int:
    ap_ = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap_.add_argument("runs", nargs="*", help="[LABEL=]RUN: an output root or a run folder")
    ap_.add_argument("--tier", default="quasistatic", help="tier of the re-simulations (explicit: on a GPU only)")
    ap_.add_argument("--device", default="cpu", help="Warp device of the re-simulations, e.g. cuda")
    ap_.add_argument("--tier-setting", action="append", default=[], metavar="KEY=VALUE",
                     help="a tier setting on top of the campaign's (e.g. scale=0.25), repeatable")
    ap_.add_argument("--dump", type=Path, default=None, help="pickle the rows here (to --merge runs done apart)")
    ap_.add_argument("--merge", type=Path, nargs="*", default=(), help="rows pickled by --dump, shown first")
    ap_.add_argument("--draws", type=int, default=8, help="posterior draws re-simulated besides the MAP")
    ap_.add_argument("--seed", type=int, default=0)
    ap_.add_argument("--figures", type=Path, default=None, help="folder of sonovue_fits_<D>um.png")
    ap_.add_argument("--csv", type=Path, default=None, help="pointwise table")
    ap_.add_argument("--simulate", default="", help="comma-separated parts of curve names to re-simulate "
                     "(default: every indentation curve; 'none': no simulation, the statistics only)")
    ap_.add_argument("--checks", default="convention,grid", help="extra MAP simulations: convention (bubblecal-v1), "
                     "grid (the training set's loading grid); '' for none")
    args = ap_.parse_args(argv)

    from bubblecal.campaigns import parse_tier_settings
    from bubblecal.workflows.calibrate import run_plan
    from bubblecal.workflows.confirm import find_runs

    TIER.update(name=args.tier, device=args.device, extra=parse_tier_settings(args.tier_setting))

    def say(m):
        print(m, file=sys.stderr, flush=True)

    import pickle

    rows = [r for p in args.merge for r in pickle.loads(p.read_bytes())]
    for item in args.runs:
        label, _, path = item.rpartition("=")
        for run_dir in find_runs(Path(path)):
            label = label or run_dir.parent.parent.name
            say(f"{label}: {run_dir}")
            ap = run_plan(run_dir)
            for curve, sur in zip(ap.curves, ap.surrogates, strict=True):
                if curve.kind != "indentation":
                    continue
                wanted = [w for w in args.simulate.split(",") if w]
                qs = not wanted or any(w in curve.name for w in wanted)
                checks = ({"qs"} | {c for c in args.checks.split(",") if c}) if qs else set()
                r = study_curve(ap, curve, sur, run_dir, args.draws, args.seed, checks, say)
                rows.append({"label": label, "run": str(run_dir), **r})
    if args.dump:
        args.dump.write_bytes(pickle.dumps(rows))
    head = (f"{'run':<8s} {'curve':<28s} {'CRPS nm':>8s} {'sigma':>6s} {'L2 d-med':>8s} {'L2 S-QS':>8s} "
            f"{'draws':>6s} {'L2 QS-d':>8s} {'lag1 d-med':>10s} {'lag1 S-QS':>9s} {'v1-mirheo':>9s} {'trg-grid':>8s}")
    print(head)
    for r in rows:
        print(f"{r['label']:<8s} {r['curve']:<28s} {fmt(r['crps_nm'], '.2f'):>8s} {fmt(r['noise_median']):>6s} "
              f"{fmt(r['rel_l2_data_vs_median']):>8s} {fmt(r.get('rel_l2_surrogate_vs_qs_map')):>8s} "
              f"{fmt(r.get('rel_l2_surrogate_vs_qs_draws_median')):>6s} {fmt(r.get('rel_l2_qs_map_vs_data')):>8s} "
              f"{fmt(r['lag1_data_minus_median'], '.2f'):>10s} {fmt(r.get('lag1_surrogate_minus_qs_map'), '.2f'):>9s} "
              f"{fmt(r.get('rel_l2_qs_map_v1_vs_mirheo')):>9s} "
              f"{fmt(r.get('rel_l2_qs_map_training_grid_vs_data_grid')):>8s}")
    for r in rows:
        print(f"{r['label']} {r['curve']}: data - median per {BIN_NM:g} nm bin {r['pattern_data_minus_median_nm']}; "
              f"surrogate - QS {r.get('pattern_surrogate_minus_qs_map_nm', '-')}")
    if args.csv:
        _write_points(rows, args.csv)
    if args.figures:
        from sonovue_fits_figure import draw  # noqa: E402  (the study's figure, beside this script)

        for path in draw(rows, args.figures):
            say(f"figure {path} ({path.stat().st_size / 1e3:.0f} kB)")
    print(json.dumps({"study": "sonovue_fits", "draws": args.draws, "seed": args.seed,
                      "rows": [{k: v for k, v in r.items() if k != "_arrays"} for r in rows]}))
    return 0


def _write_points(rows, path: Path) -> None:
    """Pointwise table: force, data, predictive median and band, surrogate and QS at the MAP (nm, nN)."""
    import pandas as pd

    out = []
    for r in rows:
        a = r["_arrays"]
        for j, f in enumerate(a["force_nN"]):
            out.append({"label": r["label"], "curve": r["curve"], "force_nN": f, "data_nm": a["data_nm"][j],
                        "median_nm": a["median_nm"][j], "lower_nm": a["lower_nm"][j], "upper_nm": a["upper_nm"][j],
                        "surrogate_map_nm": a["surrogate_nm"][0][j],
                        "qs_map_nm": a["qs_nm"][0][j] if "qs_nm" in a else math.nan,
                        "qs_v1_map_nm": a["qs_v1_nm"][j] if "qs_v1_nm" in a else math.nan})
    pd.DataFrame(out).to_csv(path, index=False)


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    raise SystemExit(main())
