"""Shared rich console and error reporting for the command line."""

from __future__ import annotations

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

console = Console()
err_console = Console(stderr=True)


def fail(message: str, code: int = 1) -> typer.Exit:
    """Print ``message`` in red on stderr and return the Exit to raise (exit status ``code``).

    ``message`` is plain text, taken literally: '[fixed]' in a priors problem is not a style tag.
    """
    err_console.print(f"[bold red]error:[/] {escape(message)}", highlight=False, markup=True)
    return typer.Exit(code)


def make_table(title: str, headers: tuple[str, ...] | list[str], caption: str | None = None) -> Table:
    """A rich Table whose headers are taken literally ('[nm]' is a unit, not a style tag)."""
    table = Table(title=escape(title), caption=escape(caption) if caption else None)
    for header in headers:
        table.add_column(escape(header), min_width=min(len(header), 24))
    return table
