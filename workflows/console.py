"""Shared rich console, error reporting and the end of a command's process."""

from __future__ import annotations

import contextlib
import gc
import logging
import os
import sys
from typing import NoReturn

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


def end_process(code: int) -> NoReturn:
    """End this process at once with exit status ``code``, without the interpreter's teardown.

    For a process whose work is done (files closed, child processes joined, messages queued): the teardown would
    only unload a device backend's compiled programs one by one. Unreferenced objects are collected
    first (the finalizers of multiprocessing queues and locks release their semaphores, which the resource tracker
    would otherwise report as leaked), then the output streams and logging are flushed.

    Parameters
    ----------
    code : int
        Exit status.
    """
    gc.collect()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    logging.shutdown()
    os._exit(code)
