"""Sweeps read back: refit the R(t) records of ringdown campaign stores, or read fitted rows from a CSV."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from bubblecal.data import DEFAULT_UNITS, UnitSystem
from bubblecal.workflows.acoustic_sweep.sweep import AGENT_KB, ROW_FIELDS, SweepResult, check_agent, sweep_row

__all__ = ["sweeps_from_store", "sweeps_from_rows_csv"]


def sweeps_from_store(store, agent: str | None = None, t_start: float | None = None,
                      units: UnitSystem = DEFAULT_UNITS) -> list[SweepResult]:
    """Refit the R(t) records of a ringdown campaign store: one :class:`SweepResult` per diameter.

    Records must be setup 'ringdown' (x = t [DPD time], y = R(t) [DPD length]); the check-7 prediction is
    recomputed from each record's equilibrium radius, gas pressure and shell mass (the area ratio of its mesh).

    Parameters
    ----------
    store : str, Path or bubblecal.data.store.CampaignStore
        A store directory, ``.jsonl`` or ``.jsonl.gz``.
    agent : str or None
        'definity' or 'sonovue' (None: from the campaign name, e.g. 'definity_ringdown').
    t_start : float or None
        Samples before this DPD time are not fitted.
    units : UnitSystem

    Returns
    -------
    list of SweepResult
        Sorted by diameter; rows sorted by k_a.

    Raises
    ------
    ValueError
        No records, non-ringdown records, mixed mass factors at one diameter, or an unknown agent.
    """
    from bubblecal.data import CampaignStore
    from bubblecal.sim.protocols.ringdown import breathing_mode_prediction

    st = store if isinstance(store, CampaignStore) else CampaignStore(store)
    recs = st.read(warn=False)
    if not recs:
        raise ValueError(f"{st.records_path}: no records")
    bad = [r["sample_id"] for r in recs if r.get("setup") != "ringdown"]
    if bad:
        raise ValueError(f"{st.records_path}: {len(bad)} record(s) are not ringdown records (e.g. {bad[0]})")
    if agent is None:
        name = str(recs[0].get("provenance", {}).get("campaign", ""))
        agent = next((a for a in AGENT_KB if name.startswith(a)), None)
        if agent is None:
            raise ValueError(f"{st.records_path}: cannot tell the agent from campaign {name!r}; pass agent=")
    agent = check_agent(agent)
    by_d: dict[float, list[dict]] = {}
    for r in recs:
        by_d.setdefault(float(r["provenance"]["diameter_um"]), []).append(r)
    out = []
    for d, group in sorted(by_d.items()):
        group.sort(key=lambda r: r["params"]["ka"])
        rows, traces, fits, tiers, infos = [], [], [], set(), []
        mass_factor = None
        for r in group:
            info = r["provenance"].get("info", {})
            mf = float(info.get("mass_factor", 160.0))
            if mass_factor is not None and mf != mass_factor:
                raise ValueError(f"{st.records_path}: mixed mass factors at {d:g} um")
            mass_factor = mf
            tiers.add(r.get("tier"))
            ka, kb = float(r["params"]["ka"]), float(r["params"]["kb"])
            r_eq, p_gas = float(info.get("radius_equilibrium", np.nan)), float(info.get("p_gas", np.nan))
            ratio = np.asarray(info.get("prediction", {}).get("area_ratio", [1.0]), dtype=float).ravel()
            pred = breathing_mode_prediction(ka, r_eq, p_gas, float(info.get("shell_mass", np.nan)),
                                             area_ratio=float(ratio[0]) if ratio.size else 1.0)
            t, y = np.asarray(r["x"], dtype=float), np.asarray(r["y"], dtype=float)
            row, fit = sweep_row(ka, kb, int(r["seed"]), r["status"], t, y, omega0_sq=float(pred["omega0_sq"]),
                                 omega0_sq_mesh=float(pred["omega0_sq_mesh"]), radius_equilibrium=r_eq, p_gas=p_gas,
                                 mass_factor=mf, units=units, t_start=t_start)
            rows.append(row)
            traces.append((t, y))
            fits.append(fit)
            infos.append({k: info.get(k) for k in ("dt", "mesh_subdivisions", "n_vertices", "record_steps")})
        settings = {"agent": agent, "diameter_um": d, "tier": "/".join(sorted(map(str, tiers))),
                    "mass_factor": mass_factor, "kb": rows[0]["kb"], "store": str(st.records_path),
                    "n_ka": len(rows), "mesh_subdivisions": infos[0].get("mesh_subdivisions"), "t_start": t_start}
        out.append(SweepResult(agent=agent, diameter_um=d, tier=settings["tier"], mass_factor=mass_factor, rows=rows,
                               traces=traces, fits=fits, settings=settings, batch_info=infos))
    return out


def sweeps_from_rows_csv(path: str | Path, agent: str | None = None) -> list[SweepResult]:
    """Read fitted ringdown rows: one :class:`SweepResult` per diameter (no traces).

    Parameters
    ----------
    path : str or Path
        CSV of ``diameter_um`` + :data:`ROW_FIELDS`, e.g. the shipped ``data/training/<agent>_ringdown_rows.csv``.
    agent : str or None
        'definity' or 'sonovue' (None: from the file name).

    Returns
    -------
    list of SweepResult
        Sorted by diameter.

    Raises
    ------
    ValueError
        Naming the file, row and column on bad input, or an unknown agent.
    """
    path = Path(path)
    if agent is None:
        agent = next((a for a in AGENT_KB if path.name.startswith(a)), None)
        if agent is None:
            raise ValueError(f"{path}: cannot tell the agent from the file name; pass agent=")
    agent = check_agent(agent)
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        missing = [c for c in ("diameter_um", *ROW_FIELDS) if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"{path}: missing column(s) {missing}")
        by_d: dict[float, list[dict]] = {}
        for i, raw in enumerate(reader, start=2):
            row = {}
            for k in ROW_FIELDS:
                v = raw[k]
                if k == "status":
                    row[k] = v
                elif k == "fit_success":
                    if v not in ("True", "False"):
                        raise ValueError(f"{path}: row {i}, column fit_success: must be True or False, got {v!r}")
                    row[k] = v == "True"
                else:
                    try:
                        row[k] = float(v) if v not in ("", "nan") else float("nan")
                    except ValueError:
                        raise ValueError(f"{path}: row {i}, column {k}: not a number ({v!r})") from None
            try:
                d = float(raw["diameter_um"])
            except ValueError:
                raise ValueError(f"{path}: row {i}, column diameter_um: not a number "
                                 f"({raw['diameter_um']!r})") from None
            by_d.setdefault(d, []).append(row)
    out = []
    for d, rows in sorted(by_d.items()):
        out.append(SweepResult(agent=agent, diameter_um=d, tier="from rows", mass_factor=float("nan"), rows=rows,
                               traces=[], fits=[None] * len(rows),
                               settings={"agent": agent, "diameter_um": d, "rows_csv": str(path),
                                         "kb": rows[0]["kb"], "mesh_subdivisions": None}))
    return out

