"""The calibration report: the console summary table and the one-page ``report.md`` of one agent.

Both read the tables of :mod:`bubblecal.workflows.summary`; ``report.md`` links the figures, ``summary.csv``,
``ess.csv`` and, when present, the model evidence of ``bubblecal evidence`` (``OUT/<agent>/evidence.csv``).
"""

from __future__ import annotations

import math
from pathlib import Path

from bubblecal.workflows.calibrate import phase2_samples, served_lines
from bubblecal.workflows.summary import PHYSICAL, POPULATION_ROW, bubble_rows, population_bands

__all__ = ["DETAIL_DATASETS", "summary_table", "hyperprior_bound_notes", "bubble_lines", "population_lines",
           "write_report"]

#: Up to this many datasets ``report.md`` also shows every parameter per dataset and every phase on its own row;
#: beyond, those tables are left to ``summary.csv`` and one row per phase kind.
DETAIL_DATASETS = 8


#: Most datasets the console summary lists one by one (more: the population row only).
CONSOLE_ROWS = 12


def summary_table(result):
    """The console summary of one agent: per dataset mean [5 %, 95 %] and MAP of ka (E), kb (kappa), d0 and noise,
    coverage and CRPS, in DPD and physical units.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult or bubblecal.workflows.calibrate.AgentOutcome
        A summarised run (``result.summary`` set; a worker process's outcome when agents run at once).

    Returns
    -------
    rich.table.Table
    """
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
    rows = _summary_cells(df, [k for k in params if k in df["parameter"].values], result.plan.agent, "\n")
    title = f"{result.plan.agent} ({result.plan.workflow}): posterior mean [90% interval] (MAP), DPD / physical"
    if len(rows) > CONSOLE_ROWS:  # many bubbles: the console keeps the population, the files keep every bubble
        title += f"; {len(rows) - 1} datasets in summary.csv and report.md, the population here"
        rows = [r for r in rows if r[0] == POPULATION_ROW]
    table = make_table(title, heads)
    for cells in rows:
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
        crps = f"{r0['crps']:.3g} ± {r0['crps_sd']:.2g} {r0['crps_unit']}"
        cells.append("" if not math.isfinite(r0["crps"]) else crps)
        rows.append(cells)
    return rows


def _fmt(v, digits=4) -> str:
    """``v`` to ``digits`` significant digits; '–' for None or non-finite."""
    return "–" if v is None or not math.isfinite(v) else f"{v:.{digits}g}"


def _plain(v) -> str:
    """``v`` to 3 significant digits, without an exponent between 0.01 and 10^6 (κ reads 53000, not 5.3e+04)."""
    if v is None or not math.isfinite(v):
        return "–"
    return f"{float(f'{v:.3g}'):.10g}" if 1e-2 <= abs(v) < 1e6 else f"{v:.3g}"


def _interval(row, p: str) -> str:
    """'median [q05, q95]' of parameter ``p`` in a :func:`~bubblecal.workflows.summary.bubble_rows` row."""
    key = f"{p}_median"
    if key not in row or not math.isfinite(row[key]):
        return ""
    return f"{_plain(row[key])} [{_plain(row[f'{p}_q05'])}, {_plain(row[f'{p}_q95'])}]"


def bubble_lines(result) -> list[str]:
    """The per-bubble table of ``report.md``: one markdown row per dataset, loading curves by diameter.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
        A summarised run.

    Returns
    -------
    list of str
        Header, separator and one row per dataset: bubble, D [um], E [MPa] and kappa [k_BT] as median [5 %, 95 %]
        (the columns of the sampled parameters), coverage of the 90 % band, CRPS with its unit.
    """
    rows = bubble_rows(result)
    params = [p for p in ("ka", "kb") if f"{p}_median" in rows]
    head = ["bubble", "D [µm]"] + [f"{PHYSICAL[p][1]} [{PHYSICAL[p][2]}] median [90 %]" for p in params]
    lines = ["| " + " | ".join([*head, "coverage 90 %", "CRPS"]) + " |", "|" + "---|" * (len(head) + 2)]
    for r in rows.to_dict("records"):
        crps = f"{r['crps']:.3g} {r['crps_unit']}" if math.isfinite(r["crps"]) else "–"
        cells = [r["bubble"], _fmt(r["diameter_um"], 3)] + [_interval(r, p) for p in params]
        lines.append("| " + " | ".join([*cells, _fmt(r["coverage_90"], 2), crps]) + " |")
    return lines


def population_lines(result) -> list[str]:
    """The population table of ``report.md``: per pooled parameter m, τ and the new-bubble predictive.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
        A summarised run.

    Returns
    -------
    list of str
        Header, separator and one row per pooled parameter in physical units (median [5 %, 95 %]); empty when
        nothing is pooled.
    """
    bands = population_bands(result)
    if not bands:
        return []
    lines = ["| parameter | unit | population mean m | population spread τ | new bubble (predictive) |",
             "|---|---|---|---|---|"]
    for k, b in bands.items():
        _u, pname, punit, _c = PHYSICAL.get(k, ("", k, "1", None))
        cells = [f"{_plain(b[f'{w}_median'])} [{_plain(b[f'{w}_q05'])}, {_plain(b[f'{w}_q95'])}]"
                 if f"{w}_median" in b else "–" for w in ("m", "tau", "new")]
        lines.append(f"| {k} ({pname}) | {punit} | " + " | ".join(cells) + " |")
    return lines


def _surrogates_phrase(config) -> str:
    """What the run's ``surrogates`` / ``networks`` settings asked for (the lines below it say what served)."""
    if config.data is not None:
        return f"the networks over the diameter ({config.networks}) for every bubble"
    if config.resolved_surrogates == "per-diameter":
        return "the per-diameter files and acoustic quadratics where the bundle has them (the paper's set-up)"
    return (f"the networks over the diameter ({config.networks}) and the acoustic laws where the bundle has them, "
            "else its per-diameter files")


def _data_line(ap) -> str:
    """The datasets of a run: their names, or past :data:`DETAIL_DATASETS` their count, protocols and diameters."""
    if len(ap.curves) <= DETAIL_DATASETS:
        text = ", ".join(c.name for c in ap.curves)
    else:
        kinds = {k: sum(c.kind == k for c in ap.curves) for k in dict.fromkeys(c.kind for c in ap.curves)}
        d = [float(c.bubble_diameter_um or c.diameter_um) for c in ap.curves]
        text = (f"{len(ap.curves)} loading curves (" + ", ".join(f"{k} × {n}" for k, n in kinds.items())
                + f"), diameters {min(d):.3g}–{max(d):.3g} µm")
    return text + (f"; acoustic: {', '.join(d.name for d in ap.acoustic)}" if ap.acoustic else "")


def _phase_lines(st, reused) -> list[str]:
    """Rows of the phase table: every phase, or past :data:`DETAIL_DATASETS` datasets one row per phase kind."""
    groups = {"phase1": st.phase1, "phase2": [st.phase2], "phase3": st.phase3}
    if len(st.phase1) <= DETAIL_DATASETS:
        return [f"| {r.name} | {_fmt(r.log_evidence, 6)} | {r.status}{' (reused)' if r.name in reused else ''} | "
                f"{_fmt(r.seconds, 3)} |" for rs in groups.values() for r in rs]
    lines = []
    for kind, rs in groups.items():
        if not rs:
            continue
        z = [r.log_evidence for r in rs]
        statuses = {s: sum(r.status == s for r in rs) for s in dict.fromkeys(r.status for r in rs)}
        n_reused = sum(r.name in reused for r in rs)
        status = (rs[0].status if len(rs) == 1 else ", ".join(f"{s} × {c}" for s, c in statuses.items())) + (
            f" ({n_reused} reused)" if n_reused else "")
        logz = _fmt(z[0], 6) if len(rs) == 1 else f"{_fmt(min(z), 6)} … {_fmt(max(z), 6)}"
        label = kind if len(rs) == 1 else f"{kind} ({len(rs)} runs)"
        lines.append(f"| {label} | {logz} | {status} | {_fmt(sum(r.seconds for r in rs), 3)} |")
    return lines


def hyperprior_bound_notes(hyp, spec, frac: float = 0.02) -> list[str]:
    """One line per hyperparameter whose 5 % or 95 % posterior quantile lies at a hyperprior bound.

    Parameters
    ----------
    hyp : pandas.DataFrame
        Summary rows with ``parameter`` 'm_ka', 'tau_kb', ... and quantiles ``q05``, ``q95`` (DPD units).
    spec : bubblecal.priors.PriorSpec
        The priors holding the hyperprior ranges.
    frac : float
        A quantile within ``frac`` x (hyperprior range) of a bound counts as at the bound.

    Returns
    -------
    list of str
        Human-readable notes; empty when no quantile is at a bound.
    """
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
    """Write the one-page ``report.md`` of one agent.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
        A summarised run; its ``figures`` are linked.
    plan : bubblecal.workflows.calibrate.Plan
        The run's plan (configuration, bundle).

    Returns
    -------
    Path
        ``out/<agent>/<workflow>/report.md``.
    """
    ap = result.plan
    config = plan.config
    out = ap.out_dir
    lines = [f"# Calibration report: {ap.agent}, workflow {ap.workflow}", ""]
    if plan.synthetic_bundle:
        lines += ["> **WARNING: SYNTHETIC surrogate bundle** (closed-form laws, for development/tests, not DPD). "
                  "The numbers below are NOT physical results.", ""]
    phase3 = ("published Korali phase 3: population prior over p(ψ | all data)" if config.phase3 == "published"
              else "exact phase 3: population prior over p(ψ | the other datasets), the joint model's marginal")
    phase3 += ("; tempered from each dataset's phase-1 draws" if config.phase3_start == "phase1"
               else "; tempered from the uniform prior")
    o_sampler = (f"staged TMCMC (phases 1 → 2 → 3; {phase3})" if config.sampler == "tmcmc" else
                 f"joint model, NUTS ({config.nuts_chains} chains × {config.nuts_samples} draws, "
                 f"{config.nuts_warmup} warm-up)")
    n_phase2 = phase2_samples(config, len(ap.dataset_names))
    lines += [
        "## Inputs", "",
        f"- surrogate bundle: `{plan.bundle_path}` — {plan.bundle.manifest.get('notes', '')[:200]}",
        f"- surrogates: {_surrogates_phrase(config)}",
        *[f"  - {line}" for line in served_lines(ap, plan.bundle)],
        f"- priors: `{ap.priors_path}`",
        f"- data: {_data_line(ap)}" + (f" (from `{config.data}`" + (f" and `{config.acoustic_data}`"
                                        if config.acoustic_data else "") + ")" if config.data else ""),
        *[f"- note: {n}" for n in ap.notes],
        f"- sampler: {o_sampler}; N = {config.num_particles} particles per phase, target CoV "
        f"{config.target_cov[0]} (phase 1) / {config.target_cov[1]} (phases 2, 3), covariance scaling "
        f"{config.cov_scale}, {config.num_mcmc_steps} MH steps per stage; phase 2 uses {n_phase2} "
        f"phase-1 draws per dataset; seed {config.seed}; device {config.device}",
        "",
    ]
    if ap.domain_warnings:
        lines += ["**Surrogate domain warnings** (prior box vs training box; diameters outside the range where the "
                  "training curves were checked against the explicit tier):", ""]
        lines += [f"- {w}" for w in ap.domain_warnings[:10]] + [""]
    df = result.summary
    lines += ["## Posterior summary", "",
              "Per bubble (loading curves by diameter, then acoustic datasets): posterior median [5 %, 95 %] of E "
              "(from k_a at ν = 1/2) and κ (continuum bending modulus from k_b), coverage of the 90 % predictive "
              "band and CRPS. Every parameter in DPD and physical units: [summary.csv](summary.csv).", ""]
    lines += bubble_lines(result) + [""]
    if df["dataset"].nunique() <= DETAIL_DATASETS + 2:  # + the population and hyperparameter rows
        lines += ["Every parameter: mean [5 %, 95 %] (MAP) per dataset; DPD units, physical units below.", ""]
        params = [p for p in ("ka", "kb", "d0", ap.spec.mechanical_noise_name, "sigma_ac") if p in set(df["parameter"])]
        head = ["dataset"] + [f"{p} ({PHYSICAL[p][1]} [{PHYSICAL[p][2]}])" if PHYSICAL[p][2] != "1" else p
                              for p in params] + ["coverage 90 %", "CRPS"]
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for cells in _summary_cells(df, params, None, "<br>"):
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    pop = population_lines(result)
    if pop:
        lines += ["### Population", "", "Median [5 %, 95 %] in physical units: the population mean m and spread τ "
                  "(posterior of ψ) and the parameter of a new bubble drawn from the population.", ""] + pop + [""]
    hyp = df[df["dataset"] == "hyperparameters"]
    if not hyp.empty:
        notes = hyperprior_bound_notes(hyp, ap.spec)
        if notes:
            lines += ["**Hyperparameters at a hyperprior bound** (the posterior there is set by the priors file, "
                      f"`{ap.priors_path}`, not by the data):", ""] + [f"- {n}" for n in notes] + [""]
    if result.staged is not None:
        st = result.staged
        lines += ["## Evidence and importance sampling", "",
                  "| phase | log Z | status | wall time [s] |", "|---|---|---|---|"]
        lines += _phase_lines(st, set(result.reused))
        lines += ["", "Phase-2 importance-sampling ESS per dataset (a collapse towards 1 means phase 1 did not cover "
                  "what ψ proposes): [ess.csv](ess.csv)", "",
                  "| dataset | ESS min | ESS 5 % | ESS median | median / N | Pareto k (leave-one-out weights) |",
                  "|---|---|---|---|---|---|"]
        for r in result.ess.itertuples():
            k = getattr(r, "pareto_k", math.nan)
            flag = " (> 0.7: unreliable)" if math.isfinite(k) and k > 0.7 else ""
            lines.append(f"| {r.dataset} | {r.ess_min:.1f} | {r.ess_p05:.1f} | {r.ess_median:.1f} | "
                         f"{r.ess_median_fraction:.3f} | {_fmt(k, 3)}{flag} |")
        lines.append("")
    else:
        lines += ["## NUTS diagnostics", "", f"{result.joint.diagnostics or 'reused from disk'}", ""]
        if result.joint.convergence_note:
            lines += [f"**{result.joint.convergence_note}**: run longer chains or the staged TMCMC.", ""]
    ev = out.parent / "evidence.csv"
    if ev.is_file():
        import pandas as pd

        e = pd.read_csv(ev)
        loo = "elpd_loo_full" in e.columns  # evidence.csv written before PSIS-LOO has no such columns
        lines += ["## Model evidence: full vs reduced shell (per curve)", "",
                  "| curve | ln Z full | ln Z reduced | ln B = ln Z_full − ln Z_reduced | verdict |"
                  + (" elpd_loo full | elpd_loo reduced | Pareto k > 0.7 (full, reduced) |" if loo else ""),
                  "|---|---|---|---|---|" + ("---|---|---|" if loo else "")]
        for r in e.itertuples():
            cells = (f" {r.elpd_loo_full:.2f} ± {r.elpd_loo_full_se:.2f} | {r.elpd_loo_reduced:.2f} ± "
                     f"{r.elpd_loo_reduced_se:.2f} | {r.pareto_k_bad_full}, {r.pareto_k_bad_reduced} |" if loo else "")
            lines.append(f"| {r.curve} | {r.log_z_full:.3f} ± {r.log_z_full_se:.3f} | {r.log_z_reduced:.3f} ± "
                         f"{r.log_z_reduced_se:.3f} | {r.ln_bayes_factor:.3f} ± {r.ln_bayes_factor_se:.3f} | "
                         f"{r.verdict} |" + cells)
        if "surrogate" in e.columns:  # evidence.csv written before it was recorded has no such column
            lines += ["", "Surrogates of the evidence runs: " + "; ".join(
                f"{r.curve}: {r.surrogate}" for r in e.itertuples())]
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
