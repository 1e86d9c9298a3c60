"""How ``bubblecal calibrate`` runs its agents: one progress display over every agent (phases, and the running
TMCMC phase's stages), agents in worker processes when several run at once, each summary printed as it finishes.
"""

from __future__ import annotations

import time

from rich.markup import escape

from bubblecal.workflows.console import console, fail

__all__ = ["run_agents"]


class _PhaseProgress:
    """A rich progress bar over the phases of one agent, fed by run_staged's progress messages, and a line
    for the running TMCMC phase's stages (stage, beta, ESS, acceptance, log Z so far; the bar is beta)."""

    def __init__(self, progress, total: int, label: str, *, prefix: bool = False):
        """Add a task of ``total`` phases labelled ``label`` to the rich ``progress``; ``prefix``: printed lines
        start with the label (agents running at once)."""
        self.progress = progress
        self.task = progress.add_task(label, total=total)
        self.stage_task = None
        self.label = label
        self.prefix = f"{label}: " if prefix else ""
        self.t0 = time.perf_counter()

    def stage(self, replica: int, row) -> None:
        """Show one TMCMC stage row (the reporter of ``TMCMC(progress=...)``)."""
        from bubblecal.inference.tmcmc import stage_text

        if self.stage_task is None:
            self.stage_task = self.progress.add_task("", total=1.0)
        self.progress.update(self.stage_task, completed=min(float(row["beta"]), 1.0),
                             description=f"  {escape(self.prefix)}TMCMC {escape(stage_text(row))}")

    def __call__(self, message: str) -> None:
        """Show ``message``; a message that ends a phase advances the bar and is printed."""
        done = not message.endswith(("running TMCMC", "draws)")) and ": running" not in message
        self.progress.update(self.task, description=f"{self.label}: {message}", advance=1 if done else 0)
        if done:
            self.progress.console.print(f"  {escape(self.prefix + message)}", highlight=False)


def run_agents(plan, jobs: int, cache: bool, workers=None) -> None:
    """Run the agents of a validated plan under one progress display, each agent's summary printed as it finishes.

    Parameters
    ----------
    plan : bubblecal.workflows.calibrate.Plan
        Checked without its preflight (``make_plan(config, check_likelihoods=False)``): each process runs the
        preflight of its own agents, and none samples before all passed. Its configuration's sampler sets the
        phases a bar counts, its ``figures`` whether each agent's figures and ``report.md`` are drawn.
    jobs : int
        Processes (:func:`~bubblecal.workflows.calibrate.agent_jobs`); above 1, groups of agents run in worker
        processes and the costliest group in this one.
    cache : bool
        The workers switch the persistent compilation cache on, as this process did.
    workers : bubblecal.workflows.calibrate.AgentProcesses or None
        Workers prestarted by the caller (:meth:`~bubblecal.workflows.calibrate.AgentProcesses.prestart`), given
        their agents here (those not needed end); None: spawned here when needed.

    Raises
    ------
    typer.Exit
        Exit status 1 (message printed): a preflight failed, or an agent failed (every failed agent named, with
        the folder keeping its finished phases).
    """
    import dataclasses

    from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    from bubblecal.workflows.calibrate import (
        AgentProcesses,
        CalibrationError,
        agent_groups,
        late_modules,
        outcome_of,
        preload_soon,
        run_agent_with_report,
    )
    from bubblecal.workflows.calibrate.preflight import preflight

    figures, sampler = plan.config.figures, plan.config.sampler
    groups = agent_groups({ap.agent: len(ap.curves) + len(ap.acoustic) for ap in plan.agents}, jobs)
    own = dataclasses.replace(plan, agents=[ap for ap in plan.agents if ap.agent in groups[0]])
    if len(groups) > 1 and workers is None:
        workers = AgentProcesses(cache=cache)
    elif len(groups) == 1 and workers is not None:
        workers.dismiss()
        workers = None

    def warn(message: str) -> None:
        console.print(f"[yellow]warning:[/] {escape(message)}", highlight=False)

    failures: dict[str, str] = {}
    try:
        if workers is not None:
            workers.start(plan.config, groups[1:])  # they plan and check their agents while this one checks its own
        try:
            preflight(own)
            if workers is not None:
                preload_soon(late_modules(plan.config.device))  # needed later: while the workers finish their preflight
                workers.wait_ready(on_warning=warn)
        except CalibrationError as exc:
            raise fail(str(exc)) from None
        with Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/"
                      "{task.total} phases"), TimeElapsedColumn(), console=console, transient=True) as progress:
            reporters = {ap.agent: _PhaseProgress(progress, 2 * len(ap.dataset_names) + 1 if sampler == "tmcmc"
                                                  else 1, ap.agent, prefix=workers is not None)
                         for ap in plan.agents}
            listener = None
            if workers is not None:
                workers.go()
                listener = workers.listen(lambda a, m: reporters[a](m), lambda a, r, row: reporters[a].stage(r, row),
                                          on_warning=warn, on_done=lambda a, o: _print_outcome(o, figures))
            for ap in own.agents:
                try:
                    result = run_agent_with_report(plan, ap, progress=reporters[ap.agent],
                                                   stages=reporters[ap.agent].stage)
                except RuntimeError as exc:
                    failures[ap.agent] = str(exc)
                    if workers is None:
                        break  # one after the other: the first failure ends the run, as it always did
                    continue
                _print_outcome(outcome_of(result), figures)
            if listener is not None:
                listener.join()
                failures.update(workers.failures)
    finally:
        if workers is not None:
            workers.stop()
    if failures:
        where = {ap.agent: ap.out_dir for ap in plan.agents}
        raise fail("; ".join(f"{a}: {msg} (finished phases are kept in {where[a]})" for a, msg in failures.items()))


def _print_outcome(outcome, figures: bool) -> None:
    """Print one finished agent: its summary table, phase-2 ESS and where its files are."""
    from bubblecal.workflows.report import summary_table

    console.print(summary_table(outcome))
    if outcome.ess is not None:
        console.print("phase-2 IS-ESS (median per dataset): " + ", ".join(
            f"{r.dataset} {r.ess_median:.0f}" for r in outcome.ess.itertuples()), highlight=False)
    console.print(f"{outcome.plan.agent}: wrote {outcome.plan.out_dir} (summary.csv"
                  + (", figures/, report.md" if figures else "") + f"); reused phases: "
                  f"{', '.join(outcome.reused) or 'none'}; {outcome.seconds['sampling_total']:.1f} s sampling",
                  highlight=False)
