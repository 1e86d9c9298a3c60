"""The synthetic population study: 40 bubbles from a known population, simulated with the quasi-static tier.

Whether ``bubblecal calibrate --data CURVES.csv`` recovers a population it has never seen, at diameters where no
published curve exists (docs/synthetic-study.md).  Two sub-commands:

``generate``
    Draws a population (true m and tau of k_a and k_b inside the hyperprior boxes of the ``definity_reduced``
    priors), ``--n`` bubbles from it (diameter uniform in [1.8, 6.0] um, k_a and k_b from the truncated normal on
    the prior box, d0 uniform in the inner half of its prior range, a fixed relative noise sigma), simulates every
    bubble with the quasi-static tier of the campaign ``definity_compression_1.5-8um`` (its loading fractions,
    tier settings and mesh level; all bubbles in one request), redraws a bubble whose curve is not 'ok', adds the
    likelihood's relative noise (models/likelihood.py) and writes ``DIR/curves.csv`` (the tidy format,
    docs/data-formats.md) and ``DIR/truth.json``.  The written file is read back with the tidy reader.
``evaluate``
    Checks the calibration's ``summary.csv`` against the truth (benchmarks/synthetic_population_checks.py).

Usage::

    python benchmarks/synthetic_population.py generate --n 40 --seed 1 --device cuda --out SYN
    bubblecal calibrate --data SYN/curves.csv --out CAL
    python benchmarks/synthetic_population.py evaluate --truth SYN/truth.json --calibration CAL/synthetic/reduced
    python benchmarks/synthetic_population.py generate --n 2 --seed 1 --device cpu --subdivisions 2 --out /tmp/syn

Each sub-command prints a table and one JSON line (``{"benchmark": "synthetic_population", ...}``).
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from scipy.special import ndtr, ndtri
from synthetic_population_checks import StudyError, evaluate, print_evaluation, read_summary

from bubblecal.data import (
    CURVE_COLUMNS,
    CURVE_OPTIONAL,
    DEFAULT_UNITS,
    NONLINEAR_PARAMETERS,
    atomic_write,
    read_bubble_curves,
)
from bubblecal.models.likelihood import SD_FLOOR_REL
from bubblecal.workflows.summary import PHYSICAL

CAMPAIGN = "definity_compression_1.5-8um"
PRIORS = "definity_reduced"
#: Diameters of the study [um]: inside the network's 1.5-8 um, where its training data reach (~6.2 um).
DIAMETER_RANGE_UM = (1.8, 6.0)
#: Relative noise of every bubble: calibrations of published curves find sigma ~0.03 and the synthetic recovery
#: tests use 0.06 (benchmarks/RESULTS.md); the inner half of the U(0, 1) prior (0.25-0.75) is noise no AFM curve shows.
SIGMA = 0.05
#: A true hyperparameter must lie this fraction of its hyperprior box's width away from either end.
MARGIN = 0.1


@dataclass(frozen=True)
class Population:
    """The true population (DPD units): k_i ~ Normal(m_k, tau_k^2) truncated to the prior box.

    Parameters
    ----------
    m_ka, tau_ka, m_kb, tau_kb : float
        Mean and spread of k_a [DPD 2-D modulus] (E = 26.9 MPa, 7.2 MPa) and of k_b [DPD energy].
    """

    m_ka: float = 15000.0
    tau_ka: float = 4000.0
    m_kb: float = 500.0
    tau_kb: float = 150.0


def check_population(pop: Population, spec) -> None:
    """Refuse a population whose m or tau is not well inside the hyperprior boxes.

    Parameters
    ----------
    pop : Population
        The true population (DPD units).
    spec : bubblecal.priors.PriorSpec
        The priors whose ``hyper_m`` and ``hyper_tau`` boxes bound the truth.

    Raises
    ------
    StudyError
        Naming the hyperparameter, its value and the allowed range (the box less :data:`MARGIN` of its width).
    """
    problems = []
    for k in ("ka", "kb"):
        p = spec.parameters[k]
        for what, box in (("m", p.hyper_m), ("tau", p.hyper_tau)):
            v, lo, hi = getattr(pop, f"{what}_{k}"), box.lo + MARGIN * box.width, box.hi - MARGIN * box.width
            if not lo <= v <= hi:
                problems.append(f"{what}_{k} = {v:g} lies outside [{lo:g}, {hi:g}] (the hyper_{what} box of "
                                f"{spec.name}, {box.lo:g}-{box.hi:g}, less {MARGIN:g} of its width at each end)")
    if problems:
        raise StudyError("; ".join(problems))


def truncnorm_draw(rng: np.random.Generator, m: float, tau: float, lo: float, hi: float, size: int) -> np.ndarray:
    """Draws of Normal(m, tau^2) truncated to [lo, hi] by the inverse CDF (the population of docs/inference.md).

    Parameters
    ----------
    rng : numpy.random.Generator
        Random source.
    m, tau : float
        Mean and spread of the untruncated normal (units of the parameter), tau > 0.
    lo, hi : float
        Truncation bounds, lo < hi, with mass Phi(beta) - Phi(alpha) not negligible.
    size : int
        Number of draws.

    Returns
    -------
    numpy.ndarray
        ``size`` draws in [lo, hi].

    Raises
    ------
    StudyError
        If tau <= 0, lo >= hi, or the truncation mass underflows (bounds many tau away from m).
    """
    if not (tau > 0 and lo < hi):
        raise StudyError(f"truncated normal needs tau > 0 and lo < hi, got tau = {tau:g}, [{lo:g}, {hi:g}]")
    a, b = ndtr((lo - m) / tau), ndtr((hi - m) / tau)
    if b - a < 1e-12:
        raise StudyError(f"truncated normal: [{lo:g}, {hi:g}] holds no mass of Normal({m:g}, {tau:g}^2)")
    return np.clip(m + tau * ndtri(rng.uniform(a, b, size)), lo, hi)  # clip: rounding of ndtri at the ends only


def noise_sd(yhat: np.ndarray, sigma: float, floor_rel: float = SD_FLOOR_REL) -> np.ndarray:
    """The likelihood's noise sd, sqrt((sigma yhat)^2 + floor^2), floor = floor_rel * max|yhat| (models/likelihood.py).

    Parameters
    ----------
    yhat : numpy.ndarray
        Noise-free curve [DPD force].
    sigma : float
        Relative noise amplitude [-].
    floor_rel : float
        The floor relative to the curve's largest |y| (the likelihood takes the observed curve's; the noise-free
        one here, which differs by O(sigma) of a 1e-4 floor).

    Returns
    -------
    numpy.ndarray
        Standard deviations [DPD force], the shape of ``yhat``.
    """
    yhat = np.asarray(yhat, dtype=float)
    return np.sqrt((sigma * yhat) ** 2 + (floor_rel * np.max(np.abs(yhat))) ** 2)


def observe(rng: np.random.Generator, yhat: np.ndarray, sigma: float) -> np.ndarray:
    """One noisy observation y ~ Normal(yhat, :func:`noise_sd` ^2) of a curve [DPD force]."""
    yhat = np.asarray(yhat, dtype=float)
    return yhat + noise_sd(yhat, sigma) * rng.standard_normal(yhat.shape)


def draw_bubbles(rng: np.random.Generator, pop: Population, spec, n: int, sigma: float = SIGMA) -> list[dict]:
    """``n`` bubbles of the population: diameter [um], ka, kb, d0 [DPD] and sigma.

    Parameters
    ----------
    rng : numpy.random.Generator
        Random source.
    pop : Population
        True population.
    spec : bubblecal.priors.PriorSpec
        The prior boxes of ka, kb (truncation) and d0 (its inner half).
    n : int
        Number of bubbles.
    sigma : float
        Relative noise of every bubble, inside the prior of ``spec.mechanical_noise_name``.

    Returns
    -------
    list of dict
        One dict per bubble: ``diameter_um``, ``ka``, ``kb``, ``d0``, ``sigma``.
    """
    d = rng.uniform(*DIAMETER_RANGE_UM, n)
    ka = truncnorm_draw(rng, pop.m_ka, pop.tau_ka, *spec.parameters["ka"].prior.as_tuple(), n)
    kb = truncnorm_draw(rng, pop.m_kb, pop.tau_kb, *spec.parameters["kb"].prior.as_tuple(), n)
    d0 = rng.uniform(*_inner_half(spec, "d0"), n)
    return [{"diameter_um": float(d[i]), "ka": float(ka[i]), "kb": float(kb[i]), "d0": float(d0[i]),
             "sigma": float(sigma)} for i in range(n)]


def tidy_rows(bubbles: list[dict], agent: str) -> list[list[str]]:
    """Rows of a tidy curve file (columns ``CURVE_COLUMNS + CURVE_OPTIONAL``), nm and nN.

    Parameters
    ----------
    bubbles : list of dict
        Each with ``id``, ``diameter_um`` [um], ``x`` (displacement, DPD length) and ``y`` (force, DPD force).
    agent : str
        The agent label of every row.

    Returns
    -------
    list of list of str
        One row per point, every point retained; numbers as ``repr`` (exact round trip).
    """
    rows = []
    for b in bubbles:
        x_nm, y_nN = DEFAULT_UNITS.dpd_to_nm(np.asarray(b["x"])), DEFAULT_UNITS.dpd_to_nN(np.asarray(b["y"]))
        rows += [[b["id"], agent, "compression", repr(float(b["diameter_um"])), repr(float(x)), repr(float(y)), "1"]
                 for x, y in zip(x_nm, y_nN, strict=True)]
    return rows


def write_tidy(path: Path, rows: list[list[str]], check=None) -> Path:
    """Write a tidy curve file atomically (header ``CURVE_COLUMNS + CURVE_OPTIONAL``); ``check(tmp)`` runs on the
    written temporary file first, so a file that fails it never replaces ``path``."""
    def writer(tmp: Path) -> None:
        with open(tmp, "w", newline="", encoding="utf-8") as handle:
            out = csv.writer(handle, lineterminator="\n")
            out.writerow(CURVE_COLUMNS + CURVE_OPTIONAL)
            out.writerows(rows)
        if check is not None:
            check(tmp)
    return atomic_write(path, writer)


def check_tidy(path: Path, bubbles: list[dict], agent: str) -> None:
    """Read ``path`` with the tidy reader and compare with the bubbles written (DPD, relative 1e-9).

    Raises
    ------
    bubblecal.data.TidyDataError
        The reader refused the file.
    StudyError
        A bubble read back differs (id, agent, diameter or a point).
    """
    read = read_bubble_curves(path)
    if [b.bubble for b in read] != [b["id"] for b in bubbles]:
        raise StudyError(f"{path}: bubbles read back {[b.bubble for b in read]}, written {[b['id'] for b in bubbles]}")
    for r, b in zip(read, bubbles, strict=True):
        same = r.agent == agent and r.protocol == "compression" and r.diameter_um == b["diameter_um"] \
            and np.allclose(r.x, b["x"], rtol=1e-9, atol=0) and np.allclose(r.y, b["y"], rtol=1e-9, atol=0)
        if not same:
            raise StudyError(f"{path}: bubble {b['id']!r} read back differs from what was written")


def simulate(config, bubbles: list[dict], spec, device: str, subdivisions: int, seed: int):
    """Quasi-static curves of the bubbles in one request (one diameter and loading grid per replica).

    Returns
    -------
    (numpy.ndarray, list of str, numpy.ndarray, list of int)
        Both-plate forces [R, P] (DPD force), statuses, grids [R, P] (total displacement, DPD length), FIRE
        steps per curve.
    """
    from bubblecal.sim.tiers import CurveRequest, get_tier

    diameters = [b["diameter_um"] for b in bubbles]
    grids = np.array([config.grid_for(d) for d in diameters])
    params = {"ka": [b["ka"] for b in bubbles], "kb": [b["kb"] for b in bubbles]}
    params |= {k: np.full(len(bubbles), float(spec.fixed[k])) for k in NONLINEAR_PARAMETERS}
    request = CurveRequest(protocol=config.protocol, diameter_um=diameters[0], grid=tuple(grids[0]), params=params,
                           seeds=tuple(seed + i for i in range(len(bubbles))), subdivisions=subdivisions,
                           diameters_um=tuple(diameters), grids=grids)
    batch = get_tier("quasistatic", **config.tier_settings).run(request, device)
    status = [s if s != "ok" or np.all(np.isfinite(row)) else "failed"
              for s, row in zip(batch.status, batch.observable, strict=True)]
    return batch.observable, status, grids, [int(v) for v in batch.info.get("fire_steps", [0] * len(bubbles))]


def population_truth(pop: Population) -> dict:
    """m and tau of ka and kb in DPD units and in the physical units of ``summary.csv`` (E [MPa], kappa [k_BT])."""
    out = {}
    for k in ("ka", "kb"):
        unit, pname, punit, conv = PHYSICAL[k]
        m, tau = getattr(pop, f"m_{k}"), getattr(pop, f"tau_{k}")
        out[k] = {"m": m, "tau": tau, "unit": unit, "physical": pname, "physical_unit": punit,
                  "m_phys": float(conv(m)), "tau_phys": float(conv(m + tau) - conv(m))}  # affine: a spread maps so
    return out


def generate(args) -> dict:
    """The ``generate`` sub-command: draw, simulate (redrawing failures), add noise, write and check."""
    from bubblecal.campaigns import load_campaign_file
    from bubblecal.priors import load_priors

    t0 = time.perf_counter()
    spec, config = load_priors(PRIORS), load_campaign_file(CAMPAIGN).config
    pop = Population()
    check_population(pop, spec)
    if not spec.bounds(spec.mechanical_noise_name).contains(args.sigma):
        raise StudyError(f"--sigma {args.sigma:g} lies outside the noise prior {spec.bounds('sigma').as_tuple()}")
    sub = args.subdivisions if args.subdivisions is not None else config.subdivisions
    draw_rng, noise_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(args.seed).spawn(2))
    bubbles = draw_bubbles(draw_rng, pop, spec, args.n, args.sigma)
    todo, redrawn, rounds = list(range(args.n)), [], []
    for attempt in range(args.max_rounds):
        t1 = time.perf_counter()
        y, status, grids, steps = simulate(config, [bubbles[i] for i in todo], spec, args.device, sub,
                                           args.seed * 1000 + attempt * args.n)
        rounds.append({"curves": len(todo), "seconds": time.perf_counter() - t1, "fire_steps": steps})
        for j, i in enumerate(todo):
            bubbles[i] |= {"status": status[j], "yhat": y[j], "grid": grids[j], "fire_steps": steps[j]}
        failed = [i for i in todo if bubbles[i]["status"] != "ok"]
        redrawn += [{k: bubbles[i][k] for k in ("diameter_um", "ka", "kb", "d0", "status", "fire_steps")}
                    for i in failed]
        for i, fresh in zip(failed, draw_bubbles(draw_rng, pop, spec, len(failed), args.sigma), strict=True):
            bubbles[i] = fresh
        todo = failed
        if not todo:
            break
    if todo:
        raise StudyError(f"{len(todo)} bubbles still not 'ok' after {args.max_rounds} rounds of redraws")
    for i, b in enumerate(bubbles):
        b["id"] = f"syn-{i + 1:03d}"
        b["x"] = b["grid"] + b["d0"]  # compression: y = S(theta; x - d0) (models/likelihood.py)
        b["y"] = observe(noise_rng, b["yhat"], b["sigma"])
        if np.any(b["y"] < 0):
            raise StudyError(f"bubble {b['id']}: a noisy force is negative (the tidy format refuses it); "
                             f"lower --sigma ({args.sigma:g})")
    out = Path(args.out)
    write_tidy(out / "curves.csv", tidy_rows(bubbles, args.agent), lambda tmp: check_tidy(tmp, bubbles, args.agent))
    unit_ka, unit_kb, unit_d0 = PHYSICAL["ka"][3], PHYSICAL["kb"][3], PHYSICAL["d0"][3]
    truth = {"benchmark": "synthetic_population", "seed": args.seed, "n": args.n, "agent": args.agent,
             "protocol": "compression", "priors": PRIORS, "campaign": CAMPAIGN, "tier": "quasistatic",
             "tier_settings": dict(config.tier_settings), "subdivisions": sub, "device": args.device,
             "diameter_range_um": list(DIAMETER_RANGE_UM), "d0_range": [float(v) for v in _inner_half(spec, "d0")],
             "sigma": args.sigma, "population": population_truth(pop), "population_dpd": asdict(pop),
             "redraws": len(redrawn), "redrawn": redrawn,
             "bubbles": [{"id": b["id"], "diameter_um": b["diameter_um"], "ka": b["ka"], "kb": b["kb"],
                          "d0": b["d0"], "sigma": b["sigma"], "status": b["status"], "fire_steps": b["fire_steps"],
                          "E_MPa": float(unit_ka(b["ka"])), "kappa_kBT": float(unit_kb(b["kb"])),
                          "d0_nm": float(unit_d0(b["d0"])), "max_force_nN": float(DEFAULT_UNITS.dpd_to_nN(
                              np.max(b["y"])))} for b in bubbles],
             "rounds": rounds, "seconds_simulation": sum(r["seconds"] for r in rounds),
             "seconds_total": time.perf_counter() - t0}
    atomic_write(out / "truth.json", lambda tmp: tmp.write_text(json.dumps(truth, indent=1)))
    return truth


def _inner_half(spec, name: str) -> tuple[float, float]:
    """The inner half of a prior range."""
    b = spec.parameters[name].prior
    return b.lo + b.width / 4, b.hi - b.width / 4


def _print_generate(truth: dict) -> None:
    print(f"{'bubble':8s} {'D [um]':>6s} {'ka':>8s} {'E [MPa]':>8s} {'kb':>7s} {'d0 [nm]':>8s} {'sigma':>6s} "
          f"{'Fmax [nN]':>9s} status")
    for b in truth["bubbles"]:
        print(f"{b['id']:8s} {b['diameter_um']:6.2f} {b['ka']:8.0f} {b['E_MPa']:8.2f} {b['kb']:7.1f} "
              f"{b['d0_nm']:8.1f} {b['sigma']:6.3f} {b['max_force_nN']:9.3f} {b['status']}")
    p = truth["population"]
    print(f"population: m_ka {p['ka']['m']:g} ({p['ka']['m_phys']:.2f} MPa), tau_ka {p['ka']['tau']:g}; "
          f"m_kb {p['kb']['m']:g}, tau_kb {p['kb']['tau']:g}; redraws {truth['redraws']}; "
          f"simulation {truth['seconds_simulation']:.1f} s, total {truth['seconds_total']:.1f} s")
    keys = ("benchmark", "seed", "n", "agent", "subdivisions", "device", "redraws", "seconds_simulation",
            "seconds_total")
    print(json.dumps({"command": "generate", **{k: truth[k] for k in keys}}))


def main(argv: list[str] | None = None) -> int:
    """Parse, run one sub-command, print; 0 when generated or every check passed, 1 on a failed check."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    g = sub.add_parser("generate", help="draw, simulate and write curves.csv + truth.json")
    g.add_argument("--n", type=int, default=40, help="bubbles")
    g.add_argument("--seed", type=int, required=True)
    g.add_argument("--device", default="cuda", help="Warp device: cpu or cuda")
    g.add_argument("--out", required=True, help="output folder")
    g.add_argument("--subdivisions", type=int, default=None, help="mesh level (default: the campaign's)")
    g.add_argument("--agent", default="synthetic", help="agent label of the tidy file (its output folder)")
    g.add_argument("--sigma", type=float, default=SIGMA, help="relative noise of every bubble")
    g.add_argument("--max-rounds", type=int, default=5, help="rounds of redraws of failed simulations")
    e = sub.add_parser("evaluate", help="check a calibration's summary.csv against truth.json")
    e.add_argument("--truth", required=True, help="truth.json of generate")
    e.add_argument("--calibration", required=True, help="OUT/<agent>/<workflow> (or its summary.csv)")
    args = ap.parse_args(argv)
    try:
        if args.command == "generate":
            if args.n < 1:
                raise StudyError(f"--n must be >= 1, got {args.n}")
            _print_generate(generate(args))
            return 0
        truth = json.loads(Path(args.truth).read_text())
        result = evaluate(truth, read_summary(args.calibration))
        print_evaluation(result)
        return 0 if result["pass"] else 1
    except StudyError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
