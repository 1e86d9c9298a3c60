"""Sobol sensitivity of a mechanical surrogate over a workflow's prior box (``docs/inference.md`` section 8).

Ties the physics-free :func:`bubblecal.inference.sensitivity.sobol_along` to a surrogate, a
:class:`~bubblecal.priors.PriorSpec` and the experimentally explored loading range of a curve.
Loading coordinates and responses are in DPD units (displacement for compression, force for indentation).
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bubblecal.data import SHELL_PARAMETERS
from bubblecal.inference.sensitivity import SobolResult, sobol_along
from bubblecal.priors import PriorSpec
from bubblecal.workflows.plotting import new_figure, save_figure

__all__ = ["SOBOL_N", "SOBOL_POINTS", "SensitivityRun", "averaging_range", "surrogate_sensitivity", "plot_sensitivity",
           "write_sensitivity"]

#: Saltelli base sample size N (``docs/inference.md`` section 8).
SOBOL_N = 2048
#: Loading coordinates along the surrogate's training range.
SOBOL_POINTS = 40


@dataclass(frozen=True)
class SensitivityRun:
    """A Sobol analysis with its context.

    Parameters
    ----------
    result : bubblecal.inference.sensitivity.SobolResult
        Indices along ``result.x`` (DPD loading coordinate) and their averages.
    setup : str
        'compression' or 'indentation'.
    bounds : dict of str to tuple of float
        The prior box of the free shell inputs (DPD units).
    fixed : dict of str to float
        Shell inputs held fixed (a reduced shell's b1..a4).
    outside_training_fraction : float
        Fraction of the prior box (probed at random) outside the surrogate's training box.
    """

    result: SobolResult
    setup: str
    bounds: dict[str, tuple[float, float]]
    fixed: dict[str, float]
    outside_training_fraction: float


def averaging_range(x_data: np.ndarray, surrogate) -> tuple[tuple[float, float], str | None]:
    """Loading range over which to average the indices: the data's explored range cut to the surrogate's.

    The surrogate is not asked about loads it never saw, and the cut is reported, not silent.

    Parameters
    ----------
    x_data : ndarray
        The curve's loading coordinate (DPD length for compression, DPD force for indentation).
    surrogate : bubblecal.surrogates.Surrogate
        Its ``x_range`` is the training range of the loading coordinate.

    Returns
    -------
    tuple
        ((lo, hi) in the DPD units of ``x_data``, message saying what was cut or None when nothing was).

    Raises
    ------
    ValueError
        The two ranges do not overlap.
    """
    lo, hi = float(np.min(x_data)), float(np.max(x_data))
    x_lo, x_hi = (float(v) for v in surrogate.x_range)
    a, b = max(lo, x_lo), min(hi, x_hi)
    if not a < b:
        raise ValueError(f"the data's loading range [{lo:g}, {hi:g}] does not overlap the surrogate's "
                         f"[{x_lo:g}, {x_hi:g}]")
    if (a, b) == (lo, hi):
        return (lo, hi), None
    return (a, b), (f"the data explore [{lo:g}, {hi:g}] but the surrogate was trained on [{x_lo:g}, {x_hi:g}]: "
                    f"indices averaged over [{a:g}, {b:g}]")


def surrogate_sensitivity(surrogate, spec: PriorSpec, x_range: tuple[float, float], *, N: int = SOBOL_N,
                          num_points: int = SOBOL_POINTS, seed: int = 0) -> SensitivityRun:
    """Sobol indices of ``surrogate`` over the prior box of ``spec``'s free shell inputs.

    The loading coordinate runs over ``num_points`` values spanning the surrogate's training range
    ``surrogate.x_range``; indices are averaged over ``x_range``. Parameters fixed by the spec (a reduced
    shell's b1..a4) are held at their values. Design points outside the surrogate's training box are
    counted and reported (never silent): a warning per domain message, and
    :attr:`SensitivityRun.outside_training_fraction`.

    Parameters
    ----------
    surrogate : bubblecal.surrogates.Surrogate
        A mechanical surrogate.
    spec : PriorSpec
        Priors whose box is analysed.
    x_range : tuple of float
        The experimentally explored loading range (DPD units; see :func:`averaging_range`).
    N : int
        Saltelli base sample size (a power of two).
    num_points : int
        Loading coordinates along the surrogate's training range.
    seed : int
        Seed of the design and of the domain probe.

    Returns
    -------
    SensitivityRun

    Raises
    ------
    ValueError
        ``N`` is not a power of two, ``spec`` has no free shell input, or ``x_range`` leaves the
        surrogate's loading range.
    """
    if not 0 < N or N & (N - 1):
        raise ValueError(f"N must be a positive power of two (Saltelli/Sobol' design), got {N}")
    free = [k for k in SHELL_PARAMETERS if k in spec.parameters]
    if not free:
        raise ValueError(f"priors {spec.name!r} have no free surrogate input among {', '.join(SHELL_PARAMETERS)}")
    bounds = {k: spec.parameters[k].prior.as_tuple() for k in free}
    fixed = {k: spec.fixed[k] for k in SHELL_PARAMETERS if k not in free}
    x_lo, x_hi = (float(v) for v in surrogate.x_range)
    lo, hi = float(x_range[0]), float(x_range[1])
    if not (x_lo <= lo < hi <= x_hi + 1e-9 * abs(x_hi)):
        raise ValueError(f"x_range [{lo:g}, {hi:g}] must lie inside the surrogate's loading range [{x_lo:g}, {x_hi:g}]")
    x = np.linspace(x_lo, x_hi, num_points)
    # one corner check of the box against the training box, reported as a fraction of design rows
    box_lo = np.array([bounds[k][0] if k in bounds else fixed[k] for k in SHELL_PARAMETERS])
    box_hi = np.array([bounds[k][1] if k in bounds else fixed[k] for k in SHELL_PARAMETERS])
    rng = np.random.default_rng(seed)
    probe = box_lo + (box_hi - box_lo) * rng.random((4096, len(SHELL_PARAMETERS)))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        inside = surrogate.check_domain(probe, x_lo, action="warn")
    for w in caught:
        warnings.warn(f"sensitivity over the prior box of {spec.name}: {w.message}", stacklevel=2)
    result = sobol_along(surrogate, bounds, x, N=N, x_range=(lo, hi), seed=seed, order=SHELL_PARAMETERS,
                         fixed=fixed)
    return SensitivityRun(result=result, setup=surrogate.setup, bounds=bounds, fixed=fixed,
                          outside_training_fraction=float(1.0 - np.mean(inside)))


def plot_sensitivity(run: SensitivityRun, path: str | Path) -> Path:
    """Plot first-order (solid) and total (dashed) indices along the loading coordinate with confidence bands.

    Parameters
    ----------
    run : SensitivityRun
    path : str or Path
        PNG to write (150 dpi).

    Returns
    -------
    Path
    """
    r = run.result
    xlabel = "imposed displacement [DPD length]" if run.setup == "compression" else "applied force [DPD force]"
    fig, ax = new_figure(figsize=(6.4, 4.2))
    for j, name in enumerate(r.names):
        (line,) = ax.plot(r.x, r.S1[:, j], label=f"{name}  S1 {r.S1_mean[j]:.2f}, ST {r.ST_mean[j]:.2f}")
        ax.fill_between(r.x, r.S1[:, j] - r.S1_conf[:, j], r.S1[:, j] + r.S1_conf[:, j], color=line.get_color(),
                        alpha=0.2, lw=0)
        ax.plot(r.x, r.ST[:, j], "--", color=line.get_color())
    ax.axvspan(*r.x_range, color="0.9", zorder=-1, label="explored range (averaged)")
    ax.set(xlabel=xlabel, ylabel="Sobol index", ylim=(-0.05, 1.05),
           title=f"{run.setup}: first-order (solid, 95% CI) and total (dashed), N = {r.N}")
    ax.legend(frameon=False, fontsize=8)
    return save_figure(fig, Path(path), dpi=150)


def _json_array(a: np.ndarray) -> list:
    """Nested list with NaN (undefined index where the output has no variance) as null."""
    return np.where(np.isfinite(a), a, None).tolist()


def write_sensitivity(run: SensitivityRun, out: str | Path, name: str) -> dict[str, Path]:
    """Write ``<name>_sobol.json`` (indices along x and averages) and ``<name>_sobol.png`` into ``out``.

    Parameters
    ----------
    run : SensitivityRun
    out : str or Path
        Output folder (created).
    name : str
        File stem, e.g. the curve name.

    Returns
    -------
    dict of str to Path
        ``{'json': ..., 'plot': ...}``.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    r = run.result
    payload = {"setup": run.setup, "bounds_dpd": run.bounds, "fixed": run.fixed, "N": r.N,
               "n_evaluations": r.n_evaluations, "conf_level": r.conf_level, "x_range_dpd": list(r.x_range),
               "outside_training_fraction": run.outside_training_fraction, "averaged": r.table(),
               "x_dpd": r.x.tolist(), "names": list(r.names),
               **{k: _json_array(getattr(r, k)) for k in ("S1", "S1_conf", "ST", "ST_conf")}}
    json_path = out / f"{name}_sobol.json"
    tmp = json_path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(payload, indent=1, allow_nan=False))
    tmp.replace(json_path)  # atomic: a crash never leaves a half-written report over a good one
    return {"json": json_path, "plot": plot_sensitivity(run, out / f"{name}_sobol.png")}
