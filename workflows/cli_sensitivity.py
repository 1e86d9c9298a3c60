"""``bubblecal sensitivity``: Sobol indices of a mechanical surrogate over a workflow's prior box."""

from __future__ import annotations

import warnings
from pathlib import Path

import typer

from bubblecal._extras import require
from bubblecal.workflows.console import console, fail, make_table
from bubblecal.workflows.sensitivity import SOBOL_N, SOBOL_POINTS


def sensitivity(
    surrogate: Path = typer.Option(..., "--surrogate", help="Mechanical surrogate .npz (bubblecal surrogates train)."),
    curve: str = typer.Option(..., "--curve", help="Reference curve whose explored loading range is averaged "
                                                   "over, e.g. definity-2.1."),
    priors: str = typer.Option(None, "--priors", help="Priors name or TOML path (default: the agent's full workflow)."),
    n: int = typer.Option(SOBOL_N, "--n", help="Saltelli base sample size N (power of two)."),
    points: int = typer.Option(SOBOL_POINTS, "--points", help="Loading coordinates along the surrogate's range."),
    seed: int = typer.Option(0, "--seed"),
    out: Path = typer.Option(Path("results/sensitivity"), "--out", help="Output folder (JSON + PNG)."),
) -> None:
    """First-order and total Sobol indices (SALib, with confidence intervals) along the loading
    coordinate, averaged over the curve's explored range; writes a JSON report and a plot."""
    from bubblecal.data import REFERENCE_CURVES, DataError, load_reference, resolve_reference_name
    from bubblecal.priors import PriorError, load_priors
    from bubblecal.surrogates import SurrogateFormatError, load
    from bubblecal.workflows.sensitivity import averaging_range, surrogate_sensitivity, write_sensitivity

    require("SALib", "sensitivity")  # before the surrogate is evaluated on the design
    try:
        name = resolve_reference_name(curve)
        agent, kind, diameter, *_ = REFERENCE_CURVES[name]
        data = load_reference(agent, diameter)
        spec = load_priors(priors or f"{agent}_full")
    except (DataError, PriorError) as exc:
        raise fail(str(exc)) from None
    if not surrogate.is_file():
        raise fail(f"surrogate file not found: {surrogate}")
    try:
        model = load(surrogate)
    except SurrogateFormatError as exc:
        raise fail(str(exc)) from None
    if model.setup != kind:
        raise fail(f"{surrogate}: a {model.setup} surrogate cannot explain the {kind} curve {name}")
    if spec.setup != kind:
        raise fail(f"priors {spec.name} are for {spec.setup}, the curve {name} is {kind}")
    try:
        with warnings.catch_warnings(record=True) as caught:  # shown once, on the console, below the table
            warnings.simplefilter("always")
            x_range, cut = averaging_range(data.x, model)
            if cut:
                warnings.warn(f"{name}: {cut}", stacklevel=1)
            run = surrogate_sensitivity(model, spec, x_range, N=n, num_points=points, seed=seed)
    except ValueError as exc:
        raise fail(str(exc)) from None
    r = run.result
    table = make_table(f"Sobol indices of the {kind} surrogate over the {spec.name} prior box "
                       f"(N = {r.N}, {r.n_evaluations} evaluations × {r.x.size} points; averaged over "
                       f"x in [{r.x_range[0]:.4g}, {r.x_range[1]:.4g}] DPD)",
                       ("parameter", "prior range [DPD]", "S1", "S1 95% CI ±", "ST", "ST 95% CI ±"))
    for row in r.table():
        lo, hi = run.bounds[row["parameter"]]
        table.add_row(row["parameter"], f"{lo:.4g} – {hi:.4g}", f"{row['S1']:.3f}", f"{row['S1_conf']:.3f}",
                      f"{row['ST']:.3f}", f"{row['ST_conf']:.3f}")
    console.print(table)
    if run.outside_training_fraction > 0:
        console.print(f"[yellow]warning:[/] {100 * run.outside_training_fraction:.1f} % of the prior box lies "
                      "outside the surrogate's training box (indices there are extrapolations)")
    for w in caught:
        console.print(str(w.message), markup=False, highlight=False)
    files = write_sensitivity(run, out, name)
    console.print(f"wrote {files['json']} and {files['plot']}")


def register(app: typer.Typer) -> None:
    """Add ``sensitivity`` to the root command."""
    app.command("sensitivity")(sensitivity)
