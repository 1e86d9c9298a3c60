"""Load grids of the quasi-static chain: sub-steps, the first-load ramp, and the reported points among them."""

from __future__ import annotations

import math

import numpy as np

__all__: list[str] = []


def _refine_grid(grid: np.ndarray, max_step: float) -> tuple[np.ndarray, np.ndarray]:
    """Insert sub-steps so no load step exceeds ``max_step``; returns (refined grid, indices of ``grid``)."""
    pts, keep, prev = [], [], 0.0
    for g in grid:
        n = max(1, int(math.ceil((g - prev) / max_step - 1e-9)))
        pts.extend(prev + (g - prev) * (i + 1) / n for i in range(n))
        keep.append(len(pts) - 1)
        prev = g
    return np.asarray(pts), np.asarray(keep)


def _ramp_grid(grid: np.ndarray, n_ramp: int) -> tuple[np.ndarray, np.ndarray]:
    """Insert ``n_ramp`` geometric sub-points base + (F - base) / 2^k, k = n_ramp ... 1, before the first positive
    load F of ``grid`` (base = the load before it, or 0); returns (grid with sub-points, indices of ``grid``).
    From the unloaded shape the first load point costs a large share of a curve's FIRE work; reached through
    halvings, each start is the predictor's extrapolation (docs/decisions.md)."""
    grid = np.asarray(grid, dtype=np.float64)
    pos = np.nonzero(grid > 0)[0]
    if n_ramp <= 0 or pos.size == 0:
        return grid, np.arange(grid.size)
    j1 = int(pos[0])
    base = float(grid[j1 - 1]) if j1 > 0 else 0.0
    sub = [base + (float(grid[j1]) - base) / 2.0 ** k for k in range(n_ramp, 0, -1)]
    full = np.r_[grid[:j1], sub, grid[j1:]]
    return full, np.r_[np.arange(j1), np.arange(j1 + n_ramp, full.size)]


def _sum_substeps(fire_steps: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """FIRE steps per reported point (last axis), each including those of the sub-points before it."""
    return np.add.reduceat(fire_steps, np.r_[0, keep[:-1] + 1], axis=-1) if len(keep) else fire_steps[..., :0]


def _select_points(out: dict, keep: np.ndarray) -> dict:
    """Restrict the per-point arrays of :func:`_run_chain` to the reported points (failures are kept)."""
    sel = dict(out)
    for k in ("fmax", "max_area_strain", "volume"):
        sel[k] = out[k][:, keep]
    sel["fire_steps"] = _sum_substeps(out["fire_steps"], keep)
    sel["point_status"] = [[ps[j] for j in keep] for ps in out["point_status"]]
    sel["obs"] = {k: v[:, keep] for k, v in out["obs"].items()}
    return sel
