"""The ``bubblecal`` command line: a thin typer shell over the package's modules.

Each command group lives in its own ``cli_<group>.py`` module exposing a ``typer.Typer`` named
``app``; those modules import heavy libraries (jax, torch, warp) inside the command functions so
that ``bubblecal --help`` stays fast.
"""

from __future__ import annotations

import importlib
import os
import sys
from typing import NoReturn

# HDF5 locks a file for its writer, and a child process (XLA's GPU compiler) started while a phase file is being
# written inherits that lock: the command's files are its own (the run folder has its own lock), so HDF5's is off
os.environ.setdefault("HDF5_USE_FILE_LOCKING", "FALSE")

import typer

from bubblecal import __version__
from bubblecal._extras import MissingExtraError
from bubblecal.workflows.console import end_process, fail

#: The exit-status convention of every command (docs/data-formats.md, "Exit status").
EXIT_STATUS_HELP = ("Exit status of every command: 0 success; 1 the run failed or an input is unusable (the message "
                    "names the file, option or value and what is allowed); 2 usage error (unknown option, missing "
                    "argument, a value of the wrong type or outside an option's listed choices).")

app = typer.Typer(
    name="bubblecal",
    help="Calibrate DPD microbubble shell models against AFM force spectroscopy and acoustic data.\n\n"
         + EXIT_STATUS_HELP,
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

#: (group name, module path) of every command group; each module exposes ``app``.
COMMAND_GROUPS: list[tuple[str, str]] = [
    ("data", "bubblecal.workflows.cli_data"),
    ("priors", "bubblecal.workflows.cli_priors"),
    ("surrogates", "bubblecal.workflows.cli_surrogates"),
    ("sim", "bubblecal.workflows.cli_sim"),
]

#: Modules that register top-level commands on :data:`app` when imported (``register(app)``).
TOP_LEVEL_MODULES: list[str] = [
    "bubblecal.workflows.cli_info",
    "bubblecal.workflows.cli_sensitivity",
    "bubblecal.workflows.cli_compare",
    "bubblecal.workflows.cli_calibrate",
]


def _version_callback(value: bool) -> None:
    """Print the version and exit when ``--version`` is given."""
    if value:
        typer.echo(f"bubblecal {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(
        False, "--version", callback=_version_callback, is_eager=True, help="Print the version and exit."
    ),
) -> None:
    """bubblecal: DPD shell models, neural surrogates and hierarchical Bayesian calibration."""


for _name, _module in COMMAND_GROUPS:
    app.add_typer(importlib.import_module(_module).app, name=_name)
for _module in TOP_LEVEL_MODULES:
    importlib.import_module(_module).register(app)


def main() -> None:
    """Console-script entry point: a command whose extra is not installed prints one message and exits 1.

    Raises
    ------
    SystemExit
        With the command's exit status (docs/data-formats.md, "Exit status").
    """
    try:
        app()
    except MissingExtraError as exc:
        raise SystemExit(fail(str(exc)).exit_code) from None


def run() -> NoReturn:
    """The ``bubblecal`` command: :func:`main`, then the process ends with its exit status at once.

    Every command has closed its files, joined its processes and printed its last line when :func:`main` returns,
    so the interpreter's own teardown would only delay the shell (:func:`~bubblecal.workflows.console.end_process`).

    Raises
    ------
    SystemExit
        Never: the process ends through ``os._exit`` with :func:`main`'s status.
    """
    try:
        main()
        code = 0
    except SystemExit as exc:
        code = exc.code
    if code is None:
        code = 0
    elif not isinstance(code, int):  # a message as the status: print it, exit 1 (as the interpreter would)
        print(code, file=sys.stderr)
        code = 1
    end_process(code)

if __name__ == "__main__":
    run()
