"""Batched TMCMC benchmark: K datasets of one structure, one by one (as ``run_staged`` runs phase 1) vs one batch.

Model (surrogate-shaped, traced like the calibration's): a tanh MLP 7→256×4→1 with softplus output and random
fixed weights (the weights are model arguments, the same arrays for every dataset, so a batch passes them
once); each dataset is a curve of 20-30 points drawn from its own parameters with 5 % multiplicative noise,
padded to the longest with a mask; 8 parameters (k_a, k_b, b1, b2, a3, a4, d0, σ) under a box prior.  TMCMC:
robust preset, N = ``--population`` particles, 10 RW steps per stage, target CoV 0.8.

Modes (``--modes``): ``split`` = ``TMCMC(...).run`` per dataset (host-driven stages, what the pipeline runs),
``fused`` = the same with ``compiled=True`` (one ``lax.while_loop`` per dataset), ``batched`` =
:func:`bubblecal.inference.run_batched` over all K.  For each K and mode: *first* = wall time of the first call
(compilation included; for split/fused one dataset, for batched the whole batch), *run* = wall time of all K
datasets with the programs compiled (split/fused: K runs; batched: the batch again with other keys),
compile ≈ first − (its share of run).  The log Z of every dataset is compared across modes (fused and batched
agree to float round-off; split differs from them by round-off amplified through accept/reject).

    python benchmarks/tmcmc_batch.py --k 1,10 --population 2000                  # 2 CPU cores
    python benchmarks/tmcmc_batch.py --k 1,10,50,200 --population 50000 --device gpu --modes split,fused,batched

The last line printed is one JSON object with every number.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time


def _parse():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--k", default="1,10", help="comma list of dataset counts K")
    p.add_argument("--population", type=int, default=2000, help="TMCMC particles N per dataset")
    p.add_argument("--device", choices=("cpu", "gpu"), default="cpu")
    p.add_argument("--modes", default="split,batched", help="comma list of split, fused, batched")
    p.add_argument("--points", type=int, default=30, help="points of the longest curve")
    p.add_argument("--min-points", type=int, default=20, help="points of the shortest curve")
    p.add_argument("--width", type=int, default=256, help="hidden units per layer")
    p.add_argument("--layers", type=int, default=4, help="hidden layers")
    p.add_argument("--steps", type=int, default=10, help="RW MH steps per stage")
    p.add_argument("--batch-size", type=int, default=None, help="runs per batched program (default: automatic)")
    p.add_argument("--chunk-size", type=int, default=None, help="particles per likelihood evaluation")
    p.add_argument("--seed", type=int, default=0)
    return p.parse_args()


ARGS = _parse() if __name__ == "__main__" else None
if ARGS is not None:
    os.environ.setdefault("JAX_PLATFORMS", "cpu" if ARGS.device == "cpu" else "cuda")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import numpyro  # noqa: E402
import numpyro.distributions as dist  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
from bubblecal.inference import TMCMC, run_batched  # noqa: E402

LO = np.array([-1, -1, -1, -1, -1, -1, 0.0, 0.01], np.float32)
HI = np.array([1, 1, 1, 1, 1, 1, 0.2, 0.2], np.float32)
NOISE_FLOOR = 1e-6  # floor on the sd (σ ŷ) so a prediction of 0 keeps the density finite


def predict(theta, x, weights, biases):
    """Curve ŷ(x) of the MLP at parameters θ (8,): shape inputs θ[:6], offset d0 = θ[6]."""
    xt = jnp.maximum(0.0, x - theta[6])
    h = jnp.concatenate([jnp.broadcast_to(theta[:6], (x.shape[0], 6)), xt[:, None]], axis=1)
    for w, b in zip(weights[:-1], biases[:-1], strict=True):
        h = jnp.tanh(h @ w + b)
    return jax.nn.softplus(h @ weights[-1] + biases[-1])[:, 0]


def curve_model(x, y, mask, weights, biases):
    """One padded curve under the box prior, multiplicative Gaussian noise σ ŷ."""
    theta = numpyro.sample("theta", dist.Uniform(jnp.asarray(LO), jnp.asarray(HI)).to_event(1))
    y_hat = predict(theta, x, weights, biases)
    with numpyro.handlers.mask(mask=mask):
        numpyro.sample("y", dist.Normal(y_hat, jnp.maximum(theta[7] * y_hat, NOISE_FLOOR)), obs=y)


def make_datasets(k: int, seed: int, points: int, min_points: int, width: int, layers: int):
    """K (x, y, mask, weights, biases) argument tuples sharing one network (the same arrays)."""
    rng = np.random.default_rng(seed)
    sizes = [7] + [width] * layers + [1]
    weights = tuple(jnp.asarray(rng.normal(0, 1 / math.sqrt(a), (a, b)), jnp.float32)
                    for a, b in zip(sizes[:-1], sizes[1:], strict=True))
    biases = tuple(jnp.asarray(rng.normal(0, 0.1, b), jnp.float32) for b in sizes[1:])
    out = []
    for _ in range(k):
        n = int(rng.integers(min_points, points + 1))
        x = np.linspace(0.0, 1.0, n, dtype=np.float32)
        theta = np.concatenate([rng.uniform(-0.6, 0.6, 6), [0.05, 0.05]]).astype(np.float32)
        y_hat = np.asarray(predict(jnp.asarray(theta), jnp.asarray(x), weights, biases))
        y = (y_hat * (1 + 0.05 * rng.normal(size=n))).astype(np.float32)
        pad = points - n
        out.append((np.r_[x, np.full(pad, x[-1], np.float32)], np.r_[y, np.zeros(pad, np.float32)],
                    np.arange(points) < n, weights, biases))
    return out


def _timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def run_mode(mode: str, datasets, keys, options: dict, batch_size):
    """(first-call seconds, compiled-run seconds for all K, log Z per dataset) of one mode."""
    if mode == "batched":
        _, first = _timed(lambda: run_batched(curve_model, datasets, None, keys[1], batch_size=batch_size,
                                              **options))
        out, run = _timed(lambda: run_batched(curve_model, datasets, None, keys[0], batch_size=batch_size,
                                              **options))
        return first, run, [r.log_evidence for r in out]
    compiled = mode == "fused"
    _, first = _timed(lambda: TMCMC(curve_model, compiled=compiled, **options).run(keys[1][0], *datasets[0]))
    out, run = _timed(lambda: [TMCMC(curve_model, compiled=compiled, **options).run(key, *args)
                               for key, args in zip(keys[0], datasets, strict=True)])
    return first, run, [r.log_evidence for r in out]


def main(args) -> dict:
    """Run every K and mode, print the table; returns the numbers."""
    options = {"num_particles": args.population, "num_mcmc_steps": args.steps, "target_cov": 0.8,
               "chunk_size": args.chunk_size}
    modes = [m.strip() for m in args.modes.split(",") if m.strip()]
    rows = []
    print(f"device {jax.devices()[0].device_kind} ({jax.default_backend()}), N = {args.population}, "
          f"MLP 7-{args.width}x{args.layers}-1, {args.min_points}-{args.points} points")
    print(f"{'K':>5} {'mode':>8} {'first s':>9} {'compile s':>10} {'run s':>9} {'s/dataset':>10} "
          f"{'max |dlogZ| vs first mode':>26}")
    for k in [int(v) for v in args.k.split(",")]:
        datasets = make_datasets(k, args.seed, args.points, args.min_points, args.width, args.layers)
        base = jax.random.PRNGKey(args.seed)
        keys = [list(jax.random.split(jax.random.fold_in(base, j), k)) for j in (0, 1)]
        ref = None
        for mode in modes:
            first, run, log_z = run_mode(mode, datasets, keys, options, args.batch_size)
            # the first call ran one dataset (split, fused) or the whole batch (batched)
            share = run if mode == "batched" else run / k
            diff = None if ref is None else float(np.max(np.abs(np.asarray(log_z) - ref)))
            ref = np.asarray(log_z) if ref is None else ref
            row = {"K": k, "mode": mode, "first_s": first, "compile_s": max(first - share, 0.0), "run_s": run,
                   "per_dataset_s": run / k, "max_abs_dlogz": diff, "mean_log_z": float(np.mean(log_z))}
            rows.append(row)
            diff_txt = "-" if diff is None else f"{diff:.2e}"
            print(f"{k:>5} {mode:>8} {first:>9.2f} {row['compile_s']:>10.2f} {run:>9.2f} {run / k:>10.3f} "
                  f"{diff_txt:>26}", flush=True)
    return {"benchmark": "tmcmc_batch", "device": jax.devices()[0].device_kind, "backend": jax.default_backend(),
            "population": args.population, "width": args.width, "layers": args.layers, "points": args.points,
            "min_points": args.min_points, "steps": args.steps, "batch_size": args.batch_size,
            "chunk_size": args.chunk_size, "cpu_count": os.cpu_count(), "python": platform.python_version(),
            "jax": jax.__version__, "rows": rows}


if __name__ == "__main__":
    print(json.dumps(main(ARGS)))
