"""``bubblecal sim``: the Warp DPD engine's verification, ringdown sweeps and training-data campaigns.

A thin command line over :mod:`bubblecal.sim` and :mod:`bubblecal.campaigns`; heavy libraries (Warp, Dask)
are imported inside the commands.  A command's docstring up to the form feed (``\\f``) is its ``--help`` text;
the numpydoc sections after it are for readers of the code.

Campaigns on a SLURM cluster (dask-jobqueue is not a bubblecal dependency; ``pip install dask-jobqueue``)::

    # in a long-lived Python session on the login node
    from dask_jobqueue import SLURMCluster
    cluster = SLURMCluster(queue="gpu", cores=4, memory="16GB", processes=1, walltime="04:00:00",
                           job_extra_directives=["--gres=gpu:1"])
    cluster.scale(jobs=8)                    # 8 GPU jobs, one Dask worker each
    print(cluster.scheduler_address)         # tcp://10.1.2.3:8786

    # in a shell (same environment): the client writes the store, the workers simulate
    bubblecal sim campaign definity_compression_2.1um --store /scratch/def21.store --scheduler tcp://10.1.2.3:8786

Several GPUs on one host: start ``dask_cuda.LocalCUDACluster()`` (one worker per GPU, each seeing only its
own GPU through CUDA_VISIBLE_DEVICES, so device "cuda" is that GPU) and pass its ``--scheduler`` address;
a plain LocalCluster with several workers and device "cuda" would put every worker on GPU 0.

Interrupt and re-run the same command at any time: finished samples are skipped, nothing is duplicated.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import typer

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
    import warp as wp

    wp.config.quiet = True
    from bubblecal.sim.validation.verify import main

    code = main(quick=quick, device=device, only=only or None)
    raise typer.Exit(code)


def _fmt(v: float) -> str:
    """A number with 6 significant digits."""
    return f"{v:.6g}"


def _design_tables(cf, where, store_note: str) -> None:
    """Print the campaign summary and the ranges table (units in the headers); ``where``: a DesignProgress."""
    from bubblecal.data import PARAMETER_UNITS
    from bubblecal.workflows.cli_priors import _physical

    c = cf.config
    grid = c.grid_for(c.diameters[0])
    unit = {"compression": "DPD length (total displacement)", "indentation": "DPD force (per pole)"}.get(c.protocol)
    summary = make_table(f"campaign {c.name} ({cf.path})", ("setting", "value"))
    rows = [("protocol", c.protocol), ("diameter(s) [um]", ", ".join(_fmt(d) for d in c.diameters)),
            ("tier", f"{c.tier} {json.dumps(c.tier_settings) if c.tier_settings else '(defaults)'}"),
            ("design", f"{c.design}, seed {c.seed}" + (f", box from priors {cf.priors}" if cf.priors else "")),
            ("design points", str(c.n_design)),
            ("replicas per task", str(c.replicas_per_task)), ("tasks (full run)", str(c.n_tasks)),
            ("device", c.device), ("subdivisions", "mesh default" if c.subdivisions is None else str(c.subdivisions)),
            ("loading grid", "t, R(t) [DPD time, DPD length]" if grid is None else
             f"{len(grid)} points {_fmt(grid[0])} .. {_fmt(grid[-1])} [{unit}]"),
            ("store", f"{c.store} {store_note}")]
    if where.n_done is not None:
        rows.append(("done / pending", f"{where.n_done} / {where.n_pending}"))
        rows.append(("pending tasks", str(where.n_pending_tasks)))
    for k, v in rows:
        summary.add_row(k, v)
    console.print(summary)
    table = make_table("parameter ranges", ("parameter", "unit [DPD]", "lo [DPD]", "hi [DPD]", "sampled",
                                            "range [E MPa | κ k_BT]"))
    for name, (lo, hi) in c.ranges.items():
        table.add_row(name, PARAMETER_UNITS[name], _fmt(lo), _fmt(hi), "yes" if hi > lo else "fixed",
                      _physical(name, lo, hi))
    console.print(table)


def _status_table(title: str, counts: dict[str, int]) -> None:
    """Print counts by status and their total."""
    table = make_table(title, ("status", "samples"))
    for k, v in counts.items():
        table.add_row(k, str(v))
    table.add_row("total", str(sum(counts.values())))
    console.print(table)


@app.command("campaign")
def campaign(
    config: str = typer.Argument(..., help="Campaign TOML file, or a shipped campaign name "
                                           "(e.g. definity_compression_2.1um)."),
    scheduler: str = typer.Option(None, "--scheduler", help="Dask scheduler address tcp://HOST:PORT (e.g. of a "
                                                            "dask-jobqueue SLURMCluster); 'inline' = in-process, "
                                                            "no Dask (quasi-static indentation then stores each "
                                                            "curve when it is finished); 'local' = a LocalCluster. "
                                                            "Default: [dask] of the file, else 'local'."),
    workers: int = typer.Option(None, "--workers", min=1, help="LocalCluster worker processes (default: [dask] "
                                                               "n_workers, else 1 on cuda / core count on cpu)."),
    limit: int = typer.Option(None, "--limit", min=0, help="Run at most N pending samples, then stop (resume "
                                                           "later with the same command)."),
    dry_run: bool = typer.Option(False, "--dry-run", help="Print the design and what is pending; simulate "
                                                          "nothing."),
    device: str = typer.Option(None, "--device", help="Override [campaign].device: cpu, cuda or cuda:N."),
    store: Path = typer.Option(None, "--store", help="Override [campaign].store (campaign store directory)."),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Show the progress bar with ETA."),
    diameter: list[float] = typer.Option(None, "--diameter", help="Run only this diameter [um] of a "
                                                                  "multi-diameter design (repeatable)."),
    tier_setting: list[str] = typer.Option(None, "--tier-setting", help="KEY=VALUE (TOML value) on top of the "
                                           "file's [tier], e.g. first_load_ramp=6 (repeatable). Changes the design: "
                                           "give a fresh --store."),
) -> None:
    """Run a training-data campaign: a seeded design over a prior box, simulated on Dask, appended to a
    resumable store (one record per sample). Re-running continues where it stopped; a killed worker is
    rescheduled. On a SLURM cluster start a dask_jobqueue.SLURMCluster, cluster.scale(jobs=N), and pass
    --scheduler tcp://... (see `python -c "import bubblecal.workflows.cli_sim as m; print(m.__doc__)"`).
    Exit 1 on a bad configuration.
    \f

    Prints the run's and the store's status counts, the wall / compute seconds, and last one JSON line
    (:meth:`bubblecal.campaigns.CampaignSummary.as_dict`); ``--dry-run`` prints the design tables only.

    Parameters
    ----------
    config : str
        Campaign TOML file or shipped campaign name (:func:`bubblecal.campaigns.available_campaigns`).
    scheduler : str, optional
        Dask scheduler address, 'inline' or 'local' (default: the file's [dask], else 'local').
    workers : int, optional
        LocalCluster worker processes.
    limit : int, optional
        Run at most this many pending samples.
    dry_run : bool
        Print the design and what is pending; simulate nothing.
    device : str, optional
        Overrides [campaign].device ('cpu', 'cuda' or 'cuda:N').
    store : Path, optional
        Overrides [campaign].store (campaign store directory).
    progress : bool
        Show the progress bar.
    diameter : list of float, optional
        Run only these diameters [um] of a multi-diameter design.
    tier_setting : list of str, optional
        ``KEY=VALUE`` [tier] overrides (a different design).

    Raises
    ------
    typer.Exit
        Code 1 on an invalid file, option or store, or a campaign that stops on task errors.
    """
    from bubblecal.campaigns import (
        CampaignConfigError,
        CampaignError,
        CampaignFileError,
        design_progress,
        load_campaign_file,
        parse_tier_settings,
        run_campaign,
    )
    from bubblecal.data import StoreError

    try:
        overrides = parse_tier_settings(tier_setting or [])
    except ValueError as exc:
        raise fail(str(exc)) from None
    try:
        cf = load_campaign_file(config, store=store, tier_overrides=overrides)
        if device is not None:
            cf = dataclasses.replace(cf, config=dataclasses.replace(cf.config, device=device))
    except CampaignFileError as exc:
        given = [k for k in overrides if exc.key in (f"[tier].{k}", "[tier]")]
        raise fail(str(exc) + (f" (given with --tier-setting {given[0]}=...)" if given else "")) from None
    except CampaignConfigError as exc:
        raise fail(f"--device: {exc.detail}") from None
    c = cf.config
    if c.protocol == "indentation" and "indentation_convention" not in c.tier_settings:
        # the tiers' default predates the Mirheo convention; a new design most likely wants the shipped one
        from rich.markup import escape

        console.print(f"[yellow]note[/]: {escape(str(cf.path))}: \\[tier].indentation_convention is not set, so "
                      "this indentation campaign uses the tiers' default 'bubblecal-v1' (1 % of the vertices loaded "
                      "per pole, kernel k_b x 2/3); the published Mirheo curves and the shipped SonoVue sets and "
                      "surrogates use 'mirheo' (set indentation_convention = \"mirheo\" under \\[tier])",
                      highlight=False)
    if dry_run:
        try:
            where = design_progress(c)
        except StoreError as exc:
            raise fail(str(exc)) from None
        note = {"new": "(not created yet)", "exists": "(exists)",
                "other_design": "(EXISTS WITH ANOTHER DESIGN: a run would refuse it)"}[where.state]
        _design_tables(cf, where, note)
        console.print("[dim]dry run: nothing simulated[/]")
        return
    try:
        summary = run_campaign(c, scheduler_address=scheduler or cf.scheduler_address,
                               n_workers=workers or cf.n_workers, limit=limit, progress=progress,
                               diameters=diameter or None)
    except CampaignConfigError as exc:
        raise fail(f"--diameter: {exc.detail}") from None
    except (CampaignError, StoreError) as exc:
        raise fail(str(exc)) from None
    _status_table(f"campaign {c.name}: this run ({summary.n_written} samples, {summary.n_tasks} tasks)",
                  summary.counts)
    _status_table(f"store {c.store} (latest record per sample)", summary.store_counts)
    console.print(f"wall {summary.wall_seconds:.1f} s (+ {summary.startup_seconds:.1f} s cluster start), "
                  f"task compute {summary.compute_seconds:.1f} s on {summary.n_workers} worker(s): "
                  f"overhead {100 * summary.overhead_fraction:.1f} %; remaining {summary.n_remaining} of "
                  f"{summary.n_design}")
    for err in summary.task_errors[:5]:
        console.print(f"[yellow]task error[/]: {err}", markup=True, highlight=False)
    console.print(json.dumps(summary.as_dict()), markup=False, highlight=False, soft_wrap=True)


@app.command("campaign-status")
def campaign_status(store: Path = typer.Argument(..., help="Campaign store directory (or .jsonl file)."),
                    config: str = typer.Option(None, "--config", help="Campaign TOML or shipped name whose "
                                               "retry_statuses define 'pending' (default: the store's own)."),
                    ) -> None:
    """Counts by status (latest record per sample) and what is still pending; exit 1 if STORE is unreadable.
    \f

    Prints the status table, the pending count, and last one JSON line
    (:meth:`bubblecal.campaigns.StoreStatus.as_dict`).

    Parameters
    ----------
    store : Path
        Campaign store directory or bare .jsonl file.
    config : str, optional
        Campaign TOML or shipped name whose retry statuses (and unstable-retry rule) define 'pending'.

    Raises
    ------
    typer.Exit
        Code 1 when the store is missing or unreadable, or the config is invalid.
    """
    from bubblecal.campaigns import CampaignFileError, load_campaign_file, pending_indices, store_status
    from bubblecal.data import CampaignStore, StoreError

    if not store.exists():
        raise fail(f"{store}: no such campaign store")
    try:
        cfg = None if config is None else load_campaign_file(config, store=store).config
        st = store_status(store, retry_statuses=None if cfg is None else cfg.retry_statuses)
        if cfg is not None:  # the config's own rule (e.g. 'unstable' only re-runs with a larger FIRE budget)
            st = dataclasses.replace(st, pending=len(pending_indices(cfg, CampaignStore(store))))
    except (StoreError, FileNotFoundError, CampaignFileError) as exc:
        raise fail(str(exc)) from None
    _status_table(f"campaign store {store}" + (f" (campaign {st.name})" if st.name else ""), st.counts)
    pending = "unknown (no campaign header)" if st.n_pending is None else f"{st.n_pending} of {st.n_design}"
    console.print(f"pending (no record, or {'/'.join(st.retry_statuses)}): {pending}; "
                  f"{st.n_records} records, {st.n_lines_skipped} unreadable line(s) skipped")
    console.print(json.dumps(st.as_dict()), markup=False, highlight=False, soft_wrap=True)


@app.command("ringdown")
def ringdown(
    agent: str = typer.Option(..., "--agent", help="definity or sonovue (sets k_b and the k_a range)."),
    diameter: float = typer.Option(..., "--diameter", help="Bubble diameter [um]."),
    out: Path = typer.Option(..., "--out", help="Output folder (CSV, JSON, PNG, traces .npz)."),
    n_ka: int = typer.Option(28, "--n-ka", help="Number of k_a values over the agent's acoustic prior range."),
    ka_min: float = typer.Option(None, "--ka-min", help="Lowest k_a [DPD] (default: prior range)."),
    ka_max: float = typer.Option(None, "--ka-max", help="Highest k_a [DPD] (default: prior range)."),
    tier: str = typer.Option("implicit", "--tier", help="implicit (shell-mass-only inertia, physics.md check 7) "
                             "or explicit (water + gas particles)."),
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
    if tier not in ("implicit", "explicit"):
        raise typer.BadParameter("tier must be 'implicit' or 'explicit'", param_hint="--tier")
    if agent.lower() not in ("definity", "sonovue"):
        raise typer.BadParameter("agent must be 'definity' or 'sonovue'", param_hint="--agent")
    if n_ka < 3:
        raise typer.BadParameter("need at least 3 k_a values for a quadratic", param_hint="--n-ka")
    import warp as wp

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
