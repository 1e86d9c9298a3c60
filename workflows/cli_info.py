"""``bubblecal info``: what is installed, which devices are visible, what data and priors ship."""

from __future__ import annotations

import importlib.metadata as metadata

import typer
from rich.table import Table

from bubblecal import __version__
from bubblecal._extras import DISTRIBUTIONS, EXTRAS
from bubblecal.data import DEFAULT_UNITS, acoustic_observations, reference_curves
from bubblecal.priors import available_priors
from bubblecal.workflows.console import console

_PACKAGES = ("numpy", "scipy", "jax", "jaxlib", "numpyro", "torch", "warp-lang", "trimesh", "onnxruntime", "arviz",
             "SALib", "dask", "matplotlib")
#: Distribution -> the extra that installs it (named where it is missing).
_EXTRA_OF = {DISTRIBUTIONS.get(module, module): extra for extra, modules in EXTRAS.items() for module in modules}


def _devices() -> str:
    """The JAX platforms, or why JAX is unavailable."""
    try:
        import jax

        return ", ".join(sorted({f"{d.platform}" for d in jax.devices()}))
    except Exception as exc:  # report, do not crash: info is a diagnostic command
        return f"unavailable ({exc})"


def info() -> None:
    """Print versions, JAX devices, the unit system and the shipped data and priors."""
    console.print(f"[bold]bubblecal {__version__}[/]")
    table = Table(title="Environment")
    table.add_column("package")
    table.add_column("version")
    for name in _PACKAGES:
        try:
            table.add_row(name, metadata.version(name))
        except metadata.PackageNotFoundError:
            extra = _EXTRA_OF.get(name)
            table.add_row(name, "[red]not installed[/]" + (f" (extra \\[{extra}])" if extra else ""))
    table.add_row("JAX devices", _devices())
    console.print(table)

    u = DEFAULT_UNITS
    units = Table(title="Unit system (DPD)")
    units.add_column("quantity")
    units.add_column("1 DPD unit =")
    units.add_row("length", f"{u.length_m * 1e9:g} nm")
    units.add_row("energy (k_BT, T = 300 K)", f"{u.energy_J:.5g} J")
    units.add_row("time", f"{u.time_s * 1e6:.4f} µs (ρ_water = {u.rho_water:g} kg/m³)")
    units.add_row("force on the shell (fscale = 0.0074)",
                  f"{1 / u.nN_to_dpd(1.0):.6g} nN  (1 nN = {u.nN_to_dpd(1.0):.3f})")
    units.add_row("k_a (2-D modulus)",
                  f"E = {u.yt_per_ka:.2f} Pa (h = {u.shell_thickness_m * 1e9:g} nm, ν = {u.poisson:g})")
    console.print(units)

    curves = reference_curves()
    console.print(f"Reference curves: {len(curves)} ({', '.join(c.name for c in curves)}); "
                  f"acoustic observations: {len(acoustic_observations())}")
    console.print(f"Prior files: {', '.join(available_priors())}")


def register(app: typer.Typer) -> None:
    """Add ``info`` to the root command."""
    app.command("info")(info)
