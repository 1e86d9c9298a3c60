"""The campaign progress bar (samples written, ETA, status counts), or nothing."""

from __future__ import annotations

from collections.abc import Mapping


class _Progress:
    """rich progress bar (samples, ETA, status counts) or nothing; rich is imported only when enabled."""

    def __init__(self, enabled: bool, total: int, name: str):
        self.enabled = enabled and total > 0
        self._bar = None
        if self.enabled:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self._bar = Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                                 TextColumn("samples"), TimeElapsedColumn(), TextColumn("ETA"),
                                 TimeRemainingColumn(), TextColumn("{task.fields[counts]}"))
            self._bar.start()
            self._task = self._bar.add_task(name, total=total, counts="")

    def update(self, n: int, counts: Mapping[str, int]) -> None:
        """Advance by ``n`` samples and show the non-zero status counts."""
        if self._bar is not None:
            text = " ".join(f"{k}={v}" for k, v in counts.items() if v)
            self._bar.update(self._task, advance=n, counts=text)

    def close(self) -> None:
        """Stop the bar (idempotent)."""
        if self._bar is not None:
            self._bar.stop()
            self._bar = None
