"""``bubblecal calibrate`` (the main job), ``bubblecal evidence`` and ``bubblecal confirm``.

Heavy imports (jax, numpyro, arviz, matplotlib, warp) happen inside the command functions. Exit status:
0 on success, 1 on bad inputs (reported before any sampling) or a failed run.
"""

from __future__ import annotations

import contextlib
import time
from pathlib import Path

import typer
from rich.markup import escape

from bubblecal._extras import require
from bubblecal.data import AGENTS
from bubblecal.workflows.calibrate import (
    DEFAULT_PHASE2_SAMPLES,
    DEFAULT_POPULATION,
    MAX_AUTO_JOBS,
    PAPER_POPULATION,
    PHASE2_DRAW_BUDGET,
    AgentProcesses,
    CalibrationConfig,
    CalibrationError,
    agent_jobs,
    gpu_memory_shared,
)
from bubblecal.workflows.choices import (
    ALL_AGENTS,
    AgentOrAll,
    JaxDevice,
    Networks,
    Phase3,
    Phase3Start,
    Sampler,
    Surrogates,
    Tier,
    Workflow,
    choice_value,
)
from bubblecal.workflows.cli_agents import run_agents
from bubblecal.workflows.confirm import DEFAULT_TIER
from bubblecal.workflows.console import console, fail
from bubblecal.workflows.evidence import DEFAULT_REPLICAS, PARETO_K_LIMIT

#: The defaults of ``calibrate`` (and of the options ``evidence`` shares with it): one source of truth.
_D = CalibrationConfig()


def calibrate(
    agent: AgentOrAll = typer.Option(ALL_AGENTS, "--agent", case_sensitive=False, help="Contrast agent(s)."),
    workflow: Workflow = typer.Option(None, "--workflow", help=f"Priors set and data (default {_D.workflow}; with "
                                      "--data: reduced-acoustic with --acoustic, else reduced).", show_default=False),
    sampler: Sampler = typer.Option(_D.sampler, "--sampler", help="tmcmc (staged phases 1-2-3) | nuts (joint "
                                    "model)."),
    population: int = typer.Option(_D.population, "--population", help="TMCMC particles per phase (default "
                                   f"{DEFAULT_POPULATION}; --paper: {PAPER_POPULATION})."),
    paper: bool = typer.Option(_D.paper, "--paper", help="Published settings: N = 50,000, CoV 0.8/0.6, scaling "
                               "0.04."),
    out: Path = typer.Option(_D.out, "--out", help="Output folder (OUT/<agent>/<workflow>/...)."),
    device: JaxDevice = typer.Option(_D.device, "--device", help="JAX device."),
    bundle: Path = typer.Option(_D.bundle, "--bundle", help="Surrogate bundle directory (default: the shipped one)."),
    force: bool = typer.Option(_D.force, "--force", help="Rerun finished phases instead of reusing them."),
    seed: int = typer.Option(_D.seed, "--seed"),
    priors: list[str] = typer.Option(None, "--priors", metavar="[LABEL=]FILE",
                                     help="Your priors TOML instead of the shipped ones: FILE (one --agent, or every "
                                     "agent of --data) or LABEL=FILE for one agent of --data (repeatable)."),
    data: Path = typer.Option(None, "--data", help="Tidy curves CSV of your bubbles (bubble, agent, protocol, "
                              "diameter_um, displacement_nm, force_nN[, retained]): one hierarchy per agent label "
                              "instead of the published study (check it first: bubblecal data check FILE)."),
    acoustic: Path = typer.Option(None, "--acoustic", help="Tidy resonance CSV for the agents of --data (agent, "
                                  "diameter_um, frequency_MHz[, source])."),
    networks: Networks = typer.Option(_D.networks, "--networks", help="Where the networks over the diameter serve "
                                      "(--data, or the published study unless --surrogates per-diameter): the "
                                      "bundle's fast ones (cheaper per point) or its accurate ones."),
    surrogates: Surrogates = typer.Option(_D.surrogates, "--surrogates", help="Published study: the networks over "
                                          "the diameter and the acoustic laws (over-diameter, the default, also "
                                          "with --paper) or the files fitted at each published diameter "
                                          "(per-diameter: with --paper, the paper's exact set-up).",
                                          show_default=False),
    data_dir: Path = typer.Option(_D.data_dir, "--data-dir", help="Folder of curve CSVs (DPD units) named like the "
                                  "shipped ones, e.g. definity_compression_2.1um_dpd.csv, and/or "
                                  "acoustic_observations_published.csv, replacing them."),
    curve: list[str] = typer.Option(None, "--curve", help="Only these curves (repeatable), e.g. "
                                    "definity_compression_2.1um."),
    phase2_samples: int = typer.Option(_D.phase2_samples, "--phase2-samples", help="Phase-1 draws per dataset in "
                                       f"phase 2 (default min(N, {DEFAULT_PHASE2_SAMPLES}), at most "
                                       f"{PHASE2_DRAW_BUDGET:,} over all datasets)."),
    mcmc_steps: int = typer.Option(_D.num_mcmc_steps, "--mcmc-steps", help="Random-walk MH steps per TMCMC stage."),
    chunk_size: int = typer.Option(_D.chunk_size, "--chunk-size", help="TMCMC particles evaluated at a time "
                                   "(default: 512 on a CPU, all at once on a GPU)."),
    nuts_samples: int = typer.Option(_D.nuts_samples, "--nuts-samples", help="NUTS draws per chain (--sampler nuts)."),
    nuts_chains: int = typer.Option(_D.nuts_chains, "--nuts-chains"),
    netcdf: bool = typer.Option(_D.netcdf, "--netcdf/--npz", help="Phase files as ArviZ NetCDF (else .npz)."),
    figures: bool = typer.Option(_D.figures, "--figures/--no-figures", help="Draw figures and report.md."),
    phase3: Phase3 = typer.Option(_D.phase3, "--phase3", help="published (Korali: population prior over p(psi | D), "
                               "which holds the curve's own data) | exact (leave-one-out psi weights: the joint "
                               "model's per-bubble marginal)."),
    phase3_start: Phase3Start = typer.Option(_D.phase3_start, "--phase3-start", help="phase1 (phase 3 starts from "
                                             "the curve's phase-1 draws and tempers only the population prior) | "
                                             "prior (from the uniform prior, as Korali): the same posterior and "
                                             "evidence."),
    cache: bool = typer.Option(True, "--cache/--no-cache", help="Keep compiled programs in the user's cache "
                               "folder for later runs (or $BUBBLECAL_CACHE_DIR)."),
    jobs: int = typer.Option(None, "--jobs", help="Agents calibrated at once, each group in its own process "
                             "(default: one per agent, up to the usable cores and "
                             f"{MAX_AUTO_JOBS}; 1: one after the other). The results do not depend on it.",
                             show_default=False),
) -> None:
    """Calibrate the shell parameters of your bubbles (--data CURVES.csv [--acoustic FREQS.csv], one hierarchy per
    agent label) or of the published study (Definity and/or SonoVue on the shipped curves): staged hierarchical
    TMCMC (or joint NUTS); writes NetCDF per phase, summary.csv, figures and report.md under
    OUT/<agent>/<workflow>/. Finished phases are reused on rerun."""
    agent, workflow, sampler, device, phase3, phase3_start, networks, surrogates = (
        choice_value(o) for o in (agent, workflow, sampler, device, phase3, phase3_start, networks, surrogates))
    if workflow is None:
        workflow = _D.workflow if data is None or acoustic is not None else "reduced"
    agents = AGENTS if agent == ALL_AGENTS else (agent,)
    try:  # before JAX starts: the processes that may share the GPU (--data: its labels are not read yet)
        gpu_memory_shared(device, agent_jobs(jobs, len(agents) if data is None else MAX_AUTO_JOBS))
    except CalibrationError as exc:
        raise fail(str(exc)) from None
    if device == "gpu":  # in the environment before the workers start: they inherit it
        from bubblecal.workflows.compile_cache import skip_gpu_autotuning

        skip_gpu_autotuning()
    # the published agents are known (a --curve filter may leave some without datasets): their workers start
    # (interpreter, imports, device) while this process imports JAX and plans (nothing imported so far loads JAX)
    workers = AgentProcesses(cache=cache, device=device)
    if data is None and not curve:
        workers.prestart(agent_jobs(jobs, len(agents)) - 1)
    try:
        from bubblecal.workflows.calibrate import make_plan, run_lock

        _compilation_cache(cache, device)
        priors_map = _priors_map(list(priors or ()), agents, data)
        try:
            config = CalibrationConfig(agents=agents, workflow=workflow, sampler=sampler, population=population,
                                       paper=paper, out=out, device=device, bundle=bundle, force=force, seed=seed,
                                       priors=priors_map, data_dir=data_dir, data=data, acoustic_data=acoustic,
                                       networks=networks, surrogates=surrogates, curves=tuple(curve or ()),
                                       phase2_samples=phase2_samples, chunk_size=chunk_size, num_mcmc_steps=mcmc_steps,
                                       nuts_samples=nuts_samples, nuts_warmup=nuts_samples, nuts_chains=nuts_chains,
                                       netcdf=netcdf, figures=figures, phase3=phase3, phase3_start=phase3_start)
            plan = make_plan(config, check_likelihoods=False)  # every input checked; the preflight runs per process
        except CalibrationError as exc:
            raise fail(str(exc)) from None
        if plan.synthetic_bundle:
            console.print(f"[bold yellow]warning:[/] {plan.bundle_path} is a SYNTHETIC bundle (closed-form laws, "
                          "not DPD): the posteriors are not physical results", highlight=False)
        from bubblecal.workflows.calibrate import served_lines

        for ap in plan.agents:
            for line in served_lines(ap, plan.bundle):
                console.print(f"surrogates: {escape(ap.agent)}: {escape(line)}", highlight=False)
            for note in ap.notes:
                console.print(f"[cyan]note:[/] {escape(ap.agent)}: {escape(note)}", highlight=False)
            for msg in ap.domain_warnings[:5]:
                console.print(f"[yellow]warning:[/] {ap.agent}: surrogate domain: {escape(msg)}", highlight=False)
        names = [ap.agent for ap in plan.agents]
        what = (f"{sum(len(ap.curves) for ap in plan.agents)} bubbles of {data}, agents {', '.join(names)}"
                if data is not None else f"agents {', '.join(names)}")
        console.print(f"calibrate: {what}, workflow {workflow}, sampler {sampler}, "
                      f"N = {config.num_particles} per phase, device {device}, bundle {plan.bundle_path}, out {out}",
                      highlight=False)
        t_all = time.perf_counter()
        with contextlib.ExitStack() as stack:  # one run per output folder (a second one stops here, named)
            try:
                stack.enter_context(run_lock(Path(out), say=lambda m: console.print(f"[yellow]note:[/] {escape(m)}",
                                                                                    highlight=False)))
            except CalibrationError as exc:
                raise fail(str(exc)) from None
            run_agents(plan, agent_jobs(jobs, len(plan.agents)), cache, workers)
        console.print(f"done in {time.perf_counter() - t_all:.1f} s", highlight=False)
    finally:
        workers.stop()


def _priors_map(entries: list[str], agents: tuple[str, ...], data: Path | None) -> dict[str, str]:
    """``--priors`` values -> {agent: file}: ``FILE`` for the single ``--agent`` (or every agent of ``--data``),
    ``LABEL=FILE`` for one agent of ``--data``."""
    from bubblecal.workflows.calibrate import PRIORS_FOR_ALL

    out: dict[str, str] = {}
    for entry in entries:
        label, sep, path = entry.partition("=")
        if sep and data is None:
            raise fail(f"--priors {entry}: LABEL=FILE names an agent of --data CURVES.csv; without --data give "
                       "--priors FILE with one --agent")
        if not sep:
            label, path = (PRIORS_FOR_ALL if data is not None else None), entry
            if label is None and len(agents) != 1:
                raise fail("--priors FILE needs a single --agent (definity or sonovue)")
            label = label or agents[0]
        if not label or not path:
            raise fail(f"--priors {entry!r}: give FILE or LABEL=FILE")
        if label in out:
            raise fail(f"--priors: two files for {'every agent' if label == PRIORS_FOR_ALL else label} "
                       f"({out[label]}, {path})")
        out[label] = path
    return out


def _compilation_cache(on: bool, device: str) -> None:
    """Switch the persistent compilation cache on (``--cache``; its problems print as one warning line) and, on a
    GPU, XLA's heuristic matmul kernels (:func:`~bubblecal.workflows.compile_cache.skip_gpu_autotuning`)."""
    if device == "gpu":
        from bubblecal.workflows.compile_cache import skip_gpu_autotuning

        skip_gpu_autotuning()
    if on:
        from bubblecal.workflows.compile_cache import enable_compilation_cache

        enable_compilation_cache(say=lambda m: console.print(f"[yellow]warning:[/] {escape(m)}", highlight=False))


def evidence(
    agent: AgentOrAll = typer.Option(ALL_AGENTS, "--agent", case_sensitive=False, help="Contrast agent(s)."),
    population: int = typer.Option(DEFAULT_POPULATION, "--population", help="TMCMC particles per run."),
    replicas: int = typer.Option(DEFAULT_REPLICAS, "--replicas", help="Independent TMCMC runs per model (ln Z ± SE)."),
    curve: list[str] = typer.Option(None, "--curve", help="Only these curves (repeatable)."),
    out: Path = typer.Option(_D.out, "--out", help="Output root: OUT/<agent>/evidence.csv."),
    bundle: Path = typer.Option(_D.bundle, "--bundle", help="Surrogate bundle directory (default: the shipped one)."),
    device: JaxDevice = typer.Option(_D.device, "--device", help="JAX device."),
    seed: int = typer.Option(_D.seed, "--seed"),
    surrogates: Surrogates = typer.Option(_D.resolved_surrogates, "--surrogates", help="The networks over the "
                                          "diameter (over-diameter, calibrate's default) or the per-diameter files "
                                          "(per-diameter, the paper's set-up); give the calibration's own, since "
                                          "its report shows the evidence beside it."),
    networks: Networks = typer.Option(_D.networks, "--networks", help="With --surrogates over-diameter: the fast "
                                      "or the accurate networks."),
    cache: bool = typer.Option(True, "--cache/--no-cache", help="Keep compiled programs in the user's cache "
                               "folder for later runs (or $BUBBLECAL_CACHE_DIR)."),
) -> None:
    """ln Z of the full and the reduced shell per curve (TMCMC, replica mean ± SE), the Bayes factor
    ln B = ln Z_full − ln Z_reduced ± error and its Kass–Raftery verdict, beside PSIS-LOO (elpd_loo ± SE,
    p_loo, points with Pareto k > 0.7, az.compare); CSV + table (and in report.md)."""
    from bubblecal.inference.tmcmc import StageDisplay
    from bubblecal.surrogates import load_bundle
    from bubblecal.workflows.calibrate import CalibrationError, check_device, resolve_bundle
    from bubblecal.workflows.console import make_table
    from bubblecal.workflows.evidence import run_evidence

    agent, device, surrogates, networks = (choice_value(o) for o in (agent, device, surrogates, networks))
    lookup = CalibrationConfig(surrogates=surrogates, networks=networks).surrogate_lookup()
    _compilation_cache(cache, device)
    agents = AGENTS if agent == ALL_AGENTS else (agent,)
    if population < 100 or replicas < 2:
        raise fail(f"--population must be >= 100 and --replicas >= 2 (for an error bar), got {population}, {replicas}")
    try:
        check_device(device)
        bundle_dir = resolve_bundle(bundle)
        b = load_bundle(bundle_dir)
        for a in agents:
            from bubblecal.data import reference_curves

            for c in reference_curves(a):
                b.get(c.kind, c.diameter_um, **lookup)
    except (CalibrationError, KeyError) as exc:
        raise fail(str(exc.args[0] if isinstance(exc, KeyError) else exc)) from None
    display = StageDisplay("TMCMC", num_replicas=replicas, console=console)
    try:
        df = run_evidence(agents, b, population=population, replicas=replicas, seed=seed, device=device, out=out,
                          curves=tuple(curve or ()), progress=lambda m: console.print(f"  {m}", highlight=False),
                          stages=display, surrogates=surrogates, networks=networks)
    finally:
        display.close()
    table = make_table("Model evidence per curve: full vs reduced shell (ln Z, Bayes factor; PSIS-LOO)",
                       ("curve", "ln Z full", "ln Z reduced", "ln B (full - reduced)", "verdict", "elpd_loo full",
                        "elpd_loo reduced", f"Pareto k > {PARETO_K_LIMIT} (full, reduced)", "LOO compare"))
    for r in df.itertuples():
        table.add_row(r.curve, f"{r.log_z_full:.3f} ± {r.log_z_full_se:.3f}",
                      f"{r.log_z_reduced:.3f} ± {r.log_z_reduced_se:.3f}",
                      f"{r.ln_bayes_factor:.3f} ± {r.ln_bayes_factor_se:.3f}", r.verdict,
                      f"{r.elpd_loo_full:.2f} ± {r.elpd_loo_full_se:.2f} (p_loo {r.p_loo_full:.1f})",
                      f"{r.elpd_loo_reduced:.2f} ± {r.elpd_loo_reduced_se:.2f} (p_loo {r.p_loo_reduced:.1f})",
                      f"{r.pareto_k_bad_full}, {r.pareto_k_bad_reduced}",
                      f"{r.loo_favours} by {r.elpd_diff:.2f} ± {r.elpd_diff_se:.2f}")
    console.print(table)
    console.print(f"wrote {', '.join(str(Path(out) / a / 'evidence.csv') for a in agents)}", highlight=False)


def confirm(
    results: Path = typer.Argument(..., help="A calibration output folder (OUT, OUT/<agent> or "
                                   "OUT/<agent>/<workflow>)."),
    tier: Tier = typer.Option(DEFAULT_TIER, "--tier", help="DPD fidelity tier."),
    device: str = typer.Option("cuda", "--device", help="Warp device: cuda | cpu"),
    subdivisions: int = typer.Option(None, "--subdivisions", help="Icosphere level (default: the tier's)."),
    scale: float = typer.Option(None, "--scale", min=0.01, max=1.0,
                                help="explicit / implicit tiers: multiply every MD step count of the protocol "
                                     "(ramp, hold, averaging; 1 = the published protocol, 0.25 = the gate runs')."),
) -> None:
    """Re-simulate each curve's phase-3 MAP with a DPD tier and overlay simulation, surrogate and data
    (PNG + CSV + relative L2 table under RUN/confirm/)."""
    from bubblecal.workflows.confirm import confirm_run, find_runs
    from bubblecal.workflows.console import make_table

    tier = choice_value(tier)
    if scale is not None and tier not in ("explicit", "implicit"):
        raise fail(f"--scale {scale:g}: only the explicit and implicit tiers run MD protocols (tier is {tier!r})")
    require("warp", "sim")  # the DPD tiers: checked before any run folder is touched
    require("trimesh", "sim")
    runs = find_runs(results)
    if not runs:
        raise fail(f"{results}: no calibration run folder (manifest.json) found")
    for run in runs:
        try:
            settings = {"scale": scale} if scale is not None and tier in ("explicit", "implicit") else None
            pts, summ, fig = confirm_run(run, tier=tier, device=device, subdivisions=subdivisions,
                                         tier_settings=settings,
                                         progress=lambda m: console.print(f"  {m}", highlight=False))
        except ValueError as exc:
            raise fail(f"{run}: {exc}") from None
        table = make_table(f"{run}: {tier} tier at the MAP, relative L2", ("curve", "status", "sim vs surrogate",
                                                                           "sim vs data", "surrogate vs data", "s"))
        for r in summ.itertuples():
            table.add_row(r.curve, r.status, f"{r.rel_l2_sim_vs_surrogate:.3f}", f"{r.rel_l2_sim_vs_data:.3f}",
                          f"{r.rel_l2_surrogate_vs_data:.3f}", f"{r.seconds:.1f}")
        console.print(table)
        if fig is not None:
            console.print(f"wrote {fig}", highlight=False)


def register(app: typer.Typer) -> None:
    """Add ``calibrate``, ``evidence`` and ``confirm`` to the root command."""
    app.command("calibrate")(calibrate)
    app.command("evidence")(evidence)
    app.command("confirm")(confirm)
