"""One ringdown sweep: simulate R(t) over a k_a grid at one diameter, fit each trace, convert to MHz.

Sweeps vary k_a with μ = k_a / 3 at a fixed k_b per agent (:data:`AGENT_KB`, ``docs/physics.md`` section 5);
b1 = b2 = a3 = a4 = 0. Units: k_a DPD 2-D modulus, k_b DPD energy, ``f_*_dpd`` cycles per DPD time,
``f_*_MHz`` physical MHz (``f = f_dpd sqrt(mass_factor) / u_t``,
:meth:`bubblecal.data.units.UnitSystem.frequency_to_physical`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from bubblecal.data import DEFAULT_UNITS, UnitSystem

__all__ = ["AGENT_KB", "ACOUSTIC_PRIOR", "ROW_FIELDS", "check_agent", "SweepResult", "default_ka_values", "sweep_row",
           "ringdown_sweep"]

#: Fixed bending constant of the acoustic sweeps (DPD energy), ``docs/physics.md`` section 5.
AGENT_KB = {"definity": 389.23, "sonovue": 7850.29}
#: Prior whose k_a box spans the default sweep.
ACOUSTIC_PRIOR = {"definity": "definity_reduced_acoustic", "sonovue": "sonovue_reduced_acoustic"}
#: Columns of one fitted sweep row (CSV and JSON outputs).
ROW_FIELDS = ("ka", "kb", "mu", "seed", "status", "fit_success", "f_res_MHz", "f_0_MHz", "f_res_stderr_MHz",
              "f_res_dpd", "f_0_dpd", "f_d_dpd", "lam_dpd", "r2", "rel_rmse", "n_cycles", "omega0_check7",
              "check7_ratio", "check7_ratio_mesh", "radius_equilibrium", "p_gas")



def check_agent(agent: str) -> str:
    """The agent name in lower case.

    Parameters
    ----------
    agent : str
        'definity' or 'sonovue' (any case).

    Returns
    -------
    str

    Raises
    ------
    ValueError
        Not an agent of :data:`AGENT_KB`.
    """
    a = str(agent).lower()
    if a not in AGENT_KB:
        raise ValueError(f"agent must be one of {sorted(AGENT_KB)}, got {agent!r}")
    return a


def default_ka_values(agent: str, n_ka: int = 28) -> np.ndarray:
    """``n_ka`` evenly spaced k_a values over the agent's acoustic prior range of k_a.

    Parameters
    ----------
    agent : str
        'definity' or 'sonovue'.
    n_ka : int
        Number of values (at least 3: a quadratic needs 3 points).

    Returns
    -------
    ndarray
        k_a values (DPD 2-D modulus).

    Raises
    ------
    ValueError
        Unknown agent or ``n_ka`` < 3.
    """
    from bubblecal.priors import load_priors

    if not isinstance(n_ka, (int, np.integer)) or n_ka < 3:
        raise ValueError(f"n_ka must be an integer >= 3 (a quadratic needs 3 points), got {n_ka!r}")
    lo, hi = load_priors(ACOUSTIC_PRIOR[check_agent(agent)]).bounds("ka").as_tuple()
    return np.linspace(lo, hi, int(n_ka))


@dataclass
class SweepResult:
    """One diameter's sweep.

    Parameters
    ----------
    agent : str
    diameter_um : float
        Bubble diameter [um].
    tier : str
        DPD tier that simulated it ('from rows' when read from a rows CSV).
    mass_factor : float
        Shell mass multiplier of the simulation (undone in the MHz columns).
    rows : list of dict
        One dict with the keys :data:`ROW_FIELDS` per k_a value.
    traces : list of tuple
        (t [DPD time], R(t) [DPD length]) per row; empty when read from a rows CSV.
    fits : list
        :class:`bubblecal.surrogates.RingdownFit` or None per row.
    settings : dict
        What produced the sweep (agent, diameter, tier, k_b, seeds, store or CSV path, ...).
    batch_info : list of dict
        Simulation info per batch (or per record).
    seconds : float
        Wall time [s].
    """

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
        """One column of :attr:`rows` (float; object for 'status')."""
        return np.array([r[name] for r in self.rows], dtype=float if name not in ("status",) else object)

    @property
    def valid(self) -> np.ndarray:
        """Rows usable for the quadratic: status ok, fit success, finite f_res > 0."""
        f = self.column("f_res_MHz")
        return np.array([r["status"] == "ok" and bool(r["fit_success"]) for r in self.rows]) & np.isfinite(f) & (f > 0)

    def summary(self) -> dict:
        """Counts, the median and range of the check-7 ratio (valid rows) and the wall time."""
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
    """Fit one R(t) trace and build its :data:`ROW_FIELDS` row.

    The check-7 ratio (``docs/physics.md`` section 6) is (2π f_0)² / ω0² with the predicted breathing
    frequency ω0² = (16π k_a + 12π R p_gas) / M.

    Parameters
    ----------
    ka, kb : float
        Shell constants (DPD 2-D modulus, DPD energy).
    seed : int
        Replica seed.
    status : str
        Simulation status; only 'ok' traces are fitted.
    t, radius : array_like
        Time [DPD time] and R(t) [DPD length].
    omega0_sq, omega0_sq_mesh : float
        Predicted ω0² [rad² / DPD time²] (sphere area; mesh area).
    radius_equilibrium : float
        Equilibrium radius [DPD length].
    p_gas : float
        Gas pressure [DPD pressure].
    mass_factor : float
        Shell mass multiplier (undone in the MHz conversion).
    units : UnitSystem
    t_start : float or None
        Samples before this DPD time are not fitted.

    Returns
    -------
    tuple
        (row dict, :class:`~bubblecal.surrogates.RingdownFit` or None); frequencies in MHz and
        cycles per DPD time, NaN where the fit failed.
    """
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


def ringdown_sweep(agent: str, diameter_um: float, ka_values: Sequence[float] | None = None, kb: float | None = None,
                   *, tier: str = "implicit", device: str = "cpu", n_ka: int = 28, mass_factor: float = 160.0,
                   seed: int = 0, batch_size: int | None = None, t_start: float | None = None,
                   units: UnitSystem = DEFAULT_UNITS, progress: Callable[[str], None] | None = None,
                   **ringdown_settings) -> SweepResult:
    """Ringdown sweep at one diameter: simulate in batches, fit every R(t), convert to MHz.

    The replicas of a batch are simulated in the same launches by
    :func:`bubblecal.sim.protocols.ringdown.ringdown_batch`; each trace is fitted by :func:`sweep_row`.

    Parameters
    ----------
    agent : str
        'definity' or 'sonovue'.
    diameter_um : float
        Bubble diameter [um].
    ka_values : sequence of float or None
        k_a values (DPD 2-D modulus; None: :func:`default_ka_values` with ``n_ka``).
    kb : float or None
        Bending constant (DPD energy; None: :data:`AGENT_KB`).
    tier : str
        'implicit' or 'explicit'.
    device : str
        Warp device.
    n_ka : int
        Number of default k_a values.
    mass_factor : float
        Shell mass multiplier (undone in the MHz conversion).
    seed : int
        Replica i gets seed + i.
    batch_size : int or None
        Replicas per launch (None: all).
    t_start : float or None
        Samples before this DPD time are not fitted.
    units : UnitSystem
    progress : callable or None
        Receives one-line messages.
    **ringdown_settings
        Passed on to ``ringdown_batch`` (dt, subdivisions, step counts, tier settings).

    Returns
    -------
    SweepResult

    Raises
    ------
    ValueError
        Unknown agent, non-positive or non-finite k_a, or ``batch_size`` < 1.
    """
    from bubblecal.sim.protocols.ringdown import ringdown_batch

    agent = check_agent(agent)
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

