"""Sobol sensitivity of a mechanical surrogate over a workflow's prior box (``inference.md`` section 8).

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
from bubblecal.inference import SobolResult, sobol_along
from bubblecal.priors import PriorSpec

__all__ = ["SensitivityRun", "surrogate_sensitivity", "plot_sensitivity", "write_sensitivity"]

#: Surrogate inputs in order (d0 is an offset of the data, not a surrogate input).


@dataclass(frozen=True)
class SensitivityRun:
    """A Sobol analysis with its context: ``result`` (indices along ``result.x``), the setup, the
    parameter box used (DPD) and the fraction of design points outside the surrogate's training box."""

    result: SobolResult
    setup: str
    bounds: dict[str, tuple[float, float]]
    fixed: dict[str, float]
    outside_training_fraction: float


def averaging_range(x_data: np.ndarray, surrogate) -> tuple[tuple[float, float], str | None]:
    """Loading range (DPD units of the surrogate's loading coordinate) over which to average the indices: the data's
    explored range [min x, max x] cut to the surrogate's training range, and a message saying what was cut (None
    when nothing was): the surrogate is not asked about loads it never saw, and the cut is reported, not silent."""
    lo, hi = float(np.min(x_data)), float(np.max(x_data))
    x_lo, x_hi = (float(v) for v in surrogate.x_range)
    a, b = max(lo, x_lo), min(hi, x_hi)
    if not a < b:
        raise ValueError(f"the data's loading range [{lo:g}, {hi:g}] does not overlap the surrogate's [{x_lo:g}, {x_hi:g}]")
    if (a, b) == (lo, hi):
        return (lo, hi), None
    return (a, b), (f"the data explore [{lo:g}, {hi:g}] but the surrogate was trained on [{x_lo:g}, {x_hi:g}]: "
                    f"indices averaged over [{a:g}, {b:g}]")


def surrogate_sensitivity(surrogate, spec: PriorSpec, x_range: tuple[float, float], *, N: int = 2048,
                          num_points: int = 40, seed: int = 0) -> SensitivityRun:
    """Sobol indices of ``surrogate`` over the prior box of ``spec``'s free shell inputs.

    The loading coordinate runs over ``num_points`` values spanning the surrogate's training range
    ``surrogate.x_range``; indices are averaged over ``x_range`` (the experimentally explored range,
    DPD units). Parameters fixed by the spec (a reduced shell's b1..a4) are held at their values.
    Design points outside the surrogate's training box are counted and reported (never silent).
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
    """First-order (solid) and total (dashed) indices along the loading coordinate with confidence bands."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    r = run.result
    xlabel = "imposed displacement [DPD length]" if run.setup == "compression" else "applied force [DPD force]"
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for j, name in enumerate(r.names):
        (line,) = ax.plot(r.x, r.S1[:, j], label=f"{name}  S1 {r.S1_mean[j]:.2f}, ST {r.ST_mean[j]:.2f}")
        ax.fill_between(r.x, r.S1[:, j] - r.S1_conf[:, j], r.S1[:, j] + r.S1_conf[:, j], color=line.get_color(),
                        alpha=0.2, lw=0)
        ax.plot(r.x, r.ST[:, j], "--", color=line.get_color())
    ax.axvspan(*r.x_range, color="0.9", zorder=-1, label="explored range (averaged)")
    ax.set(xlabel=xlabel, ylabel="Sobol index", ylim=(-0.05, 1.05),
           title=f"{run.setup}: first-order (solid, 95% CI) and total (dashed), N = {r.N}")
    ax.legend(frameon=False, fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return path


def _json_array(a: np.ndarray) -> list:
    """Nested list with NaN (undefined index where the output has no variance) as null."""
    return np.where(np.isfinite(a), a, None).tolist()


def write_sensitivity(run: SensitivityRun, out: str | Path, name: str) -> dict[str, Path]:
    """Write ``<name>_sobol.json`` (indices along x and averages) and ``<name>_sobol.png`` into ``out``."""
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
