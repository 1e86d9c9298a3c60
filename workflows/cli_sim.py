"""``bubblecal sim``: the Warp DPD engine's verification (Warp is imported inside the commands)."""

from __future__ import annotations

import typer

app = typer.Typer(help="Warp DPD simulator: physics verification.", no_args_is_help=True)


@app.command("verify")
def verify(
    quick: bool = typer.Option(False, "--quick", help="Small CPU-sized versions (default test suite)."),
    device: str = typer.Option("cpu", "--device", help="Warp device: cpu or cuda (cuda:N)."),
    only: list[str] = typer.Option(None, "--only", help="Run only checks whose name contains this (repeatable)."),
) -> None:
    """Run the checks of physics.md section 6; table, then one JSON line; exit 1 on any failure."""
    if not (device == "cpu" or device.startswith("cuda")):
        raise typer.BadParameter("device must be 'cpu' or 'cuda' (or 'cuda:N')", param_hint="--device")
    import warp as wp

    wp.config.quiet = True
    from bubblecal.sim.verify import main

    code = main(quick=quick, device=device, only=only or None)
    raise typer.Exit(code)
