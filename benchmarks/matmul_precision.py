"""Surrogate networks under XLA's dot algorithms: speed of one population evaluation and error against float64.

    python benchmarks/matmul_precision.py --device gpu            # the --paper networks, N = 50,000 x 24 points

For each network (the per-diameter compression 2.1 um and indentation 3.2 um files of the shipped bundle: the
published ``--paper`` set-up, 256-wide; and the default fast networks over the diameter) and each dot
algorithm (full float32 ``F32_F32_F32``, the surrogates' setting; ``TF32_TF32_F32_X3`` and ``BF16_BF16_F32_X6`` /
``_X3``, which split each float32 operand into two or three lower-precision parts; plain ``TF32_TF32_F32``,
the GPU default that the surrogates reject): the median wall time of one jitted forward pass over N parameter
sets x P loading points, and the largest and median relative error of the outputs against a float64 NumPy
forward pass of the same inputs (first 4,000 rows). An algorithm the backend does not support is reported as
such. Prints a table and one JSON line ``{"benchmark": "matmul_precision", ...}``.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

ALGORITHMS = ("F32_F32_F32", "TF32_TF32_F32_X3", "BF16_BF16_F32_X6", "BF16_BF16_F32_X3", "TF32_TF32_F32")


def forward(sur, u, algorithm, xp):
    """The surrogate's standardised forward pass on raw inputs ``u`` with dot ``algorithm`` (None: NumPy)."""
    import jax.numpy as jnp

    z = (u - xp.asarray(sur.in_mean)) / xp.asarray(sur.in_std)
    last = len(sur.weights) - 1
    for i, (w, b) in enumerate(zip(sur.weights, sur.biases, strict=True)):
        w, b = xp.asarray(w), xp.asarray(b)
        z = (jnp.matmul(z, w, precision=algorithm) if xp is jnp else z @ w) + b
        if i < last:
            z = xp.tanh(z)
    return z[..., 0] * xp.asarray(sur.out_std)[0] + xp.asarray(sur.out_mean)[0]


def network_inputs_of(sur, n, points, seed):
    """Raw inputs (n * points, n_in) inside the surrogate's box, float32."""
    from bubblecal.surrogates.features import network_inputs

    rng = np.random.default_rng(seed)
    lo = np.array([sur.param_ranges[k][0] for k in sur.param_names])
    hi = np.array([sur.param_ranges[k][1] for k in sur.param_names])
    params = lo + rng.random((n, len(lo))) * (hi - lo)
    x_lo, x_hi = sur.loading_range()
    x = x_lo + np.linspace(0.05, 0.95, points) * (x_hi - x_lo)
    d = sur.diameter_um if sur.over_diameter else None
    u = network_inputs(sur.inputs, params[:, None, :], x[None, :], d, xp=np, log_inputs=sur.log_inputs)
    return np.asarray(u, dtype=np.float64).reshape(-1, u.shape[-1])


def measure(sur, label, n, points, repeats, algorithms) -> list[dict]:
    """One row per dot algorithm: median ms of one forward pass, relative errors against float64."""
    import jax
    import jax.numpy as jnp

    u64 = network_inputs_of(sur, n, points, seed=0)
    ref = forward(sur, u64[:4000], None, np)
    u = jax.device_put(u64.astype(np.float32))
    rows = []
    for name in algorithms:
        algorithm = getattr(jax.lax.DotAlgorithmPreset, name)
        f = jax.jit(lambda v, a=algorithm: forward(sur, v, a, jnp))
        try:
            y = np.asarray(f(u))
        except Exception as exc:  # noqa: BLE001 - an unsupported algorithm is a result of this benchmark
            rows.append({"network": label, "algorithm": name, "error": str(exc).splitlines()[0][:120]})
            continue
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            f(u).block_until_ready()
            times.append(time.perf_counter() - t0)
        rel = np.abs(y[:4000].astype(np.float64) - ref) / np.maximum(np.abs(ref), 1e-6 * np.max(np.abs(ref)))
        rows.append({"network": label, "algorithm": name, "batch_ms": 1e3 * float(np.median(times)),
                     "rel_err_max": float(rel.max()), "rel_err_median": float(np.median(rel))})
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", choices=("cpu", "gpu"), default="cpu")
    ap.add_argument("--particles", type=int, default=50_000)
    ap.add_argument("--points", type=int, default=24)
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--algorithms", default=",".join(ALGORITHMS))
    args = ap.parse_args(argv)

    import jax

    from bubblecal.surrogates import default_bundle_path, load_bundle

    device = jax.devices(args.device)[0]
    bundle = load_bundle(default_bundle_path())
    nets = [(f"{setup} {d} um {kind}", bundle.get(setup, d, prefer=kind, network="fast"))
            for kind in ("per-diameter", "over-diameter") for setup, d in (("compression", 2.1), ("indentation", 3.2))]
    rows = []
    with jax.default_device(device):
        for label, sur in nets:
            rows += measure(sur, f"{label} {list(sur.architecture['hidden'])}", args.particles, args.points,
                            args.repeats, args.algorithms.split(","))
    print(f"{'network':58s} {'algorithm':18s} {'ms':>8s} {'max rel':>9s} {'med rel':>9s}")
    for r in rows:
        if "error" in r:
            print(f"{r['network']:58s} {r['algorithm']:18s} unsupported: {r['error']}")
        else:
            print(f"{r['network']:58s} {r['algorithm']:18s} {r['batch_ms']:8.2f} {r['rel_err_max']:9.2e} "
                  f"{r['rel_err_median']:9.2e}")
    print(json.dumps({"benchmark": "matmul_precision", "device": str(device), "particles": args.particles,
                      "points": args.points, "rows": rows}))


if __name__ == "__main__":
    main()
