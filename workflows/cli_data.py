"""``bubblecal data``: show the shipped reference data or a tidy file, and validate a user's data file."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.table import Table

from bubblecal.data import (
    DEFAULT_UNITS,
    DataError,
    acoustic_observations,
    check_consistency,
    load_acoustic_table,
    load_curve,
    read_bubble_curves,
    read_resonance,
    reference_curves,
    resolve_reference_name,
    tidy_kind,
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


def tidy_curves_table(curves) -> Table:
    """Per agent: bubbles, protocols, diameters, points and retained points of a tidy curve file.

    Parameters
    ----------
    curves : bubblecal.data.BubbleCurveSet

    Returns
    -------
    rich.table.Table
        One row per agent, then a total row.
    """
    table = make_table(f"{curves.path}: {len(curves)} bubbles of {len(curves.agents)} agents",
                       ("agent", "bubbles", "protocols", "D [µm] min–max", "points", "retained points"))
    for agent, bubbles in curves.by_agent().items():
        diameters = [b.diameter_um for b in bubbles]
        ids = [b.bubble for b in bubbles]  # a long list is shown by its ends: the table stays one row per agent
        ids_text = ", ".join(ids) if len(ids) <= 6 else f"{ids[0]}, {ids[1]}, ... {ids[-1]} ({len(ids)})"
        table.add_row(agent, ids_text, ", ".join(sorted({b.protocol for b in bubbles})),
                      f"{min(diameters):.4g}–{max(diameters):.4g}", str(sum(b.n_points for b in bubbles)),
                      str(sum(b.n_retained for b in bubbles)))
    counts = curves.counts().values()
    table.add_row("total", str(len(curves)), "", "", str(sum(c["points"] for c in counts)),
                  str(sum(c["retained"] for c in counts)))
    return table


def tidy_resonance_table(resonance) -> Table:
    """Per agent: rows, diameters and frequencies of a tidy resonance file.

    Parameters
    ----------
    resonance : bubblecal.data.ResonanceSet

    Returns
    -------
    rich.table.Table
        One row per agent.
    """
    table = make_table(f"{resonance.path}: {len(resonance)} resonance rows",
                       ("agent", "bubbles", "D [µm] min–max", "f_res [MHz] min–max"))
    for agent in resonance.agents:
        d, f = resonance.for_agent(agent)
        table.add_row(agent, str(d.size), f"{d.min():g}–{d.max():g}", f"{f.min():g}–{f.max():g}")
    return table


def _show_file(path: Path) -> None:
    """Print the summary of a tidy curve or resonance file."""
    try:
        kind = tidy_kind(path)
        if kind == "curves":
            console.print(tidy_curves_table(read_bubble_curves(path)))
        elif kind == "resonance":
            console.print(tidy_resonance_table(read_resonance(path)))
        else:
            raise fail(f"{path}: not a tidy curve file (a 'bubble' column) or resonance file (a 'frequency_MHz' "
                       "column); check a single-curve file with: bubblecal data check FILE --kind KIND")
    except DataError as exc:
        raise fail(str(exc)) from None


@app.command("show")
def show(name: str = typer.Argument(None, help="Curve name (e.g. definity-2.1, sonovue_indentation_5.8um), "
                                               "'acoustic', or a tidy curve / resonance file; omit for the "
                                               "overview.")) -> None:
    """Print the reference data (an overview, one curve point by point, the acoustic table) or a tidy file."""
    if name is not None and Path(name).is_file():
        _show_file(Path(name))
        return
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


def _check_tidy(file: Path, kind: str, resonance: Path | None) -> None:
    """Validate a tidy curve or resonance file (and a resonance file against the curves); print the summary."""
    try:
        if kind == "resonance":
            res = read_resonance(file)
            console.print(f"[green]ok[/]: {file} is a valid tidy resonance file ({len(res)} rows, "
                          f"{len(res.agents)} agents)")
            console.print(tidy_resonance_table(res))
            return
        problems = []
        curves = res = None
        try:
            curves = read_bubble_curves(file)
        except DataError as exc:
            problems.append(str(exc))
        if resonance is not None:
            try:
                res = read_resonance(resonance)
                if curves is not None:
                    check_consistency(curves, res)
            except DataError as exc:
                problems.append(str(exc))
        if problems:
            raise fail("\n".join(problems))
    except DataError as exc:
        raise fail(str(exc)) from None
    counts = curves.counts().values()
    console.print(f"[green]ok[/]: {file} is a valid tidy curve file ({len(curves)} bubbles, {len(curves.agents)} "
                  f"agents, {sum(c['points'] for c in counts)} points, {sum(c['retained'] for c in counts)} retained)"
                  + (f"; {resonance} adds {len(res)} resonance rows" if res is not None else ""))
    console.print(tidy_curves_table(curves))
    if res is not None:
        console.print(tidy_resonance_table(res))


@app.command("check")
def check(
    file: Path = typer.Argument(..., help="CSV file with a header row: a tidy curve or resonance file, the "
                                          "acoustic table, or one curve (then --kind)."),
    kind: LoadingProtocol = typer.Option(None, "--kind", help="Loading protocol of a single-curve file."),
    units: Units = typer.Option("dpd", "--units", help="Units of a single-curve file."),
    resonance: Path = typer.Option(None, "--resonance", help="Tidy resonance file to check with a tidy curve file "
                                                             "(every agent in it needs curves)."),
) -> None:
    """Validate a data file (kind judged by its header); exit status 1 with every problem listed if it is invalid."""
    try:
        detected = tidy_kind(file)
    except DataError as exc:
        raise fail(str(exc)) from None
    if detected is not None:
        _check_tidy(file, detected, resonance)
        return
    if resonance is not None:
        raise typer.BadParameter("--resonance goes with a tidy curve file (a 'bubble' column)",
                                 param_hint="--resonance")
    if kind is None:
        if _is_acoustic_table(file):
            try:
                n = len(load_acoustic_table(file))
            except DataError as exc:
                raise fail(str(exc)) from None
            console.print(f"[green]ok[/]: {file} is a valid acoustic table with {n} rows")
            return
        raise typer.BadParameter(f"{file} is not a tidy file (no 'bubble' or 'frequency_MHz' column): a single-curve "
                                 "file needs --kind compression|indentation", param_hint="--kind")
    kind, units = choice_value(kind), choice_value(units)
    try:
        curve = load_curve(file, kind, units)
    except DataError as exc:
        raise fail(str(exc)) from None
    console.print(f"[green]ok[/]: {file} is a valid {kind} curve in {units} units with {curve.n_points} points")
    console.print(_curve_table(curve, f"{file}: {kind}, {curve.n_points} points (DPD and physical units)"))


def _is_acoustic_table(file: Path) -> bool:
    """Whether the file's first line names the published acoustic table's frequency column."""
    try:
        with open(file, encoding="utf-8-sig") as handle:
            return "resonance_frequency_MHz" in handle.readline()
    except (OSError, UnicodeDecodeError):
        return False
