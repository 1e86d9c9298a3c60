"""Fits over sweeps: the f_res²(k_a) quadratic per diameter and the acoustic surrogate of an agent."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bubblecal.data import jsonable
from bubblecal.workflows.acoustic_sweep.stores import sweeps_from_rows_csv, sweeps_from_store
from bubblecal.workflows.acoustic_sweep.sweep import ROW_FIELDS, SweepResult

__all__ = ["fit_sweep", "acoustic_surrogate_from_stores", "read_sweeps", "write_rows_csv"]


def fit_sweep(results: SweepResult | Sequence[SweepResult]) -> dict:
    """The f_res²(k_a) quadratic per diameter over the valid rows
    (:func:`bubblecal.surrogates.acoustic.fit_quadratic`).

    Parameters
    ----------
    results : SweepResult or sequence of SweepResult
        Several results at the same diameter are pooled.

    Returns
    -------
    dict
        diameter_um -> :class:`~bubblecal.surrogates.acoustic.DiameterFit` (f_res in MHz, k_a DPD;
        leave-one-out relative errors of f_res).
    """
    from bubblecal.surrogates import fit_quadratic

    items = [results] if isinstance(results, SweepResult) else list(results)
    by_d: dict[float, list[SweepResult]] = {}
    for res in items:
        by_d.setdefault(res.diameter_um, []).append(res)
    out = {}
    for d, group in sorted(by_d.items()):
        ka = np.concatenate([g.column("ka")[g.valid] for g in group])
        f = np.concatenate([g.column("f_res_MHz")[g.valid] for g in group])
        meta = {"agent": group[0].agent, "tier": group[0].tier, "mass_factor": group[0].mass_factor,
                "kb": group[0].settings.get("kb"), "n_rows": int(sum(len(g.rows) for g in group)),
                "n_valid": int(ka.size)}
        out[d] = fit_quadratic(ka, f, d, meta=meta)
    return out


def acoustic_surrogate_from_stores(stores: Sequence, out: str | Path, agent: str | None = None,
                                   rows_csv: str | Path | None = None, t_start: float | None = None):
    """Refit every R(t) of ringdown campaign ``stores`` and save the agent's acoustic surrogate.

    One f_res²(k_a) quadratic per diameter (f_res in MHz, k_a DPD) with leave-one-out errors; the JSON at
    ``out`` carries the provenance (stores, tier, mesh level, counts, check-7 ratios, LOO errors).

    Parameters
    ----------
    stores : sequence
        Ringdown campaign stores (directory, ``.jsonl``, ``.jsonl.gz``) of one agent, or row CSVs written by
        an earlier call (``rows_csv``; no refit, e.g. the shipped ``data/training/*_ringdown_rows.csv``).
    out : str or Path
        Acoustic surrogate JSON to write.
    agent : str or None
        'definity' or 'sonovue' (None: from the campaign or file name).
    rows_csv : str, Path or None
        Also write every fitted row (``diameter_um`` + :data:`ROW_FIELDS`) here.
    t_start : float or None
        Samples before this DPD time are not fitted.

    Returns
    -------
    tuple
        (:class:`~bubblecal.surrogates.AcousticSurrogate`, list of :class:`SweepResult`).

    Raises
    ------
    ValueError
        Stores of several agents, or a diameter with fewer than 3 valid rows.
    """
    from bubblecal.surrogates import AcousticSurrogate

    sweeps = read_sweeps(stores, agent=agent, t_start=t_start)
    fits = fit_sweep(sweeps)
    per_d = {}
    for s in sweeps:
        sm = s.summary()
        f = fits[s.diameter_um]
        per_d[f"{s.diameter_um:g}"] = {"n": sm["n"], "n_valid": sm["n_valid"], "check7_ratio_median":
                                       sm["check7_ratio_median"], "loo_median": f.loo_median, "loo_max": f.loo_max,
                                       "mesh_subdivisions": s.settings.get("mesh_subdivisions")}
    meta = {"synthetic": False, "source": "DPD ringdown campaign (bubblecal.sim, implicit tier unless noted)",
            "agent": sweeps[0].agent, "tier": sorted({s.tier for s in sweeps}),
            "mass_factor": sorted({s.mass_factor for s in sweeps}), "kb": sweeps[0].settings.get("kb"),
            "stores": [str(s) for s in stores], "per_diameter": per_d,
            "law": "f_res^2 = a0 + a1 ka + a2 ka^2 [MHz^2], ka DPD 2-D modulus, mu = ka / 3",
            "loo_median_overall": float(np.median([f.loo_median for f in fits.values()])),
            "loo_max_overall": float(np.max([f.loo_max for f in fits.values()]))}
    sur = AcousticSurrogate(fits, name=sweeps[0].agent, meta=jsonable(meta, nonfinite_as_none=True))
    sur.save(out)
    if rows_csv is not None:
        write_rows_csv(sweeps, rows_csv)
    return sur, sweeps


def read_sweeps(stores: Sequence, agent: str | None = None, t_start: float | None = None) -> list[SweepResult]:
    """The sweeps of ringdown stores (refitted) or row CSVs (read back), all of one agent.

    Parameters
    ----------
    stores : sequence
        Ringdown campaign stores (directory, ``.jsonl``, ``.jsonl.gz``) or row CSVs (``.csv``).
    agent : str or None
        'definity' or 'sonovue' (None: from the campaign or file name).
    t_start : float or None
        Samples before this DPD time are not fitted (stores only).

    Returns
    -------
    list of SweepResult
        In the order read.

    Raises
    ------
    ValueError
        For sources of several agents, or bad input (naming the file).
    """
    sweeps: list[SweepResult] = []
    for st in stores:
        if str(st).endswith(".csv"):
            sweeps.extend(sweeps_from_rows_csv(st, agent=agent))
        else:
            sweeps.extend(sweeps_from_store(st, agent=agent, t_start=t_start))
    agents = {s.agent for s in sweeps}
    if len(agents) != 1:
        raise ValueError(f"stores hold several agents {sorted(agents)}: one acoustic surrogate per agent")
    return sweeps


def write_rows_csv(sweeps: Sequence[SweepResult], path: str | Path) -> Path:
    """Write every fitted row (``diameter_um`` + :data:`ROW_FIELDS`) of the sweeps to a CSV.

    Parameters
    ----------
    sweeps : sequence of SweepResult
        The sweeps.
    path : str or Path
        The CSV to write.

    Returns
    -------
    Path
        ``path``.
    """
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=["diameter_um", *ROW_FIELDS])
        w.writeheader()
        for s in sweeps:
            for r in s.rows:
                w.writerow({"diameter_um": f"{s.diameter_um:g}",
                            **{k: (f"{v:.10g}" if isinstance(v, float) else v) for k, v in r.items()}})
    return Path(path)

