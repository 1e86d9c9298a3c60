"""One progress line drawn with rich, or nothing: the package's single progress library.

Every layer that shows progress (surrogate training epochs, a sweep's networks, TMCMC stages, NUTS phases)
draws it through :class:`ProgressLine`; rich is imported only when the line is enabled, so library use stays
quiet and cheap::

    with ProgressLine("train 3x64", total=500, enabled=progress) as line:
        for epoch in range(500):
            ...
            line.update(advance=1, info=f"val {val:.3g}")
"""

from __future__ import annotations

__all__ = ["ProgressLine"]


class ProgressLine:
    """A rich progress bar of one task (description, bar, count, elapsed time, free text), or nothing.

    Parameters
    ----------
    description : str
        Shown before the bar (taken literally: '[nm]' is not a style tag).
    total : float or None
        Length of the bar in the caller's unit (epochs, networks, or 1.0 for a tempering exponent); an int
        also shows 'done/total'; None draws a pulsing bar.
    enabled : bool
        False: every method does nothing and rich is never imported.
    console : rich.console.Console or None
        Where to draw (default: rich's console on standard output); pass the command line's console so that
        its messages and the bar share one screen.
    transient : bool
        Remove the line when closed.
    """

    def __init__(self, description: str, total: float | None = None, *, enabled: bool = True, console=None,
                 transient: bool = True):
        self.enabled = bool(enabled)
        self._bar = None
        if not self.enabled:
            return
        from rich.markup import escape
        from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

        self._escape = escape
        self._bar = Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
                             TextColumn("{task.fields[count]}"), TimeElapsedColumn(), TextColumn("{task.fields[info]}"),
                             console=console, transient=transient)
        self._whole = isinstance(total, int)
        self._bar.start()
        self._task = self._bar.add_task(escape(description), total=total, count=self._count(0, total), info="")

    def _count(self, completed, total) -> str:
        """'k/n' for a whole-number total, else nothing (a fraction such as beta is shown by the caller)."""
        return f"{int(completed)}/{int(total)}" if self._whole and total is not None else ""

    def update(self, *, advance: float | None = None, completed: float | None = None, info: str | None = None,
               description: str | None = None) -> None:
        """Move the bar and/or change its texts (no-op when disabled).

        Parameters
        ----------
        advance : float or None
            Add this to the position (in the unit of ``total``).
        completed : float or None
            Set the position.
        info : str or None
            Free text after the elapsed time (taken literally).
        description : str or None
            New description (taken literally).
        """
        if self._bar is None:
            return
        fields = {}
        if info is not None:
            fields["info"] = self._escape(info)
        if description is not None:
            fields["description"] = self._escape(description)
        self._bar.update(self._task, advance=advance, completed=completed, **fields)
        task = self._bar.tasks[0]
        self._bar.update(self._task, count=self._count(task.completed, task.total))

    def close(self) -> None:
        """Stop drawing (idempotent)."""
        if self._bar is not None:
            self._bar.stop()
            self._bar = None

    def __enter__(self) -> ProgressLine:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
