"""Per-stage progress of a TMCMC run: the reporter interface and its rich display.

:class:`~bubblecal.inference.tmcmc.TMCMC` reports every row of its stage table, as soon as the stage is
back on the host, to a reporter ``report(replica, row)``; ``row`` is a mapping with the columns of
:data:`~bubblecal.inference.tmcmc.results.STAGE_COLUMNS` (stage, beta, ess, acceptance, log_evidence = log Z
so far, ...). ``progress=True`` selects :class:`StageDisplay` (one rich line per run); any callable is a
reporter of its own (a command line's shared display, a log). Reporting reads finished numbers only, so the
draws are the same with and without it. A ``compiled=True`` run reports its stages when the run ends.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

from bubblecal._progress import ProgressLine

__all__ = ["StageReporter", "StageDisplay", "stage_text", "stage_reporter"]

#: A reporter: ``report(replica, row)`` with the replica index and one row of the stage table.
StageReporter = Callable[[int, Mapping], None]


def stage_text(row: Mapping) -> str:
    """One line for a stage: stage, β, ESS, acceptance and log Z so far.

    Parameters
    ----------
    row : mapping
        A row of the stage table (keys ``stage``, ``beta``, ``ess``, ``acceptance``, ``log_evidence``).

    Returns
    -------
    str
        E.g. ``'stage 4  beta 0.0312  ESS 1612  acc 0.29  log Z -41.207'`` (acceptance '-' before the first
        move).
    """
    acc = row["acceptance"]
    acc_txt = "-" if not math.isfinite(acc) else f"{acc:.2f}"
    return (f"stage {row['stage']}  beta {row['beta']:.4g}  ESS {row['ess']:.0f}  acc {acc_txt}  "
            f"log Z {row['log_evidence']:.3f}")


class StageDisplay:
    """A rich progress line per TMCMC run: the bar is β from 0 to 1, the text :func:`stage_text`.

    Parameters
    ----------
    label : str
        Name of the run (e.g. the model's), shown before the bar.
    num_replicas : int
        Replicas of the run (the label gains 'replica r/R' when more than one).
    console : rich.console.Console or None
        Where to draw (default: standard output).
    """

    def __init__(self, label: str, num_replicas: int = 1, console=None):
        self.label = label
        self.num_replicas = int(num_replicas)
        self._line = ProgressLine(label, total=1.0, console=console)

    def __call__(self, replica: int, row: Mapping) -> None:
        """Show ``row`` of ``replica`` (the bar restarts at β = 0 for each replica)."""
        name = self.label if self.num_replicas == 1 else f"{self.label} replica {replica + 1}/{self.num_replicas}"
        self._line.update(completed=min(float(row["beta"]), 1.0), info=stage_text(row), description=name)

    def close(self) -> None:
        """Remove the line (idempotent)."""
        self._line.close()


def stage_reporter(progress: bool | StageReporter | None, label: str,
                   num_replicas: int) -> tuple[StageReporter, Callable[[], None]]:
    """The reporter a TMCMC run calls and what ends it, from its ``progress`` setting.

    Parameters
    ----------
    progress : bool, callable or None
        False / None: report nothing; True: a :class:`StageDisplay`; a callable: itself.
    label : str
        Name of the run (for the display).
    num_replicas : int
        Replicas of the run.

    Returns
    -------
    tuple
        ``(report, close)``: ``report(replica, row)`` and ``close()`` (a no-op unless the display was made here).

    Raises
    ------
    ValueError
        If ``progress`` is neither a bool, None nor a callable.
    """
    if progress is None or progress is False:
        return (lambda _replica, _row: None), (lambda: None)
    if progress is True:
        display = StageDisplay(label, num_replicas)
        return display, display.close
    if callable(progress):
        return progress, (lambda: None)
    raise ValueError(f"progress must be True, False or a callable report(replica, row), got {progress!r}")
