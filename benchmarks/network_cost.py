"""Cost of the accurate vs the fast network over the diameter: one evaluation batch and one phase-1 TMCMC.

    python benchmarks/network_cost.py                      # CPU, both protocols, bubbles syn-001..syn-003
    python benchmarks/network_cost.py --bubbles syn-001 --particles 1000

Per loading protocol and network role (``Bundle.get(..., network='accurate'|'fast')``): the time of one jitted
evaluation of N particles x P points at a bound diameter (median of repeats, after compilation). Then, for each
bubble of ``benchmarks/studies/synthetic_population_40/curves.csv`` named by ``--bubbles`` (compression, priors
``definity_reduced``), one phase-1 TMCMC (the calibrate phase-1 model and options: N particles, 10 MH steps) with
each network: wall time (the first bubble of a network includes the compilation of its programs, shared by the
next ones), the posterior mean and 90 % interval of ka. Prints a table and one JSON line
``{"benchmark": "network_cost", ...}``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
CURVES = HERE / "studies" / "synthetic_population_40" / "curves.csv"
ROLES = ("accurate", "fast")


def eval_batch(bundle, setup: str, network: str, n: int, points: int, diameter_um: float, repeats: int) -> dict:
    """Median wall time [ms] of one jitted evaluation of ``n`` parameter sets x ``points`` loading points."""
    import jax
    import jax.numpy as jnp

    from bubblecal.surrogates import flops_per_point

    sur = bundle.get(setup, diameter_um, prefer="over-diameter", network=network)
    rng = np.random.default_rng(0)
    lo = np.array([sur.param_ranges[k][0] for k in sur.param_names])
    hi = np.array([sur.param_ranges[k][1] for k in sur.param_names])
    params = jnp.asarray(lo + rng.random((n, 6)) * (hi - lo), dtype=jnp.float32)
    top = sur.loading_range_per_size[1] * (2 * sur.radius_dpd if setup == "compression" else 1.0)
    x = jnp.asarray(np.linspace(0.05, 0.95, points) * top, dtype=jnp.float32)
    f = jax.jit(lambda p, xx: sur(p[:, None, :], xx[None, :]))
    f(params, x).block_until_ready()  # compile
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f(params, x).block_until_ready()
        times.append(time.perf_counter() - t0)
    hidden = list(sur.architecture["hidden"])
    return {"setup": setup, "network": network, "hidden": hidden,
            "flops_per_point": flops_per_point([len(sur.input_names), *hidden, 1]),
            "batch_ms": 1e3 * float(np.median(times))}


def phase1(bundle, bubble, network: str, particles: int, steps: int, seed: int) -> dict:
    """One phase-1 TMCMC of one bubble with the ``network`` role: wall [s] and the ka posterior summary."""
    import jax

    from bubblecal.inference.hierarchical import run_phase
    from bubblecal.models import TracedSurrogate, mechanical_model
    from bubblecal.priors import load_priors
    from bubblecal.workflows.calibrate.config import CalibrationConfig, phase_tmcmc_options

    spec = load_priors("definity_reduced")
    curve = bubble.loading_curve()
    sur = bundle.get(curve.kind, curve.diameter_um, network=network)
    o1, _ = phase_tmcmc_options(CalibrationConfig(population=particles, num_mcmc_steps=steps))
    args = (np.asarray(curve.x), np.asarray(curve.y), TracedSurrogate.wrap(sur), spec)
    t0 = time.perf_counter()
    res = run_phase(f"phase1_{curve.name}", mechanical_model, args, {}, jax.random.PRNGKey(seed), o1)
    wall = time.perf_counter() - t0
    ka = np.asarray(res.samples["ka"])
    return {"bubble": curve.name, "diameter_um": float(curve.diameter_um), "network": network,
            "hidden": list(sur.architecture["hidden"]), "over_diameter": bool(sur.over_diameter), "wall_s": wall,
            "ka_mean": float(ka.mean()), "ka_q05": float(np.quantile(ka, 0.05)),
            "ka_q95": float(np.quantile(ka, 0.95)), "log_evidence": res.log_evidence}


def main(argv=None) -> dict:
    """Run the benchmark and print the table and the JSON line."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bubbles", default="syn-001,syn-002,syn-003", help="Bubbles of the synthetic population.")
    ap.add_argument("--particles", type=int, default=2000, help="TMCMC particles (and batch rows).")
    ap.add_argument("--steps", type=int, default=10, help="MH steps per TMCMC stage.")
    ap.add_argument("--points", type=int, default=20, help="Loading points of the evaluation batch.")
    ap.add_argument("--repeats", type=int, default=20, help="Timed repeats of the evaluation batch.")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-tmcmc", action="store_true", help="Only the evaluation batches.")
    a = ap.parse_args(argv)

    from bubblecal.data import read_bubble_curves
    from bubblecal.surrogates import default_bundle_path, load_bundle

    bundle = load_bundle(default_bundle_path(must_exist=True))
    batches = [eval_batch(bundle, setup, role, a.particles, a.points, 4.5, a.repeats)
               for setup in ("compression", "indentation") for role in ROLES]
    print(f"\none evaluation: {a.particles} particles x {a.points} points at 4.5 um, jit, "
          f"{os.cpu_count()} CPU core(s)")
    print(f"{'protocol':12s} {'network':9s} {'hidden':18s} {'flops/pt':>9s} {'batch ms':>9s}")
    for r in batches:
        print(f"{r['setup']:12s} {r['network']:9s} {str(r['hidden']):18s} {r['flops_per_point']:9d} "
              f"{r['batch_ms']:9.2f}")
    runs = []
    if not a.no_tmcmc:
        wanted = [b.strip() for b in a.bubbles.split(",") if b.strip()]
        by_name = {b.bubble: b for b in read_bubble_curves(CURVES)}
        missing = [w for w in wanted if w not in by_name]
        if missing:
            raise SystemExit(f"{CURVES}: no bubble(s) {', '.join(missing)}")
        for role in ROLES:  # one network's bubbles in a row: its programs compile on the first one
            runs += [phase1(bundle, by_name[w], role, a.particles, a.steps, a.seed) for w in wanted]
        print(f"\nphase-1 TMCMC, priors definity_reduced, N = {a.particles}, {a.steps} MH steps "
              "(first bubble of a network: compilation included)")
        print(f"{'bubble':8s} {'D um':>6s} {'network':9s} {'wall s':>7s} {'ka mean':>9s} {'ka 90% interval':>22s}")
        for r in runs:
            print(f"{r['bubble']:8s} {r['diameter_um']:6.3f} {r['network']:9s} {r['wall_s']:7.1f} "
                  f"{r['ka_mean']:9.0f} [{r['ka_q05']:9.0f}, {r['ka_q95']:9.0f}]")
    out = {"benchmark": "network_cost", "machine": platform.node(), "cpus": os.cpu_count(),
           "particles": a.particles, "points": a.points, "steps": a.steps, "batches": batches, "phase1": runs}
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
