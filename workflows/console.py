"""Shared rich console and error reporting for the command line."""

from __future__ import annotations

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

#: Standard output of every command.
console = Console()
#: Standard error (error messages of :func:`fail`).
err_console = Console(stderr=True)


def fail(message: str, code: int = 1) -> typer.Exit:
    """Print ``message`` in red on stderr and return the Exit to raise.

    Parameters
    ----------
    message : str
        Plain text, taken literally: '[fixed]' in a priors problem is not a style tag.
    code : int
        Exit status.

    Returns
    -------
    typer.Exit
        To be raised by the caller (``raise fail(...)``).
    """
    err_console.print(f"[bold red]error:[/] {escape(message)}", highlight=False, markup=True)
    return typer.Exit(code)


def make_table(title: str, headers: tuple[str, ...] | list[str], caption: str | None = None) -> Table:
    """A rich Table whose title, caption and headers are taken literally ('[nm]' is a unit, not a style tag).

    Parameters
    ----------
    title : str
    headers : sequence of str
        Column headers (each column at least as wide as its header, up to 24 characters).
    caption : str or None

    Returns
    -------
    rich.table.Table
    """
    table = Table(title=escape(title), caption=escape(caption) if caption else None)
    for header in headers:
        table.add_column(escape(header), min_width=min(len(header), 24))
    return table
