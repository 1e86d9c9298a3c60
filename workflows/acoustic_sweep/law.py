"""Ringdown rows or stores -> the agent's diameter-continuous acoustic law (surrogate file format version 2)."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bubblecal.data import jsonable
from bubblecal.workflows.acoustic_sweep.fit import read_sweeps, write_rows_csv

__all__ = ["acoustic_law_from_stores", "law_rows"]


def law_rows(sweeps) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(diameter_um, ka, f_res_MHz) of the valid rows of sweeps (status ok, fit success, finite f_res > 0).

    Parameters
    ----------
    sweeps : sequence of SweepResult
        Sweeps of one agent.

    Returns
    -------
    tuple of numpy.ndarray
        Diameters [um], stretching moduli [DPD 2-D modulus], resonance frequencies [MHz].
    """
    d = np.concatenate([np.full(int(s.valid.sum()), s.diameter_um) for s in sweeps])
    ka = np.concatenate([s.column("ka")[s.valid] for s in sweeps])
    f = np.concatenate([s.column("f_res_MHz")[s.valid] for s in sweeps])
    return d, ka, f


def _source(path) -> dict:
    """A source's path and, for a file, its SHA-256."""
    p = Path(path)
    out = {"path": str(path)}
    if p.is_file():
        out["sha256"] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def acoustic_law_from_stores(stores: Sequence, out: str | Path, agent: str | None = None, form: str | None = None,
                             bands_um: Sequence[tuple[float, float]] | None = None,
                             rows_csv: str | Path | None = None, t_start: float | None = None):
    """Fit the agent's resonance law f_res(k_a, D) over every diameter of ``stores`` and save it (version 2).

    Parameters
    ----------
    stores : sequence
        Ringdown row CSVs (e.g. ``data/training/<agent>_ringdown_1.5-8um_rows.csv``; no refit) or ringdown
        campaign stores (refitted), of one agent.
    out : str or Path
        Acoustic surrogate JSON to write.
    agent : str or None
        'definity' or 'sonovue' (None: from the campaign or file name).
    form : str or None
        Law form (None: :data:`bubblecal.surrogates.DEFAULT_LAW_FORM`).
    bands_um : sequence of (float, float) or None
        Diameter bands [um] held out as a whole (None: 3.5-4.5 um, :data:`bubblecal.surrogates.law_fit.
        DEFAULT_BANDS_UM`).
    rows_csv : str, Path or None
        Also write every row read (``diameter_um`` + the row fields) here.
    t_start : float or None
        Samples before this DPD time are not fitted (stores only).

    Returns
    -------
    tuple
        (:class:`~bubblecal.surrogates.AcousticLawSurrogate`, list of SweepResult).

    Raises
    ------
    ValueError
        Sources of several agents, an unknown form, too few diameters or rows, or an empty band.
    """
    from bubblecal.surrogates import DEFAULT_LAW_FORM, AcousticLawSurrogate, fit_law
    from bubblecal.surrogates.law_fit import DEFAULT_BANDS_UM

    sweeps = read_sweeps(stores, agent=agent, t_start=t_start)
    d, ka, f = law_rows(sweeps)
    per_d: dict[str, dict] = {}
    for s in sweeps:
        e = per_d.setdefault(f"{s.diameter_um:g}", {"n": 0, "n_valid": 0})
        e["n"] += len(s.rows)
        e["n_valid"] += int(s.valid.sum())
    meta = {"synthetic": False, "source": "DPD ringdown sweeps (bubblecal.sim, implicit tier unless noted)",
            "agent": sweeps[0].agent, "tier": sorted({s.tier for s in sweeps}), "kb": sweeps[0].settings.get("kb"),
            "sources": [_source(s) for s in stores], "per_diameter": per_d,
            "units": {"f_res": "MHz", "ka": "DPD 2-D modulus", "diameter": "um"}}
    law = fit_law(d, ka, f, form or DEFAULT_LAW_FORM, DEFAULT_BANDS_UM if bands_um is None else bands_um)
    sur = AcousticLawSurrogate(law, name=sweeps[0].agent, meta=jsonable(meta, nonfinite_as_none=True))
    sur.save(out)
    if rows_csv is not None:
        write_rows_csv(sweeps, rows_csv)
    return sur, sweeps
