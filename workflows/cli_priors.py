"""``bubblecal priors``: show and check the prior/hyperprior TOML files; write a template for a user's agent."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.table import Table

from bubblecal.data import DEFAULT_UNITS, PARAMETER_UNITS, atomic_write
from bubblecal.priors import PriorError, available_priors, load_priors, priors_template
from bubblecal.workflows.choices import LoadingProtocol, Workflow, choice_value
from bubblecal.workflows.console import console, fail, make_table

app = typer.Typer(help="Prior and hyperprior ranges (user-editable TOML files).", no_args_is_help=True)


def _physical(name: str, lo: float, hi: float) -> str:
    """The physical equivalent of a DPD range, with its unit."""
    u = DEFAULT_UNITS
    if name == "ka":
        return f"E {u.ka_to_young(lo) / 1e6:.3g} – {u.ka_to_young(hi) / 1e6:.3g} MPa"
    if name == "kb":
        return f"κ {u.kb_to_bending_kBT(lo):.3g} – {u.kb_to_bending_kBT(hi):.3g} k_BT"
    if name == "d0":
        return f"{u.dpd_to_nm(lo):.3g} – {u.dpd_to_nm(hi):.3g} nm"
    return "–"


def _range(b) -> str:
    """'lo – hi' of a bounds object, '–' for None."""
    return "–" if b is None else f"{b.lo:.4g} – {b.hi:.4g}"


def priors_table(spec) -> Table:
    """Rich table of a PriorSpec: one row per parameter, units in every header.

    Parameters
    ----------
    spec : bubblecal.priors.PriorSpec

    Returns
    -------
    rich.table.Table
        Prior ranges in DPD units and in physical units (E [MPa], κ [k_BT], d0 [nm]), pooling and
        hyperprior ranges; fixed and noise parameters below.
    """
    table = make_table(f"{spec.name}: {spec.agent} {spec.setup}, {spec.shell} shell"
                       f"{' + acoustic' if spec.acoustic else ''}  ({spec.path})",
                       ("parameter", "unit [DPD]", "prior range [DPD]", "prior range [E MPa | κ k_BT | nm]",
                        "pooled", "population mean m range [DPD]", "population spread τ range [DPD]"))
    for name, p in spec.parameters.items():
        table.add_row(name, PARAMETER_UNITS[name], _range(p.prior), _physical(name, p.prior.lo, p.prior.hi),
                      "yes" if p.pooled else "no", _range(p.hyper_m), _range(p.hyper_tau))
    for name, value in spec.fixed.items():
        table.add_row(name, PARAMETER_UNITS[name], f"fixed = {value:g}", "–", "–", "–", "–")
    for name, n in spec.noise.items():
        table.add_row(name, "relative [-]", _range(n.prior), "–", "no (per dataset)", "–", "–")
    return table


@app.command("show")
def show(name: str = typer.Argument(None, help="Shipped workflow name (e.g. definity_reduced_acoustic) or a "
                                               "TOML path; omit to list the shipped files.")) -> None:
    """Print a workflow's prior and hyperprior ranges in DPD and physical units."""
    if name is None:
        table = make_table("Shipped prior files (bubblecal priors show NAME)",
                           ("name", "agent", "setup", "shell", "acoustic", "free parameters", "noise"))
        for n in available_priors():
            s = load_priors(n)
            table.add_row(n, s.agent, s.setup, s.shell, str(s.acoustic).lower(), ", ".join(s.free_names),
                          ", ".join(s.noise_names))
        console.print(table)
        return
    try:
        spec = load_priors(name)
    except PriorError as exc:
        raise fail(str(exc)) from None
    console.print(priors_table(spec))


@app.command("check")
def check(file: Path = typer.Argument(..., help="Priors TOML file to validate.")) -> None:
    """Validate a priors file; exit status 1 with every problem listed if it is invalid."""
    try:
        spec = load_priors(file)
    except PriorError as exc:
        raise fail(str(exc)) from None
    console.print(f"[green]ok[/]: {file} is valid ({len(spec.parameters)} free, {len(spec.fixed)} fixed, "
                  f"{len(spec.noise)} noise parameters)")
    console.print(priors_table(spec))


@app.command("template")
def template(
    agent: str = typer.Option(..., "--agent", help="Your agent's label (as in the tidy curve file)."),
    protocol: LoadingProtocol = typer.Option(..., "--protocol", help="How the agent's bubbles were measured: picks "
                                                                     "the published agent whose priors are copied."),
    workflow: Workflow = typer.Option("reduced", "--workflow", help="Workflow whose shipped priors are copied."),
    out: Path = typer.Option(..., "--out", help="TOML file to write."),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing file."),
) -> None:
    """Write an editable priors TOML for an agent, starting from the shipped priors of its protocol."""
    if out.exists() and not force:
        raise fail(f"{out} exists; pass --force to overwrite it")
    try:
        text = priors_template(agent, choice_value(protocol), choice_value(workflow))
    except PriorError as exc:
        raise fail(str(exc)) from None
    try:
        atomic_write(out, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    except OSError as exc:
        raise fail(f"{out}: cannot write: {exc.strerror or exc}") from None
    spec = load_priors(out)
    console.print(f"[green]wrote[/] {out}: priors for agent {agent!r} ({choice_value(protocol)}), from the shipped "
                  f"{spec.agent} {choice_value(workflow)} priors; edit it, then: bubblecal priors check {out}")
