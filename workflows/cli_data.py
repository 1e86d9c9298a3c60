"""``bubblecal data``: show the shipped reference data and validate a user's curve file."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.table import Table

from bubblecal.data import (
    DEFAULT_UNITS,
    DataError,
    acoustic_observations,
    load_curve,
    reference_curves,
    resolve_reference_name,
)
from bubblecal.workflows.choices import LoadingProtocol, Units, choice_value
from bubblecal.workflows.console import console, fail, make_table

app = typer.Typer(help="Reference force curves and acoustic observations.", no_args_is_help=True)


def _summary_table() -> Table:
    """Overview of the reference curves (diameters, retained points, ranges in nm and nN)."""
    table = make_table("Reference force-spectroscopy curves (retained points enter the likelihood)",
                       ("name", "D [µm]", "R [DPD length]", "points retained/source", "displacement [nm]",
                        "force [nN]"),
                       caption="Definity: Buchner Santos et al., Langmuir 28:5753 (2012); SonoVue: J. K. Morris, "
                               "PhD thesis, Edinburgh (2014). D: nominal (measured) diameter.")
    for c in reference_curves():
        disp, force = c.displacement_nm, c.force_nN
        measured = f" ({c.bubble_diameter_um:g})" if c.bubble_diameter_um != c.diameter_um else ""
        diameter = f"{c.diameter_um:g}" + measured
        table.add_row(c.name, diameter, f"{c.radius_dpd:g}", f"{c.n_points}/{c.source_curve.x.size}",
                      f"{disp.min():.1f}–{disp.max():.1f}", f"{force.min():.2f}–{force.max():.2f}")
    return table


def _acoustic_table() -> Table:
    """The acoustic resonance observations (diameter [um], radius [DPD length], f_res [MHz])."""
    table = make_table("Acoustic resonance observations",
                       ("#", "agent", "diameter [µm]", "radius [DPD length]", "f_res [MHz]", "source"))
    for k, o in enumerate(acoustic_observations(), start=1):
        table.add_row(str(k), o.agent, f"{o.diameter_um:.2f}", f"{DEFAULT_UNITS.radius_dpd(o.diameter_um):.2f}",
                      f"{o.frequency_MHz:.2f}", f"{o.source}, {o.source_figure}")
    return table


def _curve_table(curve, title: str) -> Table:
    """One curve point by point, in physical and DPD units."""
    headers = ["#"] + [curve.axis_label(axis, u) for axis in ("x", "y") for u in ("physical", "dpd")]
    table = make_table(title, headers)
    for k in range(curve.n_points):
        table.add_row(str(k + 1), f"{curve.x_physical[k]:.4g}", f"{curve.x[k]:.5g}",
                      f"{curve.y_physical[k]:.4g}", f"{curve.y[k]:.5g}")
    return table


@app.command("show")
def show(name: str = typer.Argument(None, help="Curve name (e.g. definity-2.1, sonovue_indentation_5.8um) or "
                                               "'acoustic'; omit for the overview.")) -> None:
    """Print the reference data: an overview, one curve point by point, or the acoustic table."""
    if name is None:
        console.print(_summary_table())
        console.print(_acoustic_table())
        return
    if name.lower() == "acoustic":
        console.print(_acoustic_table())
        return
    try:
        canonical = resolve_reference_name(name)
    except DataError as exc:
        raise fail(str(exc)) from None
    curve = next(c for c in reference_curves() if c.name == canonical)
    title = f"{curve.name}: {curve.agent} {curve.kind}, D = {curve.diameter_um:g} µm ({curve.source})"
    console.print(_curve_table(curve, title))


@app.command("check")
def check(
    file: Path = typer.Argument(..., help="CSV file with a header row."),
    kind: LoadingProtocol = typer.Option(..., "--kind", help="Loading protocol."),
    units: Units = typer.Option("dpd", "--units", help="Units of the file."),
) -> None:
    """Validate a loading-curve CSV; exit status 1 with every problem listed if it is invalid."""
    kind, units = choice_value(kind), choice_value(units)
    try:
        curve = load_curve(file, kind, units)
    except DataError as exc:
        raise fail(str(exc)) from None
    console.print(f"[green]ok[/]: {file} is a valid {kind} curve in {units} units with {curve.n_points} points")
    console.print(_curve_table(curve, f"{file}: {kind}, {curve.n_points} points (DPD and physical units)"))
