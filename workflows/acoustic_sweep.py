"""Acoustic ringdown sweeps: simulate R(t) over a k_a grid, fit, convert to MHz, fit f_res^2(k_a).

Pipeline (issue 6 items 1 and 5-acoustic, physics.md section 5):

1. :func:`ringdown_sweep` -- one diameter, ``n_ka`` k_a values (default 28, evenly spaced over the
   agent's acoustic prior range of k_a), mu = k_a / 3, k_b fixed (389.23 Definity, 7850.29 SonoVue),
   b1 = b2 = a3 = a4 = 0; the replicas are simulated in batches by
   :func:`bubblecal.sim.protocols.ringdown.ringdown_batch` (all replicas of a batch in the same
   launches), each R(t) is fitted with :func:`bubblecal.surrogates.fit_ringdown` and the DPD
   frequencies are converted with ``f = f_dpd sqrt(mass_factor) / u_t`` through
   :meth:`bubblecal.data.units.UnitSystem.frequency_to_physical`.  The check-7 ratio
   (2 pi f_0)^2 / omega0^2 with omega0^2 = (16 pi k_a + 12 pi R p_gas) / M is reported per row.
2. :func:`fit_sweep` -- :func:`bubblecal.surrogates.fit_quadratic` per diameter
   (f_res^2 = a0 + a1 k_a + a2 k_a^2, f_res in MHz) with leave-one-out relative errors.
3. :func:`write_sweep_outputs` -- CSV (one row per k_a), JSON (rows, fit, settings) and a PNG
   (R(t) with fits; f_res^2 against k_a with the quadratic).

Units: k_a DPD 2-D modulus, k_b DPD energy, f_*_dpd cycles per DPD time, f_*_MHz physical MHz.
"""

from __future__ import annotations

import csv
import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bubblecal.data import DEFAULT_UNITS, UnitSystem, jsonable

__all__ = ["AGENT_KB", "ACOUSTIC_PRIOR", "SweepResult", "default_ka_values", "ringdown_sweep", "fit_sweep",
           "write_sweep_outputs", "ROW_FIELDS", "sweep_row", "sweeps_from_store", "sweeps_from_rows_csv",
           "acoustic_surrogate_from_stores"]

#: Fixed bending constant of the acoustic sweeps (DPD energy), physics.md section 5.
AGENT_KB = {"definity": 389.23, "sonovue": 7850.29}
#: Prior whose k_a box spans the default sweep.
ACOUSTIC_PRIOR = {"definity": "definity_reduced_acoustic", "sonovue": "sonovue_reduced_acoustic"}

ROW_FIELDS = ("ka", "kb", "mu", "seed", "status", "fit_success", "f_res_MHz", "f_0_MHz", "f_res_stderr_MHz",
              "f_res_dpd", "f_0_dpd", "f_d_dpd", "lam_dpd", "r2", "rel_rmse", "n_cycles", "omega0_check7",
              "check7_ratio", "check7_ratio_mesh", "radius_equilibrium", "p_gas")


def _agent(agent: str) -> str:
    a = str(agent).lower()
    if a not in AGENT_KB:
        raise ValueError(f"agent must be one of {sorted(AGENT_KB)}, got {agent!r}")
    return a


def default_ka_values(agent: str, n_ka: int = 28) -> np.ndarray:
    """``n_ka`` evenly spaced k_a values (DPD 2-D modulus) over the agent's acoustic prior range of k_a."""
    from bubblecal.priors import load_priors

    if not isinstance(n_ka, (int, np.integer)) or n_ka < 3:
        raise ValueError(f"n_ka must be an integer >= 3 (a quadratic needs 3 points), got {n_ka!r}")
    lo, hi = load_priors(ACOUSTIC_PRIOR[_agent(agent)]).bounds("ka").as_tuple()
    return np.linspace(lo, hi, int(n_ka))


@dataclass
class SweepResult:
    """One diameter's sweep: ``rows`` (dicts with :data:`ROW_FIELDS`), the traces ``t [T]`` / ``radius [n, T]``
    (DPD time / length; batches may differ in T, then ``traces`` holds (t, radius) per row), the fits
    (:class:`bubblecal.surrogates.RingdownFit` or None per row), settings and timings."""

    agent: str
    diameter_um: float
    tier: str
    mass_factor: float
    rows: list[dict]
    traces: list[tuple[np.ndarray, np.ndarray]]
    fits: list
    settings: dict = field(default_factory=dict)
    batch_info: list[dict] = field(default_factory=list)
    seconds: float = 0.0

    def column(self, name: str) -> np.ndarray:
        return np.array([r[name] for r in self.rows], dtype=float if name not in ("status",) else object)

    @property
    def valid(self) -> np.ndarray:
        """Rows usable for the quadratic: status ok, fit success, finite f_res > 0."""
        f = self.column("f_res_MHz")
        return np.array([r["status"] == "ok" and bool(r["fit_success"]) for r in self.rows]) & np.isfinite(f) & (f > 0)

    def summary(self) -> dict:
        ratio = self.column("check7_ratio")[self.valid]
        ratio_m = self.column("check7_ratio_mesh")[self.valid]
        return {"agent": self.agent, "diameter_um": self.diameter_um, "tier": self.tier,
                "mass_factor": self.mass_factor, "n": len(self.rows), "n_valid": int(self.valid.sum()),
                "check7_ratio_median": float(np.median(ratio)) if ratio.size else float("nan"),
                "check7_ratio_range": [float(ratio.min()), float(ratio.max())] if ratio.size else None,
                "check7_ratio_mesh_median": float(np.median(ratio_m)) if ratio_m.size else float("nan"),
                "seconds": self.seconds}


def sweep_row(ka: float, kb: float, seed: int, status: str, t, radius, *, omega0_sq: float, omega0_sq_mesh: float,
              radius_equilibrium: float, p_gas: float, mass_factor: float, units: UnitSystem = DEFAULT_UNITS,
              t_start: float | None = None) -> tuple[dict, object]:
    """Fit one R(t) trace (``t`` DPD time, ``radius`` DPD length) and build its :data:`ROW_FIELDS` row
    (frequencies in MHz via ``mass_factor``; check-7 ratios against ``omega0_sq`` [rad^2 / DPD time^2]).
    Returns (row, RingdownFit or None)."""
    from bubblecal.surrogates import fit_ringdown

    r = np.asarray(radius, dtype=np.float64)
    fit = None
    if status == "ok" and np.all(np.isfinite(r)):
        try:
            fit = fit_ringdown(np.asarray(t, dtype=np.float64), r, t_start=t_start)
        except (ValueError, RuntimeError):
            fit = None
    row = {"ka": float(ka), "kb": float(kb), "mu": float(ka) / 3.0, "seed": int(seed), "status": status,
           "fit_success": bool(fit is not None and fit.success),
           "omega0_check7": math.sqrt(omega0_sq) if omega0_sq > 0 else float("nan"),
           "radius_equilibrium": float(radius_equilibrium), "p_gas": float(p_gas)}
    if fit is not None:
        mhz = fit.physical_MHz(mass_factor, units)
        conv = float(units.frequency_to_physical(1.0, mass_factor)) / 1e6
        w0 = 2 * math.pi * fit.f_0
        row.update({"f_res_MHz": mhz["f_res"], "f_0_MHz": mhz["f_0"],
                    "f_res_stderr_MHz": fit.f_res_stderr * conv, "f_res_dpd": fit.f_res, "f_0_dpd": fit.f_0,
                    "f_d_dpd": fit.f_d, "lam_dpd": fit.lam, "r2": fit.r2, "rel_rmse": fit.rel_rmse,
                    "n_cycles": fit.n_cycles, "check7_ratio": w0**2 / omega0_sq if omega0_sq > 0 else float("nan"),
                    "check7_ratio_mesh": w0**2 / omega0_sq_mesh if omega0_sq_mesh > 0 else float("nan")})
    return {k: row.get(k, float("nan")) for k in ROW_FIELDS}, fit


def sweeps_from_store(store, agent: str | None = None, t_start: float | None = None,
                      units: UnitSystem = DEFAULT_UNITS) -> list[SweepResult]:
    """Refit the R(t) records of a ringdown campaign store (directory, .jsonl or .jsonl.gz): one
    :class:`SweepResult` per diameter, rows sorted by k_a.  ``agent`` (default: from the campaign name,
    'definity_ringdown' / 'sonovue_ringdown').  Records must be setup 'ringdown' (x = t [DPD time],
    y = R(t) [DPD length]); the check-7 prediction is recomputed from each record's equilibrium radius,
    gas pressure and shell mass (the area ratio of its mesh)."""
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
    agent = _agent(agent)
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


def ringdown_sweep(agent: str, diameter_um: float, ka_values: Sequence[float] | None = None, kb: float | None = None,
                   *, tier: str = "implicit", device: str = "cpu", n_ka: int = 28, mass_factor: float = 160.0,
                   seed: int = 0, batch_size: int | None = None, t_start: float | None = None,
                   units: UnitSystem = DEFAULT_UNITS, progress: Callable[[str], None] | None = None,
                   **ringdown_settings) -> SweepResult:
    """Ringdown sweep at one diameter (see the module docstring).

    ``ka_values`` (DPD; default :func:`default_ka_values` with ``n_ka``), ``kb`` (DPD; default
    :data:`AGENT_KB`), ``tier`` 'implicit' | 'explicit', ``device`` Warp device, ``mass_factor`` (shell mass
    multiplier, undone in the MHz conversion), ``seed`` (replica i gets seed + i), ``batch_size``
    (replicas per launch; default all), ``t_start`` (DPD time: samples before it are not fitted),
    ``progress`` (callable receiving one-line messages), ``ringdown_settings`` passed on to
    :func:`bubblecal.sim.protocols.ringdown.ringdown_batch` (dt, subdivisions, step counts, tier settings).
    """
    from bubblecal.sim.protocols.ringdown import ringdown_batch

    agent = _agent(agent)
    ka = default_ka_values(agent, n_ka) if ka_values is None else np.asarray(ka_values, dtype=np.float64).ravel()
    if ka.size < 1 or not np.all(np.isfinite(ka)) or np.any(ka <= 0):
        raise ValueError(f"ka_values must be finite and > 0 (DPD), got {ka!r}")
    kb = AGENT_KB[agent] if kb is None else float(kb)
    n = ka.size
    bs = n if batch_size is None else int(batch_size)
    if bs < 1:
        raise ValueError(f"batch_size must be >= 1, got {batch_size!r}")
    rows: list[dict] = []
    traces, fits, infos = [], [], []
    t0 = time.perf_counter()
    for b0 in range(0, n, bs):
        sl = slice(b0, min(n, b0 + bs))
        kab = ka[sl]
        seeds = [int(seed) + i for i in range(sl.start, sl.stop)]
        params = {"ka": kab, "kb": np.full(kab.size, kb)}
        tb = time.perf_counter()
        batch = ringdown_batch(float(diameter_um), params, seeds, tier=tier, device=device, mass_factor=mass_factor,
                               **ringdown_settings)
        info = dict(batch.info)
        infos.append(info)
        pred = info.get("prediction", {})
        for j in range(kab.size):
            w2 = float(pred["omega0_sq"][j]) if "omega0_sq" in pred else float("nan")
            w2m = float(pred["omega0_sq_mesh"][j]) if "omega0_sq_mesh" in pred else float("nan")
            row, fit = sweep_row(float(kab[j]), kb, seeds[j], batch.status[j], batch.t, batch.radius[j],
                                 omega0_sq=w2, omega0_sq_mesh=w2m,
                                 radius_equilibrium=float(np.asarray(info.get("radius_equilibrium",
                                                                              [np.nan] * kab.size))[j]),
                                 p_gas=float(np.asarray(info.get("p_gas", [np.nan] * kab.size))[j]),
                                 mass_factor=mass_factor, units=units, t_start=t_start)
            fits.append(fit)
            traces.append((batch.t, batch.radius[j]))
            rows.append(row)
        if progress is not None:
            done = sl.stop
            el = time.perf_counter() - t0
            progress(f"ringdown {agent} {diameter_um:g} um [{tier}]: {done}/{n} k_a values, batch "
                     f"{time.perf_counter() - tb:.1f} s, elapsed {el:.1f} s, ETA {el / done * (n - done):.1f} s")
    settings = {"agent": agent, "diameter_um": float(diameter_um), "tier": tier, "device": device,
                "mass_factor": float(mass_factor), "kb": kb, "seed": int(seed), "batch_size": bs, "t_start": t_start,
                "n_ka": n, "ringdown_settings": {k: v for k, v in ringdown_settings.items() if k != "progress"}}
    return SweepResult(agent=agent, diameter_um=float(diameter_um), tier=tier, mass_factor=float(mass_factor),
                       rows=rows, traces=traces, fits=fits, settings=settings, batch_info=infos,
                       seconds=time.perf_counter() - t0)


def fit_sweep(results: SweepResult | Sequence[SweepResult]) -> dict:
    """:func:`bubblecal.surrogates.fit_quadratic` per diameter over the valid rows.

    Returns {diameter_um: DiameterFit} (f_res in MHz, ka DPD; leave-one-out relative errors of f_res).
    Several results at the same diameter are pooled.
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


def write_sweep_outputs(result: SweepResult, out_dir: str | Path, fit=None, plot: bool = True) -> dict[str, Path]:
    """Write ``ringdown_<agent>_<d>um.csv`` / ``.json`` / ``.png`` (and ``_traces.npz``) into ``out_dir``.

    ``fit``: a DiameterFit (default: :func:`fit_sweep` when >= 3 valid rows).  Returns the paths.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stem = f"ringdown_{result.agent}_{result.diameter_um:g}um"
    if fit is None and result.valid.sum() >= 3:
        fit = fit_sweep(result)[result.diameter_um]
    paths = {"csv": out / f"{stem}.csv", "json": out / f"{stem}.json", "npz": out / f"{stem}_traces.npz"}
    with open(paths["csv"], "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=list(ROW_FIELDS))
        w.writeheader()
        for r in result.rows:
            w.writerow({k: (f"{v:.10g}" if isinstance(v, float) else v) for k, v in r.items()})
    doc = {"summary": result.summary(), "settings": result.settings, "rows": result.rows,
           "fit": None if fit is None else fit.to_dict(),
           "units": {"ka": "DPD 2-D modulus", "kb": "DPD energy", "f_*_MHz": "MHz (sqrt(mass_factor) applied)",
                     "f_*_dpd": "cycles per DPD time", "lam_dpd": "1 / DPD time", "omega0_check7": "rad / DPD time",
                     "radius_equilibrium": "DPD length", "p_gas": "DPD pressure"},
           "batch_info": [{k: v for k, v in b.items() if k not in ("health_final", "health_after_perturbation")}
                          for b in result.batch_info]}
    paths["json"].write_text(json.dumps(jsonable(doc, nonfinite_as_none=True), indent=1))
    lens = {t.size for t, _ in result.traces}
    if len(lens) == 1 and result.traces:
        np.savez_compressed(paths["npz"], t=result.traces[0][0], radius=np.stack([r for _, r in result.traces]),
                            ka=result.column("ka"))
    else:
        np.savez_compressed(paths["npz"], **{f"t_{i}": t for i, (t, _) in enumerate(result.traces)},
                            **{f"radius_{i}": r for i, (_, r) in enumerate(result.traces)}, ka=result.column("ka"))
    if plot:
        paths["png"] = out / f"{stem}.png"
        _plot(result, fit, paths["png"])
    return paths


def _plot(result: SweepResult, fit, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.5))
    n = len(result.rows)
    picks = sorted({0, n // 2, n - 1}) if n else []
    for i in picks:
        t, r = result.traces[i]
        (line,) = ax1.plot(t, r, ".", ms=2, label=f"k_a = {result.rows[i]['ka']:.0f}")
        f = result.fits[i]
        if f is not None:
            ax1.plot(t, f.predict(t), "-", lw=1, color=line.get_color())
    ax1.set_xlabel("t [DPD time]")
    ax1.set_ylabel("R(t) = (3V/4pi)^(1/3) [DPD length]")
    ax1.set_title(f"{result.agent} {result.diameter_um:g} um, {result.tier}: ringdown + damped-sine fit")
    ax1.legend(fontsize=8)
    ka = result.column("ka")
    f = result.column("f_res_MHz")
    ok = result.valid
    ax2.plot(ka[ok], f[ok] ** 2, "o", label="simulated f_res^2")
    if (~ok).any():
        ax2.plot(ka[~ok], np.where(np.isfinite(f[~ok]), f[~ok] ** 2, np.nan), "x", color="grey", label="invalid")
    if fit is not None:
        kk = np.linspace(ka.min(), ka.max(), 200)
        ax2.plot(kk, fit.a0 + fit.a1 * kk + fit.a2 * kk**2, "-",
                 label=f"quadratic (LOO median {100 * fit.loo_median:.2f} %)")
    ax2.set_xlabel("k_a [DPD]")
    ax2.set_ylabel("f_res^2 [MHz^2]")
    ax2.set_title(f"mass factor {result.mass_factor:g} (undone: f x sqrt(M))")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def sweeps_from_rows_csv(path: str | Path, agent: str | None = None) -> list[SweepResult]:
    """Read fitted ringdown rows (CSV of ``diameter_um`` + :data:`ROW_FIELDS`, e.g. the shipped
    ``data/training/<agent>_ringdown_rows.csv``): one :class:`SweepResult` per diameter (no traces).
    ``agent`` default: from the file name.  Raises ValueError naming the file, row and column on bad input."""
    path = Path(path)
    if agent is None:
        agent = next((a for a in AGENT_KB if path.name.startswith(a)), None)
        if agent is None:
            raise ValueError(f"{path}: cannot tell the agent from the file name; pass agent=")
    agent = _agent(agent)
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
                raise ValueError(f"{path}: row {i}, column diameter_um: not a number ({raw['diameter_um']!r})") from None
            by_d.setdefault(d, []).append(row)
    out = []
    for d, rows in sorted(by_d.items()):
        out.append(SweepResult(agent=agent, diameter_um=d, tier="from rows", mass_factor=float("nan"), rows=rows,
                               traces=[], fits=[None] * len(rows),
                               settings={"agent": agent, "diameter_um": d, "rows_csv": str(path),
                                         "kb": rows[0]["kb"], "mesh_subdivisions": None}))
    return out


def acoustic_surrogate_from_stores(stores: Sequence, out: str | Path, agent: str | None = None,
                                   rows_csv: str | Path | None = None, t_start: float | None = None):
    """Refit every R(t) of ringdown campaign ``stores`` and save the agent's acoustic surrogate.

    ``stores`` may also name row CSVs written by an earlier call (``rows_csv``; no refit, e.g. the shipped
    ``data/training/*_ringdown_rows.csv``).

    One f_res^2(k_a) quadratic per diameter (f_res in MHz, k_a DPD) with leave-one-out errors; the JSON at
    ``out`` carries the provenance (stores, tier, mesh level, counts, check-7 ratios, LOO errors).
    ``rows_csv``: also write every fitted row (diameter_um + :data:`ROW_FIELDS`).  Raises ValueError when a
    diameter has fewer than 3 valid rows.  Returns (AcousticSurrogate, list of SweepResult).
    """
    from bubblecal.surrogates import AcousticSurrogate

    sweeps: list[SweepResult] = []
    for st in stores:
        if str(st).endswith(".csv"):
            sweeps.extend(sweeps_from_rows_csv(st, agent=agent))
        else:
            sweeps.extend(sweeps_from_store(st, agent=agent, t_start=t_start))
    agents = {s.agent for s in sweeps}
    if len(agents) != 1:
        raise ValueError(f"stores hold several agents {sorted(agents)}: one acoustic surrogate per agent")
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
        with open(rows_csv, "w", newline="", encoding="utf-8") as fh:
            w = csv.DictWriter(fh, fieldnames=["diameter_um", *ROW_FIELDS])
            w.writeheader()
            for s in sweeps:
                for r in s.rows:
                    w.writerow({"diameter_um": f"{s.diameter_um:g}",
                                **{k: (f"{v:.10g}" if isinstance(v, float) else v) for k, v in r.items()}})
    return sur, sweeps
