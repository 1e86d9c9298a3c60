"""``bubblecal sim campaign`` and ``bubblecal sim campaign-status``: training-data campaigns from the command line.

A thin command line over :mod:`bubblecal.campaigns` (Dask is imported by the runner, inside the command); the
commands are registered on the ``sim`` group by :mod:`bubblecal.workflows.cli_sim`.  A command's docstring up to
the form feed (``\\f``) is its ``--help`` text; the numpydoc sections after it are for readers of the code.

Several GPUs of one machine: ``--gpus N`` starts one Dask worker process per GPU, each pinned to its GPU by
``CUDA_VISIBLE_DEVICES`` (:func:`bubblecal.campaigns.gpu_cluster`)::

    bubblecal sim campaign definity_compression_1.5-8um --store /scratch/d.store --gpus 2

A SLURM cluster (dask-jobqueue, the ``[cluster]`` extra: ``pip install 'bubblecal[cluster]'``; one GPU job per
worker), or any Dask scheduler such as one with ``dask cuda worker`` processes: pass its address::

    python -m bubblecal.campaigns.slurm --jobs 8 --queue gpu      # on the login node; prints tcp://HOST:PORT
    bubblecal sim campaign definity_compression_1.5-8um --store /scratch/d.store --scheduler tcp://HOST:PORT

docs/distributed.md has the whole of it.

Interrupt and re-run the same command at any time: finished samples are skipped, nothing is duplicated.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import typer

from bubblecal.campaigns.scheduler import CONNECT_TIMEOUT_S
from bubblecal.workflows.console import console, fail, make_table

__all__ = ["campaign", "campaign_status"]


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
    diameters = ", ".join(_fmt(d) for d in c.diameters)
    if c.diameter_range_um is not None:
        diameters = (f"{_fmt(c.diameter_range_um[0])} - {_fmt(c.diameter_range_um[1])} (Latin-hypercube dimension, "
                     f"{len(c.diameters)} levels {_fmt(c.diameter_step_um)} apart)")
    loading = ("t, R(t) [DPD time, DPD length]" if grid is None else
               f"{len(grid)} points {_fmt(grid[0])} .. {_fmt(grid[-1])} [{unit}]")
    if c.loading_fractions is not None:
        top = c.grid_for(c.diameters[-1])
        loading = (f"{len(grid)} points, total displacement {_fmt(c.loading_fractions[0])} .. "
                   f"{_fmt(c.loading_fractions[-1])} x diameter ({_fmt(grid[-1])} [DPD length] at "
                   f"{_fmt(c.diameters[0])} um, {_fmt(top[-1])} at {_fmt(c.diameters[-1])} um)")
    rows = [("protocol", c.protocol), ("diameter(s) \\[um]", diameters),
            ("tier", f"{c.tier} {json.dumps(c.tier_settings) if c.tier_settings else '(defaults)'}"),
            ("design", f"{c.design}, seed {c.seed}" + (f", box from priors {cf.priors}" if cf.priors else "")),
            ("design points", str(c.n_design)),
            ("replicas per task", str(c.replicas_per_task)), ("tasks (full run)", str(c.n_tasks)),
            ("device", c.device), ("subdivisions", "mesh default" if c.subdivisions is None else str(c.subdivisions)),
            ("loading grid", loading),
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


def campaign(
    config: str = typer.Argument(..., help="Campaign TOML file, or a shipped campaign name "
                                           "(e.g. definity_compression_2.1um)."),
    scheduler: str = typer.Option(None, "--scheduler", help="Dask scheduler address tcp://HOST:PORT (e.g. of a "
                                                            "dask-jobqueue SLURMCluster); 'inline' = in-process, "
                                                            "no Dask (quasi-static indentation then stores each "
                                                            "curve when it is finished); 'local' = a LocalCluster. "
                                                            "Default: \\[dask] of the file, else 'local'."),
    workers: int = typer.Option(None, "--workers", min=1, help="LocalCluster worker processes (default: \\[dask] "
                                                               "n_workers, else 1 on cuda / core count on cpu)."),
    gpus: int = typer.Option(None, "--gpus", min=1, help="Run on N GPUs of this machine: one Dask worker per GPU, "
                                                         "pinned by CUDA_VISIBLE_DEVICES, each on its cuda:0 (not "
                                                         "with --scheduler, --workers or --device)."),
    limit: int = typer.Option(None, "--limit", min=0, help="Run at most N pending samples, then stop (resume "
                                                           "later with the same command)."),
    dry_run: bool = typer.Option(False, "--dry-run", help="Print the design and what is pending; simulate "
                                                          "nothing."),
    device: str = typer.Option(None, "--device", help="Override \\[campaign].device: cpu, cuda or cuda:N."),
    store: Path = typer.Option(None, "--store", help="Override \\[campaign].store (campaign store directory)."),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Show the progress bar with ETA."),
    diameter: list[float] = typer.Option(None, "--diameter", help="Run only this diameter \\[um] of a "
                                                                  "multi-diameter design (repeatable)."),
    connect_timeout: float = typer.Option(CONNECT_TIMEOUT_S, "--connect-timeout", min=0.1, help="Seconds to wait "
                                          "for a tcp:// scheduler before stopping with its address named."),
    tier_setting: list[str] = typer.Option(None, "--tier-setting", help="KEY=VALUE (TOML value) on top of the "
                                           "file's \\[tier], e.g. first_load_ramp=6 (repeatable). Changes the design: "
                                           "give a fresh --store."),
) -> None:
    """Run a training-data campaign: a seeded design over a prior box, simulated on Dask, appended to a
    resumable store (one record per sample). Re-running continues where it stopped; a killed worker's task is
    re-run elsewhere. Several GPUs here: --gpus N. On a SLURM cluster start `python -m
    bubblecal.campaigns.slurm --jobs N` and pass --scheduler tcp://... (docs/distributed.md). Exit 1 on a bad
    configuration.
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
    gpus : int, optional
        GPUs of this machine, one pinned worker each.
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
    connect_timeout : float
        Seconds to wait for a remote scheduler.
    tier_setting : list of str, optional
        ``KEY=VALUE`` [tier] overrides (a different design).

    Raises
    ------
    typer.BadParameter
        ``--gpus`` with ``--scheduler``, ``--workers`` or ``--device`` (exit code 2).
    typer.Exit
        Code 1 on an invalid file, option or store, a device this machine lacks (more ``--gpus`` than it has), a
        campaign that stops on task errors, or a run whose samples all failed.
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

    if gpus is not None:
        given = [o for o, v in (("--scheduler", scheduler), ("--workers", workers), ("--device", device)) if v]
        if given:
            raise typer.BadParameter(f"--gpus starts one worker per GPU of this machine on its cuda:0, so it does "
                                     f"not go with {' / '.join(given)}", param_hint="--gpus")
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
        local = gpus is None  # --gpus: this machine's GPUs, whatever the file's [dask] says
        summary = run_campaign(c, scheduler_address=scheduler or cf.scheduler_address if local else None,
                               n_workers=workers or cf.n_workers if local else None, limit=limit, progress=progress,
                               diameters=diameter or None, connect_timeout_s=connect_timeout, gpus=gpus)
    except CampaignConfigError as exc:
        option = {"scheduler_address": "--scheduler", "gpus": "--gpus"}.get(exc.field, "--diameter")
        raise fail(f"{option}: {exc.detail}") from None
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
    if summary.all_failed:
        raise fail(f"every one of the {summary.n_written} samples of this run failed (see the records' messages: "
                   f"bubblecal sim campaign-status {c.store}); the next run re-runs those whose status is in "
                   "retry_statuses")


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
