"""Summaries of a calibration run: per-dataset posterior tables and predictive checks.

:func:`summarise_agent` fills an :class:`~bubblecal.workflows.calibrate.AgentResult` with

* ``summary`` (pandas DataFrame, written to ``summary.csv``): one row per (dataset, parameter) with the
  posterior mean, 5 % and 95 % quantiles and the MAP draw in DPD units and in physical units
  (k_a -> E [MPa] at nu = 1/2, k_b -> continuum bending modulus kappa [k_BT], d0 -> nm, Lim coefficients
  and noise amplitudes dimensionless), plus per dataset the coverage of the 90 % posterior-predictive band
  and the CRPS (Monte Carlo, ``config.crps_replicates`` replicates: mean and sd over replicates) in nN
  (compression: force), nm (indentation: depth) or MHz (acoustics) (``docs/inference.md`` section 7); the
  dataset ``population (new bubble)`` holds the population-predictive draws of the pooled parameters;
* ``ess`` (``ess.csv``): the phase-2 importance-sampling ESS per dataset
  (:func:`bubblecal.inference.phase_results.ess_table`) and ``pareto_k``, the PSIS Pareto k̂ of the dataset's
  leave-one-out importance weights 1 / L_i(ψ) over the phase-2 draws (:func:`bubblecal.workflows.calibrate.
  phase2_pareto_k`; above 0.7 the leave-one-out estimate, and phase 3 exact, is unreliable for that dataset);
* ``bands``: predictive medians and 90 % bands at the data and on a dense grid (for the figures).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from bubblecal.data import DEFAULT_UNITS, NOISE_PARAMETERS, NONLINEAR_PARAMETERS
from bubblecal.workflows.summary_stats import StatisticsPool

__all__ = ["PHYSICAL", "POPULATION_ROW", "BUBBLE_PARAMETERS", "dataset_posteriors", "psi_samples", "bubble_rows",
           "population_bands", "summarise_agent"]

#: Dataset name of the population-predictive rows of ``summary.csv``.
POPULATION_ROW = "population (new bubble)"

#: parameter -> (DPD unit, physical name, physical unit, converter DPD -> physical); E at ν = 1/2,
#: κ the continuum bending modulus (:mod:`bubblecal.data.units`).
PHYSICAL = {
    "ka": ("DPD 2-D modulus", "E", "MPa", lambda v: np.asarray(DEFAULT_UNITS.ka_to_young(v)) * 1e-6),
    "kb": ("DPD energy", "kappa", "k_BT", lambda v: np.asarray(DEFAULT_UNITS.kb_to_bending_kBT(v))),
    "d0": ("DPD length", "d0", "nm", lambda v: np.asarray(DEFAULT_UNITS.dpd_to_nm(v))),
}
for _k in (*NONLINEAR_PARAMETERS, *NOISE_PARAMETERS):
    PHYSICAL[_k] = ("1", _k, "1", lambda v: np.asarray(v, dtype=float))


def _y_to_physical(kind: str):
    """Converter of a curve's y (DPD) to physical units and the unit name."""
    if kind == "compression":
        return (lambda v: np.asarray(DEFAULT_UNITS.dpd_to_nN(v))), "nN"
    return (lambda v: np.asarray(DEFAULT_UNITS.dpd_to_nm(v))), "nm"


def dataset_posteriors(result) -> dict[str, dict]:
    """The final posterior draws of every dataset of one agent.

    Staged runs: phase-3 draws; NUTS: the joint draws sliced per curve / acoustic dataset (the MAP then
    uses the joint total log likelihood).

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult

    Returns
    -------
    dict
        Dataset name -> {'kind' (protocol or 'acoustic'), 'samples' (dict of (S,) arrays, DPD units),
        'loglik' ((S,) array or None), 'obj' (the curve or acoustic dataset), 'surrogate'}.
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


def psi_samples(result) -> tuple[dict, dict]:
    """Population hyperparameter draws of one agent (phase 2, or the joint run).

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult

    Returns
    -------
    tuple of dict
        (m, τ): pooled parameter name -> draws of its population mean and spread (DPD units); empty
        dicts when nothing is pooled.
    """
    if result.staged is not None:
        src = result.staged.phase2.samples
    else:
        src = result.joint.samples
    m = {k[2:]: np.asarray(v) for k, v in src.items() if k.startswith("m_")}
    tau = {k[4:]: np.asarray(v) for k, v in src.items() if k.startswith("tau_")}
    return m, tau


#: Parameters shown per bubble in the forest plot, the diameter plot and the report's per-bubble table.
BUBBLE_PARAMETERS = ("ka", "kb")


def bubble_rows(result):
    """One row per dataset of a summarised run: loading curves sorted by diameter, then acoustic datasets.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
        A summarised run (``result.summary`` set).

    Returns
    -------
    pandas.DataFrame
        Columns ``dataset``, ``bubble`` (the name without the ``<agent>_`` prefix), ``label`` ("bubble (D µm)"),
        ``kind``, ``diameter_um`` [um] (the measured diameter of a curve, NaN for an acoustic dataset),
        ``coverage_90``, ``crps``, ``crps_unit`` and, for each sampled parameter of :data:`BUBBLE_PARAMETERS`,
        ``<p>_q05``, ``<p>_median``, ``<p>_q95`` in physical units (E [MPa], kappa [k_BT]).
    """
    import pandas as pd

    df = result.summary
    agent = result.plan.agent
    diam = {c.name: float(c.bubble_diameter_um or c.diameter_um) for c in result.plan.curves}
    rows = []
    for name, sub in df.groupby("dataset", sort=False):
        if name in diam or sub["kind"].iloc[0] == "acoustic":
            bubble = name.removeprefix(f"{agent}_")
            d = diam.get(name, math.nan)
            r0 = sub.iloc[0]
            # a one-bubble acoustic dataset (a resonance row) names its diameter in the label
            d_ac = float(r0["diameter_um"]) if name not in diam else math.nan
            label = (f"{bubble} ({d:g} µm)" if name in diam else
                     f"{bubble} ({d_ac:g} µm)" if math.isfinite(d_ac) else bubble)
            row = {"dataset": name, "bubble": bubble, "label": label,
                   "kind": r0["kind"], "diameter_um": d, "coverage_90": float(r0["coverage_90"]),
                   "crps": float(r0["crps"]), "crps_unit": r0["crps_unit"]}
            for p in BUBBLE_PARAMETERS:
                r = sub[sub["parameter"] == p]
                if not r.empty:
                    row |= {f"{p}_{q}": float(r[f"{q}_phys"].iloc[0]) for q in ("q05", "median", "q95")}
            rows.append(row)
    out = pd.DataFrame(rows)
    if out.empty:
        return out
    # acoustic datasets (NaN diameter) last; equal diameters keep the plan's order
    return out.sort_values("diameter_um", kind="stable", na_position="last").reset_index(drop=True)


def population_bands(result) -> dict[str, dict[str, float]]:
    """Population intervals of every pooled parameter in physical units.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
        A summarised run: the phase-2 (or joint) draws of ψ and ``result.population_predictive``.

    Returns
    -------
    dict
        Pooled parameter -> ``m_q05``, ``m_median``, ``m_q95`` (the population mean m), ``tau_q05``,
        ``tau_median``, ``tau_q95`` (the spread τ) and ``new_q05``, ``new_median``, ``new_q95`` (the
        population predictive of a new bubble; absent without ``result.population_predictive``), in the
        physical unit of :data:`PHYSICAL`; empty when nothing is pooled.
    """
    m, tau = psi_samples(result)
    pop = result.population_predictive or {}
    out = {}
    for k in m:
        conv = PHYSICAL.get(k, (None, k, "", lambda a: np.asarray(a, dtype=float)))[3]
        entry = {}
        # the conversions are proportional, so a spread converts with the same factor as a mean
        for what, v in (("m", m[k]), ("tau", tau.get(k)), ("new", pop.get(k))):
            if v is not None:
                q = conv(np.quantile(np.asarray(v, dtype=float), [0.05, 0.5, 0.95]))
                entry |= {f"{what}_q05": float(q[0]), f"{what}_median": float(q[1]), f"{what}_q95": float(q[2])}
        out[k] = entry
    return out


def _thin(samples: Mapping[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
    """At most ``n`` evenly spaced draws (deterministic)."""
    size = int(next(iter(samples.values())).shape[0])
    if size <= n:
        return {k: np.asarray(v) for k, v in samples.items()}
    idx = np.linspace(0, size - 1, n).round().astype(int)
    return {k: np.asarray(v)[idx] for k, v in samples.items()}


def _param_rows(base: dict, samples: Mapping[str, np.ndarray], names, map_index: int | None) -> list[dict]:
    """Summary rows (mean, 5 %, 95 %, MAP in DPD and physical units) of the parameters ``names``."""
    rows = []
    for k in names:
        if k not in samples:
            continue
        v = np.asarray(samples[k], dtype=float)
        unit, pname, punit, conv = PHYSICAL.get(k, ("DPD", k, "DPD", lambda a: np.asarray(a)))
        q05, q50, q95 = np.quantile(v, [0.05, 0.5, 0.95])
        mp = float(v[map_index]) if map_index is not None else math.nan
        rows.append({**base, "parameter": k, "unit": unit, "mean": float(v.mean()), "median": float(q50),
                     "q05": float(q05), "q95": float(q95), "map": mp, "physical": pname, "physical_unit": punit,
                     "mean_phys": float(conv(v).mean()), "median_phys": float(conv(q50)), "q05_phys": float(conv(q05)),
                     "q95_phys": float(conv(q95)), "map_phys": float(conv(mp)) if map_index is not None else math.nan})
    return rows


#: Points of the dense grid of the predictive bands (figures).
_GRID_POINTS = 80
#: Prediction points (data + grid) are padded to a multiple of this, so curves share compiled programs.
_POINT_BUCKET = 64


def _prediction_arguments(thin: Mapping, samples: Mapping, imap: int | None, surrogate, spec, x, grid,
                          y_scale: float):
    """Arguments of the prediction program of one curve: ``(values, surrogate, points, y_scale)``.

    The thinned draws and the MAP draw (the first draw without a MAP index) are evaluated together at the data
    and grid points, padded to a multiple of :data:`_POINT_BUCKET` with the last grid point; the surrogate
    goes as a :class:`~bubblecal.models.TracedSurrogate` (its weights are arguments, not constants) where it can.
    """
    from bubblecal.models import TracedSurrogate

    names = [*spec.parameters, spec.mechanical_noise_name]
    best = imap if imap is not None else 0
    values = {k: np.append(np.asarray(thin[k]), np.asarray(samples[k])[best]) for k in names}
    points = np.concatenate([x, grid])
    points = np.pad(points, (0, -len(points) % _POINT_BUCKET), mode="edge")
    return values, TracedSurrogate.wrap(surrogate), points, y_scale


def _curve_predictions(predict, arguments, spec, n: int, m: int, imap: int | None):
    """Predictive (mean, sd) at the ``n`` data points and on the ``m`` grid points, and the MAP model curve on
    the grid, from one call of ``predict`` on :func:`_prediction_arguments`.

    Returns numpy arrays ``(mu, sd)`` (S, n), ``(gmu, gsd)`` (S, m), and the MAP curve (m,) or None without a
    MAP index.
    """
    from bubblecal.models import TracedSurrogate, mechanical_prediction

    values, surrogate, points, y_scale = arguments
    if isinstance(surrogate, TracedSurrogate):
        mu, sd = predict(*arguments)
    else:  # another callable (e.g. a closed-form law) cannot be an argument of a program: evaluated as is
        mu, sd = mechanical_prediction(values, surrogate, spec, points, y_scale=y_scale)
    mu, sd = np.asarray(mu, dtype=float), np.asarray(sd, dtype=float)
    s = mu.shape[0] - 1
    map_curve = mu[s, n:n + m] if imap is not None else None
    return mu[:s, :n], sd[:s, :n], mu[:s, n:n + m], sd[:s, n:n + m], map_curve


def summarise_agent(result, config) -> None:
    """Fill ``result.summary``, ``result.ess``, ``result.bands``, ``result.population_predictive``; write CSVs.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
        A finished run; filled in place. ``summary.csv`` (and ``ess.csv`` for staged runs) are written to
        its ``plan.out_dir``.
    config : bubblecal.workflows.calibrate.CalibrationConfig
        ``seed`` (CRPS draws and population predictive), ``predictive_samples`` and ``crps_replicates``.
    """
    import jax
    import pandas as pd

    from bubblecal.inference import map_index
    from bubblecal.inference.tmcmc import compile_lowered
    from bubblecal.models import TracedSurrogate, mechanical_prediction
    from bubblecal.workflows.host_programs import acoustic_prediction_program, population_predictive_draws

    # one compiled prediction per agent: curves of one network shape (and point bucket) share its program
    predict = jax.jit(lambda values, surrogate, x, y_scale: mechanical_prediction(values, surrogate, ap.spec, x,
                                                                                  y_scale=y_scale))

    ap = result.plan
    spec = ap.spec
    noise = spec.mechanical_noise_name
    rows = []
    bands = {}
    post = dataset_posteriors(result)
    rng = np.random.default_rng(config.seed)
    contexts = {}
    calls = {}
    for name, d in post.items():
        samples, obj = d["samples"], d["obj"]
        ll = d["loglik"]
        imap = map_index(ll) if ll is not None and np.size(ll) == next(iter(samples.values())).shape[0] else None
        thin = _thin(samples, config.predictive_samples)
        if d["kind"] == "acoustic":
            diam = np.asarray(obj.diameter_um, dtype=float)
            f = np.asarray(obj.frequency_MHz, dtype=float)
            arguments = (thin["ka"], thin["sigma_ac"], diam, float(np.max(f)))
            calls[name] = (acoustic_prediction_program(ap.f_res), arguments)
            contexts[name] = {"kind": "acoustic", "x": diam, "y": f, "sigma_mean": float(np.mean(thin["sigma_ac"])),
                              "names": ["ka", "sigma_ac"], "samples": samples, "imap": imap,
                              "diameter": float(np.mean(diam)) if diam.size == 1 else math.nan}
        else:
            x, y = np.asarray(obj.x, dtype=float), np.asarray(obj.y, dtype=float)
            grid = np.linspace(0.0, float(x.max()) * 1.02, _GRID_POINTS)
            y_scale = float(np.max(np.abs(y)))
            arguments = _prediction_arguments(thin, samples, imap, d["surrogate"], spec, x, grid, y_scale)
            calls[name] = (predict, arguments)
            contexts[name] = {"kind": d["kind"], "x": x, "y": y, "grid": grid, "names": [*spec.parameters, noise],
                              "samples": samples, "imap": imap, "diameter": float(obj.diameter_um)}
    # the curves' prediction programs lowered here, compiled several at a time; their calls then compile nothing
    compile_lowered([predict.lower(*arguments) for program, arguments in calls.values()
                     if program is predict and isinstance(arguments[1], TracedSurrogate)])
    # predictions on this thread, bands and CRPS on the pool's threads
    with StatisticsPool(rng, config.crps_replicates) as pool:
        for name, (program, arguments) in calls.items():
            c = contexts[name]
            if c["kind"] == "acoustic":
                mu, sd = program(*arguments)
                pool.submit(name, mu, sd, c["y"])
            else:
                mu, sd, gmu, gsd, c["map_curve"] = _curve_predictions(predict, arguments, spec, len(c["x"]),
                                                                      len(c["grid"]), c["imap"])
                pool.submit(name, mu, sd, c["y"], gmu, gsd)
        stats = pool.results()
    for name, c in contexts.items():
        st, kind = stats[name], c["kind"]
        band, crps = st.band, st.crps
        cov = band.coverage(c["y"])
        if kind == "acoustic":
            crps_sd = float(np.std(crps.replicates, ddof=1) if crps.replicates.size > 1 else 0.0)
            crps_mean, unit = crps.mean, "MHz"
            bands[name] = {"kind": kind, "x": c["x"], "y": c["y"], "median": band.median, "lower": band.lower,
                           "upper": band.upper, "sigma_mean": c["sigma_mean"]}
        else:
            conv, unit = _y_to_physical(kind)
            crps_mean = float(conv(crps.mean))
            crps_sd = float(conv(np.std(crps.replicates, ddof=1))) if crps.replicates.size > 1 else 0.0
            gband = st.grid_band
            # grid_model: the model curve itself (no observation noise), the spread of the surrogate prediction
            bands[name] = {"kind": kind, "x": c["x"], "y": c["y"], "median": band.median, "lower": band.lower,
                           "upper": band.upper, "grid": c["grid"], "grid_median": gband.median,
                           "grid_lower": gband.lower, "grid_upper": gband.upper, "grid_model": st.grid_model,
                           "map_curve": c["map_curve"]}
        base = {"agent": ap.agent, "workflow": ap.workflow, "dataset": name, "kind": kind,
                "diameter_um": c["diameter"], "n_points": int(np.size(bands[name]["y"])),
                "coverage_90": float(cov), "crps": float(crps_mean), "crps_sd": float(crps_sd), "crps_unit": unit}
        rows += _param_rows(base, c["samples"], c["names"], c["imap"])
    # population predictive of a new bubble
    m, tau = psi_samples(result)
    pop = None
    if m:
        bounds = {k: spec.parameters[k].prior.as_tuple() for k in m}
        pop = population_predictive_draws(jax.random.PRNGKey(config.seed + 7), m, tau, bounds,
                                          config.predictive_samples)
        base = {"agent": ap.agent, "workflow": ap.workflow, "dataset": POPULATION_ROW, "kind": "population",
                "diameter_um": math.nan, "n_points": 0, "coverage_90": math.nan, "crps": math.nan, "crps_sd": math.nan,
                "crps_unit": ""}
        rows += _param_rows(base, pop, list(m), None)
        hyper = {f"m_{k}": v for k, v in m.items()} | {f"tau_{k}": v for k, v in tau.items()}
        for key, v in hyper.items():
            k = key.split("_", 1)[1]
            unit, pname, punit, conv = PHYSICAL.get(k, ("DPD", k, "DPD", lambda a: np.asarray(a)))
            q05, q50, q95 = np.quantile(v, [0.05, 0.5, 0.95])
            rows.append({**base, "dataset": "hyperparameters", "kind": "psi", "parameter": key, "unit": unit,
                         "mean": float(v.mean()), "median": float(q50), "q05": float(q05), "q95": float(q95),
                         "map": math.nan, "physical": f"{key.split('_')[0]}_{pname}", "physical_unit": punit,
                         "mean_phys": float(conv(v).mean()), "median_phys": float(conv(q50)),
                         "q05_phys": float(conv(q05)), "q95_phys": float(conv(q95)), "map_phys": math.nan})
    result.summary = pd.DataFrame(rows)
    result.bands = bands
    result.population_predictive = pop
    result.summary.to_csv(ap.out_dir / "summary.csv", index=False)
    if result.staged is not None:
        result.ess = result.staged.ess()
        result.ess["pareto_k"] = _phase2_pareto_k(result, list(result.ess["dataset"]))
        result.ess.to_csv(ap.out_dir / "ess.csv", index=False)


def _phase2_pareto_k(result, names) -> list[float]:
    """Pareto k̂ of each dataset's phase-2 leave-one-out weights, in the order of ``names`` (NaN without the
    pointwise log likelihood, e.g. a run stored as ``.npz``)."""
    from bubblecal.workflows.calibrate import PHASE2_LOGLIK, phase2_pareto_k

    ll = result.pointwise.get("phase2", {}).get(PHASE2_LOGLIK)
    if ll is None:
        return [math.nan] * len(names)
    k = dict(zip(result.plan.dataset_names, phase2_pareto_k(ll), strict=True))
    return [float(k.get(n, math.nan)) for n in names]

