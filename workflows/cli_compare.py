"""``bubblecal compare``: one single-curve posterior sampled by TMCMC and by NUTS, with an agreement report.

Units: DPD throughout (:mod:`bubblecal.data.units`); the curve, priors and surrogate are those of
:func:`bubblecal.models.mechanical_model`. The verdict of :func:`bubblecal.inference.compare.compare_posteriors`
is information: the command exits 0 whenever both samplers ran, 1 on bad inputs (before any sampling).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import typer
from rich.markup import escape

from bubblecal.workflows.choices import LoadingProtocol, Units, choice_value
from bubblecal.workflows.console import console, fail, make_table
from bubblecal.workflows.domain import prior_box_domain_warnings


def _finite(value: float) -> float | None:
    """``value`` as float, or None when not finite (strict JSON)."""
    return float(value) if math.isfinite(value) else None


def compare(
    curve: str = typer.Option(None, "--curve", help="Shipped reference curve, e.g. definity-2.1 or sonovue-3.2."),
    data: Path = typer.Option(None, "--data", help="Your curve CSV instead of --curve (needs --kind and --units)."),
    kind: LoadingProtocol = typer.Option(None, "--kind", help="Loading protocol of --data."),
    units: Units = typer.Option("dpd", "--units", help="Units of --data."),
    surrogate: Path = typer.Option(..., "--surrogate", help="Mechanical surrogate .npz (bubblecal surrogates train)."),
    priors: str = typer.Option(None, "--priors", help="Priors name or TOML path (default: the agent's reduced "
                                                      "workflow; with --data, <kind's agent>_reduced)."),
    particles: int = typer.Option(4000, "--particles", help="TMCMC particles N."),
    replicas: int = typer.Option(4, "--replicas", help="Independent TMCMC runs (log Z ± its standard error)."),
    nuts_samples: int = typer.Option(1000, "--nuts-samples", help="NUTS draws per chain."),
    nuts_warmup: int = typer.Option(None, "--nuts-warmup", help="NUTS warm-up steps per chain (default: "
                                                                  "--nuts-samples)."),
    nuts_chains: int = typer.Option(4, "--nuts-chains", help="NUTS chains (vectorised)."),
    seed: int = typer.Option(0, "--seed"),
    out: Path = typer.Option(None, "--out", help="Optional folder: both posteriors as ArviZ NetCDF + JSON report."),
) -> None:
    """Sample one curve's posterior with TMCMC and with NUTS (the same NumPyro model) and report
    whether the two agree (quantile differences in posterior sd and KS statistic per parameter)."""
    from bubblecal.data import REFERENCE_CURVES, DataError, load_curve, load_reference, resolve_reference_name
    from bubblecal.priors import PriorError, load_priors
    from bubblecal.surrogates import SurrogateFormatError, load

    # ---- inputs, all checked before any sampling ------------------------------------------------
    kind, units = choice_value(kind), choice_value(units)
    if (curve is None) == (data is None):
        raise fail("give exactly one of --curve NAME or --data FILE")
    for name, value, minimum in (("--particles", particles, 2), ("--replicas", replicas, 1),
                                 ("--nuts-samples", nuts_samples, 1), ("--nuts-chains", nuts_chains, 1),
                                 ("--nuts-warmup", 0 if nuts_warmup is None else nuts_warmup, 0)):
        if value < minimum:
            raise fail(f"{name} must be >= {minimum}, got {value}")
    try:
        if curve is not None:
            name = resolve_reference_name(curve)
            agent, curve_kind, diameter, *_ = REFERENCE_CURVES[name]
            obs = load_reference(agent, diameter)
        else:
            if kind is None:
                raise fail("--data needs --kind compression|indentation")
            obs = load_curve(data, kind, units)
            name, curve_kind = obs.name, obs.kind
            agent = {"compression": "definity", "indentation": "sonovue"}[curve_kind]
        spec = load_priors(priors or f"{agent}_reduced")
    except (DataError, PriorError) as exc:
        raise fail(str(exc)) from None
    if not surrogate.is_file():
        raise fail(f"surrogate file not found: {surrogate}")
    try:
        model_s = load(surrogate)
    except (SurrogateFormatError, OSError, KeyError, ValueError) as exc:
        raise fail(f"{surrogate}: not a surrogate file ({exc})") from None
    if model_s.setup != curve_kind:
        raise fail(f"{surrogate}: a {model_s.setup} surrogate cannot explain the {curve_kind} curve {name}")
    if spec.setup != curve_kind:
        raise fail(f"priors {spec.name} are for {spec.setup}, the curve {name} is {curve_kind}")
    if spec.mechanical_noise_name not in spec.noise:
        raise fail(f"priors {spec.name} declare no noise amplitude {spec.mechanical_noise_name!r}")
    domain = prior_box_domain_warnings(model_s, spec, obs.x)
    for msg in domain:
        console.print(f"[yellow]warning:[/] the prior box exceeds the surrogate's training box: {escape(msg)}",
                      highlight=False, markup=True)

    # ---- sampling ---------------------------------------------------------------------------------
    import jax
    from numpyro.infer import init_to_value

    from bubblecal.inference import TMCMC, compare_posteriors, run_nuts
    from bubblecal.models import mechanical_model, nuts_init_values

    key_tm, key_nuts = jax.random.split(jax.random.PRNGKey(seed))
    console.print(f"curve {name} ({curve_kind}, {obs.x.size} points), priors {spec.name}, surrogate {surrogate}")
    tm = TMCMC(mechanical_model, num_particles=particles, num_replicas=replicas, progress=True)
    tm.run(key_tm, obs.x, obs.y, model_s, spec)
    nuts = run_nuts(mechanical_model, obs.x, obs.y, model_s, spec, rng_key=key_nuts,
                    num_warmup=nuts_samples if nuts_warmup is None else nuts_warmup, num_samples=nuts_samples,
                    num_chains=nuts_chains, init_strategy=init_to_value(values=nuts_init_values(spec)), progress=True)
    names = [*spec.parameters, spec.mechanical_noise_name]
    result = compare_posteriors(tm, nuts, names=names)

    # ---- report -----------------------------------------------------------------------------------
    n_stages = len(tm.stage_info) - 1
    se = tm.log_evidence_se
    se_txt = f" ± {se:.3f} (SE over {replicas} replicas)" if math.isfinite(se) else " (one replica: no SE)"
    console.print(f"TMCMC  N = {particles}: status {tm.status}, log Z = {tm.log_evidence:.3f}{se_txt}, "
                  f"{n_stages} stages, {tm.num_evaluations} likelihood evaluations", highlight=False)
    console.print(f"NUTS   {nuts_chains} chains × {nuts_samples} draws: max r_hat = {nuts.max_r_hat:.3f}, "
                  f"min bulk ESS = {nuts.min_n_eff:.0f}, divergences = {nuts.num_divergences}", highlight=False)
    table = make_table(f"TMCMC vs NUTS on {name}: quantile differences (TMCMC − NUTS) in posterior sd",
                       ("parameter", "sd", "dq05", "dq25", "dq50", "dq75", "dq95", "KS", "pass"))
    for row in result.table:
        dq = (f"{row[f'dq_{q}']:+.3f}" for q in ("05", "25", "50", "75", "95"))
        table.add_row(row["name"], f"{row['sd']:.4g}", *dq, f"{row['ks']:.3f}", "yes" if row["passed"] else "NO")
    console.print(table)
    th = result.thresholds
    colour = "green" if result.passed else "red"
    console.print(f"verdict: [bold {colour}]{'AGREE' if result.passed else 'DISAGREE'}[/] (central |dq| <= "
                  f"{th['max_central_diff']} sd, tail |dq| <= {th['max_tail_diff']} sd, KS <= {th['max_ks']})",
                  highlight=False)

    if out is not None:
        import arviz as az

        out.mkdir(parents=True, exist_ok=True)
        tm_path, nuts_path = out / f"{name}_tmcmc.nc", out / f"{name}_nuts.nc"
        tm.to_inference_data().to_netcdf(str(tm_path))
        az.from_numpyro(nuts.mcmc).to_netcdf(str(nuts_path))
        report = {
            "curve": name, "kind": curve_kind, "priors": spec.name, "surrogate": str(surrogate), "seed": seed,
            "domain_warnings": domain,
            "tmcmc": {"num_particles": particles, "num_replicas": replicas, "status": tm.status,
                      "log_evidence": tm.log_evidence, "log_evidence_se": _finite(se),
                      "log_evidences": [float(v) for v in tm.log_evidences], "stages": n_stages,
                      "num_evaluations": tm.num_evaluations},
            "nuts": {"num_chains": nuts_chains, "num_samples": nuts_samples,
                     "num_warmup": nuts_samples if nuts_warmup is None else nuts_warmup,
                     "max_r_hat": nuts.max_r_hat, "min_n_eff": nuts.min_n_eff,
                     "num_divergences": nuts.num_divergences, "converged": nuts.converged},
            "comparison": {"passed": result.passed, "thresholds": th, "table": result.table},
        }
        json_path = out / f"{name}_compare.json"
        tmp = json_path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(report, indent=1, allow_nan=False))
        tmp.replace(json_path)
        console.print(f"wrote {tm_path}, {nuts_path} and {json_path}", highlight=False)


def register(app: typer.Typer) -> None:
    """Add ``compare`` to the root command."""
    app.command("compare")(compare)
