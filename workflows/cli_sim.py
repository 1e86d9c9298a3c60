"""``bubblecal sim``: the Warp DPD engine's verification, ringdown sweeps and training-data campaigns.

A thin command line over :mod:`bubblecal.sim` and :mod:`bubblecal.campaigns`; heavy libraries (Warp, Dask)
are imported inside the commands.  A command's docstring up to the form feed (``\\f``) is its ``--help`` text;
the numpydoc sections after it are for readers of the code.  The campaign commands live in
:mod:`bubblecal.workflows.cli_campaign` (with how to run a campaign on a cluster).
"""

from __future__ import annotations

import json
from pathlib import Path

import typer

from bubblecal._extras import require
from bubblecal.workflows.choices import Agent, RingdownTier, choice_value
from bubblecal.workflows.cli_campaign import campaign, campaign_status
from bubblecal.workflows.console import console, fail, make_table

app = typer.Typer(help="Warp DPD simulator: physics verification and training-data campaigns.",
                  no_args_is_help=True)


@app.command("verify")
def verify(
    quick: bool = typer.Option(False, "--quick", help="Small CPU-sized versions (default test suite)."),
    device: str = typer.Option("cpu", "--device", help="Warp device: cpu or cuda (cuda:N)."),
    only: list[str] = typer.Option(None, "--only", help="Run only checks whose name contains this (repeatable)."),
) -> None:
    """Run the checks of docs/physics.md section 6; table, then one JSON line; exit 1 on any failure.
    \f

    Parameters
    ----------
    quick : bool
        Small CPU-sized versions of the checks (those of the default test suite).
    device : str
        Warp device: 'cpu', 'cuda' or 'cuda:N'.
    only : list of str, optional
        Run only the checks whose name contains one of these.

    Raises
    ------
    typer.BadParameter
        ``device`` is not cpu / cuda[:N].
    typer.Exit
        Always: code 0 when every check passes, 1 otherwise.
    """
    if not (device == "cpu" or device.startswith("cuda")):
        raise typer.BadParameter("device must be 'cpu' or 'cuda' (or 'cuda:N')", param_hint="--device")
    wp = require("warp", "sim")
    require("trimesh", "sim")  # the shell meshes

    wp.config.quiet = True
    from bubblecal.sim.validation.verify import main

    code = main(quick=quick, device=device, only=only or None)
    raise typer.Exit(code)


app.command("campaign")(campaign)
app.command("campaign-status")(campaign_status)


@app.command("ringdown")
def ringdown(
    agent: Agent = typer.Option(..., "--agent", case_sensitive=False, help="Sets k_b and the k_a range."),
    diameter: float = typer.Option(..., "--diameter", help="Bubble diameter [um]."),
    out: Path = typer.Option(..., "--out", help="Output folder (CSV, JSON, PNG, traces .npz)."),
    n_ka: int = typer.Option(28, "--n-ka", help="Number of k_a values over the agent's acoustic prior range."),
    ka_min: float = typer.Option(None, "--ka-min", help="Lowest k_a [DPD] (default: prior range)."),
    ka_max: float = typer.Option(None, "--ka-max", help="Highest k_a [DPD] (default: prior range)."),
    tier: RingdownTier = typer.Option("implicit", "--tier", help="implicit (shell-mass-only inertia, "
                                      "docs/physics.md check 7) or explicit (water + gas particles)."),
    device: str = typer.Option("cpu", "--device", help="Warp device: cpu or cuda (cuda:N)."),
    mass_factor: float = typer.Option(160.0, "--mass-factor", help="Shell mass multiplier (f x sqrt(M) undone)."),
    subdivisions: int = typer.Option(None, "--subdivisions", help="Icosphere level (default 4; 5 above 5 um)."),
    batch: int = typer.Option(None, "--batch", help="Replicas per launch (default: all k_a values at once)."),
    seed: int = typer.Option(0, "--seed", help="Seed of the first replica (replica i: seed + i)."),
    dt: float = typer.Option(None, "--dt", help="Time step [DPD] (default: explicit 1e-4, implicit automatic)."),
    equilibration_steps: int = typer.Option(None, "--equilibration-steps", help="Steps before the perturbation."),
    record_steps: int = typer.Option(None, "--record-steps", help="Steps recorded after it (default: 8 periods)."),
    record_every: int = typer.Option(None, "--record-every", help="Steps between R(t) samples."),
    perturbation: float = typer.Option(0.015, "--perturbation", help="Relative radial scaling at t = 0."),
) -> None:
    """Ringdown sweep over k_a at one diameter: fit R(t), f_res in MHz, f_res^2(k_a) quadratic + LOO errors.
    \f

    Writes CSV, JSON, PNG and the traces (.npz) to ``out``, prints the per-k_a table and last one JSON line.

    Parameters
    ----------
    agent : str
        'definity' or 'sonovue' (sets k_b and the k_a range of the agent's acoustic prior).
    diameter : float
        Bubble diameter [um].
    out : Path
        Output folder.
    n_ka : int
        Number of k_a values (>= 3).
    ka_min, ka_max : float, optional
        k_a range [DPD 2-D modulus] (default: the prior range).
    tier : str
        'implicit' (shell-mass-only inertia, docs/physics.md section 6, check 7) or 'explicit' (water + gas particles).
    device : str
        Warp device: 'cpu', 'cuda' or 'cuda:N'.
    mass_factor : float
        Shell mass multiplier (dimensionless).
    subdivisions : int, optional
        Icosphere level.
    batch : int, optional
        Replicas per launch.
    seed : int
        Seed of the first replica (replica i: seed + i).
    dt : float, optional
        Time step [DPD time].
    equilibration_steps, record_steps, record_every : int, optional
        Steps before the perturbation, steps recorded after it, steps between R(t) samples.
    perturbation : float
        Relative radial scaling at t = 0 (dimensionless).

    Raises
    ------
    typer.BadParameter
        An option is out of range.
    typer.Exit
        Code 1 on an invalid sweep or fewer than 3 valid rows (no quadratic).
    """
    import numpy as np

    if not (device == "cpu" or device.startswith("cuda")):
        raise typer.BadParameter("device must be 'cpu' or 'cuda' (or 'cuda:N')", param_hint="--device")
    agent, tier = choice_value(agent), choice_value(tier)
    if n_ka < 3:
        raise typer.BadParameter("need at least 3 k_a values for a quadratic", param_hint="--n-ka")
    wp = require("warp", "sim")
    require("trimesh", "sim")  # the shell meshes

    wp.config.quiet = True
    from bubblecal.workflows.acoustic_sweep import (
        default_ka_values,
        fit_sweep,
        ringdown_sweep,
        write_sweep_outputs,
    )

    ka = default_ka_values(agent, n_ka)
    if ka_min is not None or ka_max is not None:
        ka = np.linspace(ka[0] if ka_min is None else ka_min, ka[-1] if ka_max is None else ka_max, n_ka)
    kw = {k: v for k, v in dict(dt=dt, equilibration_steps=equilibration_steps, record_steps=record_steps,
                                record_every=record_every, subdivisions=subdivisions).items() if v is not None}
    try:
        res = ringdown_sweep(agent, diameter, ka, tier=tier, device=device, mass_factor=mass_factor, seed=seed,
                             batch_size=batch, perturbation=perturbation,
                             progress=lambda m: console.print(m, markup=False, highlight=False), **kw)
    except ValueError as exc:
        raise fail(str(exc)) from None
    fit = fit_sweep(res)[res.diameter_um] if res.valid.sum() >= 3 else None
    paths = write_sweep_outputs(res, out, fit=fit)
    table = make_table(f"ringdown {res.agent} {diameter:g} um ({tier}, mass factor {mass_factor:g})",
                       ("k_a [DPD]", "status", "f_res [MHz]", "f_0 [MHz]", "R^2", "cycles", "check-7 ratio"))
    for r in res.rows:
        table.add_row(f"{r['ka']:.0f}", r["status"], f"{r['f_res_MHz']:.4g}", f"{r['f_0_MHz']:.4g}",
                      f"{r['r2']:.4f}", f"{r['n_cycles']:.1f}", f"{r['check7_ratio']:.4f}")
    console.print(table)
    summary = res.summary()
    if fit is not None:
        summary.update({"a0": fit.a0, "a1": fit.a1, "a2": fit.a2, "loo_median": fit.loo_median,
                        "loo_max": fit.loo_max})
        console.print(f"f_res^2 = {fit.a0:.6g} + {fit.a1:.6g} k_a + {fit.a2:.6g} k_a^2 [MHz^2]; LOO median "
                      f"{100 * fit.loo_median:.3f} %, max {100 * fit.loo_max:.3f} %")
    else:
        console.print("[yellow]fewer than 3 valid rows: no quadratic[/]")
    summary["files"] = {k: str(v) for k, v in paths.items()}
    console.print(json.dumps(summary), markup=False, highlight=False, soft_wrap=True)
    if fit is None:
        raise typer.Exit(1)
