"""Acoustic ringdown sweeps: simulate R(t) over a k_a grid, fit, convert to MHz, fit f_res^2(k_a).

Pipeline (issue 6 items 1 and 5-acoustic, physics.md section 5):

1. :func:`ringdown_sweep` -- one diameter, ``n_ka`` k_a values (default 28, evenly spaced over the
   agent's acoustic prior range of k_a), mu = k_a / 3, k_b fixed (389.23 Definity, 7850.29 SonoVue),
   b1 = b2 = a3 = a4 = 0; the replicas are simulated in batches by
   :func:`bubblecal.sim.experiments.ringdown.ringdown_batch` (all replicas of a batch in the same
   launches), each R(t) is fitted with :func:`bubblecal.surrogates.acoustic.fit_ringdown` and the DPD
   frequencies are converted with ``f = f_dpd sqrt(mass_factor) / u_t`` through
   :meth:`bubblecal.data.units.UnitSystem.frequency_to_physical`.  The check-7 ratio
   (2 pi f_0)^2 / omega0^2 with omega0^2 = (16 pi k_a + 12 pi R p_gas) / M is reported per row.
2. :func:`fit_sweep` -- :func:`bubblecal.surrogates.acoustic.fit_quadratic` per diameter
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

from bubblecal.data.files import jsonable
from bubblecal.data.units import DEFAULT_UNITS, UnitSystem

__all__ = ["AGENT_KB", "ACOUSTIC_PRIOR", "SweepResult", "default_ka_values", "ringdown_sweep", "fit_sweep",
           "write_sweep_outputs", "ROW_FIELDS"]

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
    from bubblecal.priors.spec import load_priors

    if not isinstance(n_ka, (int, np.integer)) or n_ka < 3:
        raise ValueError(f"n_ka must be an integer >= 3 (a quadratic needs 3 points), got {n_ka!r}")
    lo, hi = load_priors(ACOUSTIC_PRIOR[_agent(agent)]).bounds("ka").as_tuple()
    return np.linspace(lo, hi, int(n_ka))


@dataclass
class SweepResult:
    """One diameter's sweep: ``rows`` (dicts with :data:`ROW_FIELDS`), the traces ``t [T]`` / ``radius [n, T]``
    (DPD time / length; batches may differ in T, then ``traces`` holds (t, radius) per row), the fits
    (:class:`bubblecal.surrogates.acoustic.RingdownFit` or None per row), settings and timings."""

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
    :func:`bubblecal.sim.experiments.ringdown.ringdown_batch` (dt, subdivisions, step counts, tier settings).
    """
    from bubblecal.sim.experiments.ringdown import ringdown_batch
    from bubblecal.surrogates.acoustic import fit_ringdown

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
            r = batch.radius[j]
            fit = None
            if batch.status[j] == "ok" and np.all(np.isfinite(r)):
                try:
                    fit = fit_ringdown(batch.t, r, t_start=t_start)
                except (ValueError, RuntimeError):
                    fit = None
            fits.append(fit)
            traces.append((batch.t, r))
            w2 = float(pred["omega0_sq"][j]) if "omega0_sq" in pred else float("nan")
            w2m = float(pred["omega0_sq_mesh"][j]) if "omega0_sq_mesh" in pred else float("nan")
            row = {"ka": float(kab[j]), "kb": kb, "mu": float(kab[j]) / 3.0, "seed": seeds[j],
                   "status": batch.status[j], "fit_success": bool(fit is not None and fit.success),
                   "omega0_check7": math.sqrt(w2) if w2 > 0 else float("nan"),
                   "radius_equilibrium": float(np.asarray(info.get("radius_equilibrium", [np.nan] * kab.size))[j]),
                   "p_gas": float(np.asarray(info.get("p_gas", [np.nan] * kab.size))[j])}
            if fit is not None:
                mhz = fit.physical_MHz(mass_factor, units)
                conv = float(units.frequency_to_physical(1.0, mass_factor)) / 1e6
                w0 = 2 * math.pi * fit.f_0
                row.update({"f_res_MHz": mhz["f_res"], "f_0_MHz": mhz["f_0"],
                            "f_res_stderr_MHz": fit.f_res_stderr * conv, "f_res_dpd": fit.f_res, "f_0_dpd": fit.f_0,
                            "f_d_dpd": fit.f_d, "lam_dpd": fit.lam, "r2": fit.r2, "rel_rmse": fit.rel_rmse,
                            "n_cycles": fit.n_cycles, "check7_ratio": w0**2 / w2 if w2 > 0 else float("nan"),
                            "check7_ratio_mesh": w0**2 / w2m if w2m > 0 else float("nan")})
            rows.append({k: row.get(k, float("nan")) for k in ROW_FIELDS})
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
    """:func:`bubblecal.surrogates.acoustic.fit_quadratic` per diameter over the valid rows.

    Returns {diameter_um: DiameterFit} (f_res in MHz, ka DPD; leave-one-out relative errors of f_res).
    Several results at the same diameter are pooled.
    """
    from bubblecal.surrogates.acoustic import fit_quadratic

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
