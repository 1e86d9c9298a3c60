"""Milliseconds per Adam step of the surrogate trainer: CPU (1 thread), CUDA eager, CUDA graphs.

    python benchmarks/train_step_bench.py [--points 81000] [--epochs 3]

Prints a table and one JSON line.  Each run trains ``--epochs`` epochs of the standard recipe (batch 256) on
random inputs; the time per step is the epoch wall time over the number of batches.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np


def main() -> None:
    import torch

    from bubblecal.surrogates.training import TrainConfig, train_mlp

    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=81000)
    ap.add_argument("--epochs", type=int, default=3)
    ap.add_argument("--archs", default="32x2,128x3,256x4")
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    u = rng.uniform(size=(args.points, 7))
    y = np.tanh(u @ rng.normal(size=7))
    paths = [("cpu", {"device": "cpu"})]
    if torch.cuda.is_available():
        paths += [("cuda eager", {"device": "cuda", "cuda_graphs": False}), ("cuda graphs", {"device": "cuda"})]
    n_steps = args.epochs * int(np.ceil(0.9 * args.points / 256))
    rows = []
    for arch in args.archs.split(","):
        w, d = (int(v) for v in arch.split("x"))
        for name, kw in paths:
            cfg = TrainConfig(max_epochs=args.epochs, patience=10**6, **kw)
            t0 = time.perf_counter()
            train_mlp(u, y, (w,) * d, cfg, progress=False)
            ms = 1e3 * (time.perf_counter() - t0) / n_steps
            rows.append({"arch": arch, "path": name, "ms_per_step": ms})
            print(f"{arch:>7} {name:>12} {ms:8.3f} ms/step", flush=True)
    dev = torch.cuda.get_device_name(0) if torch.cuda.is_available() else "cpu only"
    print(json.dumps({"benchmark": "train_step", "device": dev, "points": args.points, "rows": rows}))


if __name__ == "__main__":
    main()
