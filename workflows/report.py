"""Summaries of a calibration run: per-dataset posterior tables, predictive checks, the Markdown report.

:func:`summarise_agent` fills an :class:`~bubblecal.workflows.calibrate.AgentResult` with

* ``summary`` (pandas DataFrame, written to ``summary.csv``): one row per (dataset, parameter) with the
  posterior mean, 5 % and 95 % quantiles and the MAP draw in DPD units and in physical units
  (k_a -> E [MPa] at nu = 1/2, k_b -> continuum bending modulus kappa [k_BT], d0 -> nm, Lim coefficients
  and noise amplitudes dimensionless), plus per dataset the coverage of the 90 % posterior-predictive band
  and the CRPS (Monte Carlo, ``config.crps_replicates`` replicates: mean and sd over replicates) in nN
  (compression: force), nm (indentation: depth) or MHz (acoustics); the dataset
  ``population (new bubble)`` holds the population-predictive draws of the pooled parameters;
* ``ess`` (``ess.csv``): the phase-2 importance-sampling ESS per dataset
  (:func:`bubblecal.inference.hierarchical.ess_table`);
* ``bands``: predictive medians and 90 % bands at the data and on a dense grid (for the figures).

:func:`write_report` writes the one-page ``report.md`` linking figures and tables.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from bubblecal.data import DEFAULT_UNITS

__all__ = ["PHYSICAL", "hyperprior_bound_notes", "dataset_posteriors", "summarise_agent", "summary_table", "write_report", "POPULATION_ROW"]

POPULATION_ROW = "population (new bubble)"

#: parameter -> (DPD unit, physical name, physical unit, converter DPD -> physical)
PHYSICAL = {
    "ka": ("DPD 2-D modulus", "E", "MPa", lambda v: np.asarray(DEFAULT_UNITS.ka_to_young(v)) * 1e-6),
    "kb": ("DPD energy", "kappa", "k_BT", lambda v: np.asarray(DEFAULT_UNITS.kb_to_bending_kBT(v))),
    "d0": ("DPD length", "d0", "nm", lambda v: np.asarray(DEFAULT_UNITS.dpd_to_nm(v))),
}
for _k in ("b1", "b2", "a3", "a4", "sigma", "sigma_mech", "sigma_ac"):
    PHYSICAL[_k] = ("1", _k, "1", lambda v: np.asarray(v, dtype=float))


def _y_to_physical(kind: str):
    """Converter of a curve's y (DPD) to physical units and the unit name."""
    if kind == "compression":
        return (lambda v: np.asarray(DEFAULT_UNITS.dpd_to_nN(v))), "nN"
    return (lambda v: np.asarray(DEFAULT_UNITS.dpd_to_nm(v))), "nm"


def dataset_posteriors(result) -> dict[str, dict]:
    """name -> {'kind', 'samples' (dict of (S,) arrays), 'loglik' (S,) or None, 'obj' (curve/dataset), 'surrogate'}.

    Staged runs: phase-3 draws; NUTS: the joint draws sliced per curve / acoustic dataset (the MAP then
    uses the joint total log likelihood).
    """
    ap = result.plan
    spec = ap.spec
    noise = spec.mechanical_noise_name
    out = {}
    if result.staged is not None:
        by_name = {r.name.removeprefix("phase3_"): r for r in result.staged.phase3}
        for curve, sur in zip(ap.curves, ap.surrogates, strict=True):
            r = by_name[curve.name]
            out[curve.name] = {"kind": curve.kind, "samples": dict(r.samples), "obj": curve, "surrogate": sur,
                               "loglik": result.loglik.get(f"phase3_{curve.name}")}
        for ds in ap.acoustic:
            r = by_name[ds.name]
            out[ds.name] = {"kind": "acoustic", "samples": dict(r.samples), "obj": ds, "surrogate": ap.f_res,
                            "loglik": result.loglik.get(f"phase3_{ds.name}")}
    else:
        js = result.joint.samples
        ll = result.joint.loglik
        for i, (curve, sur) in enumerate(zip(ap.curves, ap.surrogates, strict=True)):
            s = {k: np.asarray(js[k])[:, i] for k in [*spec.parameters, noise] if k in js}
            out[curve.name] = {"kind": curve.kind, "samples": s, "obj": curve, "surrogate": sur, "loglik": ll}
        for j, ds in enumerate(ap.acoustic):
            s = {"ka": np.asarray(js["ka_ac"])[:, j], "sigma_ac": np.asarray(js["sigma_ac"])[:, j]}
            out[ds.name] = {"kind": "acoustic", "samples": s, "obj": ds, "surrogate": ap.f_res, "loglik": ll}
    return out


def _psi(result) -> tuple[dict, dict]:
    if result.staged is not None:
        src = result.staged.phase2.samples
    else:
        src = result.joint.samples
    m = {k[2:]: np.asarray(v) for k, v in src.items() if k.startswith("m_")}
    tau = {k[4:]: np.asarray(v) for k, v in src.items() if k.startswith("tau_")}
    return m, tau


def _thin(samples: Mapping[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
    size = int(next(iter(samples.values())).shape[0])
    if size <= n:
        return {k: np.asarray(v) for k, v in samples.items()}
    idx = np.linspace(0, size - 1, n).round().astype(int)
    return {k: np.asarray(v)[idx] for k, v in samples.items()}


def _param_rows(base: dict, samples: Mapping[str, np.ndarray], names, map_index: int | None) -> list[dict]:
    rows = []
    for k in names:
        if k not in samples:
            continue
        v = np.asarray(samples[k], dtype=float)
        unit, pname, punit, conv = PHYSICAL.get(k, ("DPD", k, "DPD", lambda a: np.asarray(a)))
        q05, q95 = np.quantile(v, [0.05, 0.95])
        mp = float(v[map_index]) if map_index is not None else math.nan
        rows.append({**base, "parameter": k, "unit": unit, "mean": float(v.mean()), "q05": float(q05),
                     "q95": float(q95), "map": mp, "physical": pname, "physical_unit": punit,
                     "mean_phys": float(conv(v).mean()), "q05_phys": float(conv(q05)), "q95_phys": float(conv(q95)),
                     "map_phys": float(conv(mp)) if map_index is not None else math.nan})
    return rows


def summarise_agent(result, config) -> None:
    """Fill ``result.summary``, ``result.ess``, ``result.bands``, ``result.population_predictive``; write CSVs."""
    import jax
    import pandas as pd

    from bubblecal.inference import map_index, predictive_band, predictive_crps
    from bubblecal.models import acoustic_prediction, mechanical_prediction, sample_population_predictive

    ap = result.plan
    spec = ap.spec
    noise = spec.mechanical_noise_name
    rows = []
    bands = {}
    post = dataset_posteriors(result)
    rng = np.random.default_rng(config.seed)
    for name, d in post.items():
        samples, obj, kind = d["samples"], d["obj"], d["kind"]
        ll = d["loglik"]
        imap = map_index(ll) if ll is not None and np.size(ll) == next(iter(samples.values())).shape[0] else None
        thin = _thin(samples, config.predictive_samples)
        if kind == "acoustic":
            diam = np.asarray(obj.diameter_um, dtype=float)
            f = np.asarray(obj.frequency_MHz, dtype=float)
            mu, sd = acoustic_prediction(thin["ka"], thin["sigma_ac"], ap.f_res, diam, f_scale=float(np.max(f)))
            mu, sd = np.asarray(mu, dtype=float), np.asarray(sd, dtype=float)
            band = predictive_band(mu, sd, 0.9)
            crps = predictive_crps(mu, sd, f, replicates=config.crps_replicates, seed=rng)
            cov, crps_mean, crps_sd, unit = band.coverage(f), crps.mean, float(np.std(crps.replicates, ddof=1)
                                                                               if crps.replicates.size > 1 else 0.0), "MHz"
            bands[name] = {"kind": kind, "x": diam, "y": f, "median": band.median, "lower": band.lower,
                           "upper": band.upper, "sigma_mean": float(np.mean(thin["sigma_ac"]))}
            names = ["ka", "sigma_ac"]
            diameter = float(np.mean(diam)) if diam.size == 1 else math.nan
        else:
            x, y = np.asarray(obj.x, dtype=float), np.asarray(obj.y, dtype=float)
            y_scale = float(np.max(np.abs(y)))
            mu, sd = mechanical_prediction(thin, d["surrogate"], spec, x, y_scale=y_scale)
            mu, sd = np.asarray(mu, dtype=float), np.asarray(sd, dtype=float)
            band = predictive_band(mu, sd, 0.9)
            crps = predictive_crps(mu, sd, y, replicates=config.crps_replicates, seed=rng)
            conv, unit = _y_to_physical(kind)
            cov = band.coverage(y)
            crps_mean = float(conv(crps.mean))
            crps_sd = float(conv(np.std(crps.replicates, ddof=1))) if crps.replicates.size > 1 else 0.0
            grid = np.linspace(0.0 if kind == "compression" else 0.0, float(x.max()) * 1.02, 80)
            gmu, gsd = mechanical_prediction(thin, d["surrogate"], spec, grid, y_scale=y_scale)
            gband = predictive_band(np.asarray(gmu, dtype=float), np.asarray(gsd, dtype=float), 0.9)
            # the model curve itself (no observation noise): the spread of the surrogate prediction
            gmodel = np.quantile(np.asarray(gmu, dtype=float), [0.05, 0.5, 0.95], axis=0)
            bands[name] = {"kind": kind, "x": x, "y": y, "median": band.median, "lower": band.lower,
                           "upper": band.upper, "grid": grid, "grid_median": gband.median, "grid_lower": gband.lower,
                           "grid_upper": gband.upper, "grid_model": gmodel,
                           "map_curve": (np.asarray(mechanical_prediction({k: np.asarray(v)[imap:imap + 1]
                                                                           for k, v in samples.items()},
                                                                          d["surrogate"], spec, grid,
                                                                          y_scale=y_scale)[0])[0]
                                         if imap is not None else None)}
            names = [*spec.parameters, noise]
            diameter = float(obj.diameter_um)
        base = {"agent": ap.agent, "workflow": ap.workflow, "dataset": name, "kind": kind, "diameter_um": diameter,
                "n_points": int(np.size(bands[name]["y"])), "coverage_90": float(cov), "crps": float(crps_mean),
                "crps_sd": float(crps_sd), "crps_unit": unit}
        rows += _param_rows(base, samples, names, imap)
    # population predictive of a new bubble
    m, tau = _psi(result)
    pop = None
    if m:
        bounds = {k: spec.parameters[k].prior.as_tuple() for k in m}
        pop = sample_population_predictive(jax.random.PRNGKey(config.seed + 7), m, tau, bounds,
                                           config.predictive_samples)
        pop = {k: np.asarray(v) for k, v in pop.items()}
        base = {"agent": ap.agent, "workflow": ap.workflow, "dataset": POPULATION_ROW, "kind": "population",
                "diameter_um": math.nan, "n_points": 0, "coverage_90": math.nan, "crps": math.nan, "crps_sd": math.nan,
                "crps_unit": ""}
        rows += _param_rows(base, pop, list(m), None)
        hyper = {f"m_{k}": v for k, v in m.items()} | {f"tau_{k}": v for k, v in tau.items()}
        for key, v in hyper.items():
            k = key.split("_", 1)[1]
            unit, pname, punit, conv = PHYSICAL.get(k, ("DPD", k, "DPD", lambda a: np.asarray(a)))
            q05, q95 = np.quantile(v, [0.05, 0.95])
            rows.append({**base, "dataset": "hyperparameters", "kind": "psi", "parameter": key, "unit": unit,
                         "mean": float(v.mean()), "q05": float(q05), "q95": float(q95), "map": math.nan,
                         "physical": f"{key.split('_')[0]}_{pname}", "physical_unit": punit,
                         "mean_phys": float(conv(v).mean()), "q05_phys": float(conv(q05)),
                         "q95_phys": float(conv(q95)), "map_phys": math.nan})
    result.summary = pd.DataFrame(rows)
    result.bands = bands
    result.population_predictive = pop
    result.summary.to_csv(ap.out_dir / "summary.csv", index=False)
    if result.staged is not None:
        result.ess = result.staged.ess()
        result.ess.to_csv(ap.out_dir / "ess.csv", index=False)


def summary_table(result):
    """A rich Table: per dataset mean [5 %, 95 %] and MAP of ka (E), kb (kappa), d0 and noise, coverage, CRPS."""
    from bubblecal.workflows.console import make_table

    df = result.summary
    spec = result.plan.spec
    noise = spec.mechanical_noise_name
    params = [k for k in ("ka", "kb", "d0") if k in spec.parameters] + [noise, "sigma_ac"]
    heads = ["dataset"]
    for k in params:
        if k in df["parameter"].values:
            _u, pname, punit, _c = PHYSICAL[k]
            heads.append(f"{k} / {pname} [{punit}]" if punit != "1" else k)
    heads += ["coverage 90%", "CRPS"]
    table = make_table(f"{result.plan.agent} ({result.plan.workflow}): posterior mean [90% interval] (MAP), "
                       "DPD / physical", heads)
    for cells in _summary_cells(df, [k for k in params if k in df["parameter"].values], result.plan.agent, "\n"):
        table.add_row(*cells)
    return table


def _summary_cells(df, params, agent: str | None, newline: str) -> list[list[str]]:
    """Rows of cells per dataset: name, 'mean [q05, q95] (MAP)' (+ physical units after ``newline``) per
    parameter, coverage, CRPS ± sd (the printed table and report.md share them)."""
    rows = []
    for name, sub in df.groupby("dataset", sort=False):
        if name == "hyperparameters":
            continue
        cells = [name.removeprefix(f"{agent}_") if agent else name]
        for p in params:
            r = sub[sub["parameter"] == p]
            if r.empty:
                cells.append("")
                continue
            r = r.iloc[0]
            mp = f" ({_fmt(r['map'])})" if math.isfinite(r["map"]) else ""
            txt = f"{_fmt(r['mean'])} [{_fmt(r['q05'])}, {_fmt(r['q95'])}]{mp}"
            if r["physical_unit"] != "1":
                mpp = f" ({_fmt(r['map_phys'], 3)})" if math.isfinite(r["map_phys"]) else ""
                txt += f"{newline}{_fmt(r['mean_phys'], 3)} [{_fmt(r['q05_phys'], 3)}, {_fmt(r['q95_phys'], 3)}]{mpp}"
            cells.append(txt)
        r0 = sub.iloc[0]
        cells.append(_fmt(r0["coverage_90"], 2))
        cells.append("" if not math.isfinite(r0["crps"]) else f"{r0['crps']:.3g} ± {r0['crps_sd']:.2g} {r0['crps_unit']}")
        rows.append(cells)
    return rows


def _fmt(v, digits=4) -> str:
    return "–" if v is None or not math.isfinite(v) else f"{v:.{digits}g}"


def hyperprior_bound_notes(hyp, spec, frac: float = 0.02) -> list[str]:
    """One line per hyperparameter whose 5 % or 95 % posterior quantile lies within ``frac`` of the
    hyperprior range of a bound (``hyp``: summary rows with parameter 'm_ka', 'tau_kb', ... in DPD units)."""
    notes = []
    for r in hyp.itertuples():
        which, name = r.parameter.split("_", 1)
        prior = spec.parameters.get(name)
        bounds = None if prior is None else (prior.hyper_m if which == "m" else prior.hyper_tau)
        if bounds is None:
            continue
        lo, hi = bounds.as_tuple()
        tol = frac * (hi - lo)
        for q, edge, label in ((r.q05, lo, "lower"), (r.q95, hi, "upper")):
            if abs(q - edge) <= tol:
                notes.append(f"{r.parameter}: {'5' if label == 'lower' else '95'} % quantile {q:.4g} at the {label} "
                             f"hyperprior bound {edge:.4g} [DPD] (range [{lo:.4g}, {hi:.4g}])")
    return notes


def write_report(result, plan) -> Path:
    """Write ``report.md`` (one page) for one agent and return its path."""
    ap = result.plan
    config = plan.config
    out = ap.out_dir
    lines = [f"# Calibration report: {ap.agent}, workflow {ap.workflow}", ""]
    if plan.synthetic_bundle:
        lines += ["> **WARNING: SYNTHETIC surrogate bundle** (closed-form laws, for development/tests, not DPD). "
                  "The numbers below are NOT physical results.", ""]
    phase3 = ("published Korali phase 3: population prior over p(ψ | all data)" if config.phase3 == "published"
              else "exact phase 3: population prior over p(ψ | the other datasets), the joint model's marginal")
    o_sampler = (f"staged TMCMC (phases 1 → 2 → 3; {phase3})" if config.sampler == "tmcmc" else
                 f"joint model, NUTS ({config.nuts_chains} chains × {config.nuts_samples} draws, "
                 f"{config.nuts_warmup} warm-up)")
    lines += [
        "## Inputs", "",
        f"- surrogate bundle: `{plan.bundle_path}` — {plan.bundle.manifest.get('notes', '')[:200]}",
        f"- priors: `{ap.priors_path}`",
        f"- data: {', '.join(c.name for c in ap.curves)}" + (f"; acoustic: {', '.join(d.name for d in ap.acoustic)}"
                                                            if ap.acoustic else ""),
        f"- sampler: {o_sampler}; N = {config.num_particles} particles per phase, target CoV "
        f"{config.target_cov[0]} (phase 1) / {config.target_cov[1]} (phases 2, 3), covariance scaling "
        f"{config.cov_scale}, {config.num_mcmc_steps} MH steps per stage; phase 2 uses {min(config.num_particles, config.phase2_samples or 2000)} "
        f"phase-1 draws per dataset; seed {config.seed}; device {config.device}",
        "",
    ]
    if ap.domain_warnings:
        lines += ["**Surrogate domain warnings** (prior box vs training box):", ""]
        lines += [f"- {w}" for w in ap.domain_warnings[:10]] + [""]
    lines += ["## Posterior summary", "",
              "Mean [5 %, 95 %] (MAP) per dataset; DPD units, physical units below (E from k_a at ν = 1/2, "
              "κ = continuum bending modulus from k_b). Full table: [summary.csv](summary.csv).", ""]
    df = result.summary
    params = [p for p in ("ka", "kb", "d0", ap.spec.mechanical_noise_name, "sigma_ac") if p in set(df["parameter"])]
    head = ["dataset"] + [f"{p} ({PHYSICAL[p][1]} [{PHYSICAL[p][2]}])" if PHYSICAL[p][2] != "1" else p
                          for p in params] + ["coverage 90 %", "CRPS"]
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for cells in _summary_cells(df, params, None, "<br>"):
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    hyp = df[df["dataset"] == "hyperparameters"]
    if not hyp.empty:
        lines += ["Population hyperparameters ψ (posterior mean [5 %, 95 %], physical units): "
                  + "; ".join(f"{r.parameter} = {r.mean_phys:.3g} [{r.q05_phys:.3g}, {r.q95_phys:.3g}] {r.physical_unit}"
                              for r in hyp.itertuples()), ""]
        notes = hyperprior_bound_notes(hyp, ap.spec)
        if notes:
            lines += ["**Hyperparameters at a hyperprior bound** (the posterior there is set by the priors file, "
                      f"`{ap.priors_path}`, not by the data):", ""] + [f"- {n}" for n in notes] + [""]
    if result.staged is not None:
        st = result.staged
        lines += ["## Evidence and importance sampling", "",
                  "| phase | log Z | status | wall time [s] |", "|---|---|---|---|"]
        for r in [*st.phase1, st.phase2, *st.phase3]:
            reused = " (reused)" if r.name in result.reused else ""
            lines.append(f"| {r.name} | {_fmt(r.log_evidence, 6)} | {r.status}{reused} | {_fmt(r.seconds, 3)} |")
        lines += ["", "Phase-2 importance-sampling ESS per dataset (a collapse towards 1 means phase 1 did not cover "
                  "what ψ proposes): [ess.csv](ess.csv)", "",
                  "| dataset | ESS min | ESS 5 % | ESS median | median / N |", "|---|---|---|---|---|"]
        for r in result.ess.itertuples():
            lines.append(f"| {r.dataset} | {r.ess_min:.1f} | {r.ess_p05:.1f} | {r.ess_median:.1f} | "
                         f"{r.ess_median_fraction:.3f} |")
        lines.append("")
    else:
        lines += ["## NUTS diagnostics", "", f"{result.joint.diagnostics or 'reused from disk'}", ""]
    ev = out.parent / "evidence.csv"
    if ev.is_file():
        import pandas as pd

        e = pd.read_csv(ev)
        lines += ["## Model evidence: full vs reduced shell (per curve)", "",
                  "| curve | ln Z full | ln Z reduced | ln B = ln Z_full − ln Z_reduced | verdict |", "|---|---|---|---|---|"]
        for r in e.itertuples():
            lines.append(f"| {r.curve} | {r.log_z_full:.3f} ± {r.log_z_full_se:.3f} | {r.log_z_reduced:.3f} ± "
                         f"{r.log_z_reduced_se:.3f} | {r.ln_bayes_factor:.3f} ± {r.ln_bayes_factor_se:.3f} | {r.verdict} |")
        lines += ["", "Source: [evidence.csv](../evidence.csv)", ""]
    if result.figures:
        lines += ["## Figures", ""]
        for f in result.figures:
            rel = f.relative_to(out)
            lines.append(f"![{f.stem}]({rel.as_posix()})")
        lines.append("")
    total = sum(v for k, v in result.seconds.items() if k.startswith(("phase", "joint")))
    lines += ["## Wall times", "", ", ".join(f"{k} {v:.1f} s" for k, v in result.seconds.items())
              + f" (phases total {total:.1f} s)", ""]
    path = out / "report.md"
    path.write_text("\n".join(lines))
    return path
