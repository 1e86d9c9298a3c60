"""Which inputs let one network cover every bubble size: the raw diameter, or the shell's dimensionless groups?

    python benchmarks/studies/diameter_inputs.py STORE [--epochs 400] [--seed 0] [--bands 2.5-2.9,4.5-4.9,6.5-6.9]

Reads the 'ok' curves of a campaign store over a diameter range and trains the same tanh MLP (3 x 64, Adam,
minibatches of 4,096 points, standardised inputs and output) on three parameterisations:

* ``raw``: log ka, log kb, b1, b2, a3, a4, D [um], x  ->  y;
* ``scaled_y``: the same inputs  ->  y~ (below), y = y~ times its scale;
* ``linear``: ka, kb, b1, b2, a3, a4, D, x  ->  y~ (ka and kb not logged);
* ``groups``: the groups of the athermal shell (R = radius_dpd; energies over ka R^2):
  log(kb / (ka R^2)), log(p0 R / ka), b1, b2, a3, a4, x~  ->  y~, with (x~, y~) = (F / (ka R), d / R) for
  indentation and (d / R, F / (ka R)) for compression, and y = y~ times its scale.

Holdouts: whole diameter bands never trained on (``--bands``, levels inside them) and 10 % of the other curves
(grouped by curve).  Prints the median [p90] relative L2 per held-out curve, in the physical response, and a
JSON line; ``--corner LO-HI`` adds the held-out curves with LO < ka < HI (where lipid shells' posteriors lie) as
a third group.  The quasi-static gas pressure p0 = 3 (``IdealGas``) enters the scaled set as a group.
"""

from __future__ import annotations

import argparse
import gzip
import json
import time

import numpy as np

P0 = 3.0  # quasi-static ideal-gas pressure at the reference volume (bubblecal.sim.tiers.quasistatic.IdealGas)


def load(path: str) -> dict:
    """The 'ok' curves of a store: params [n, 6], radius [n], diameter [n], x [n, P], y [n, P], setup."""
    opener = gzip.open if path.endswith(".gz") else open
    rows = []
    with opener(path, "rt") as fh:
        for line in fh:
            r = json.loads(line)
            if r.get("status") == "ok" and "params" in r:
                rows.append(r)
    keys = ("ka", "kb", "b1", "b2", "a3", "a4")
    return {"params": np.array([[r["params"][k] for k in keys] for r in rows]),
            "radius": np.array([r["radius_dpd"] for r in rows]),
            "diameter": np.array([r["provenance"]["diameter_um"] for r in rows]),
            "x": np.array([r["x"] for r in rows]), "y": np.array([r["y"] for r in rows]), "setup": rows[0]["setup"]}


def features(d: dict, kind: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Point-wise inputs [N, 8 or 7], targets [N] and the per-point factor that turns a target into y."""
    p, R, x, y = d["params"], d["radius"][:, None], d["x"], d["y"]
    n, m = x.shape
    ka, kb = p[:, :1], p[:, 1:2]
    rep = lambda a: np.repeat(a, m, axis=0)  # noqa: E731 - per-curve columns to per-point rows
    if d["setup"] == "indentation":
        xt, scale = x / (ka * R), np.broadcast_to(R, x.shape)
    else:
        xt, scale = x / R, np.broadcast_to(ka * R, x.shape)
    if kind in ("raw", "scaled_y", "linear"):
        moduli = p[:, :2] if kind == "linear" else np.log(p[:, :2])
        cols = np.hstack([moduli, p[:, 2:], d["diameter"][:, None]])
        inputs = np.hstack([rep(cols), x.reshape(-1, 1)])
        if kind == "raw":
            return inputs, y.reshape(-1), np.ones(n * m)
        return inputs, (y / scale).reshape(-1), scale.reshape(-1)
    groups = np.hstack([np.log(kb / (ka * R**2)), np.log(P0 * R / ka), p[:, 2:]])
    return np.hstack([rep(groups), xt.reshape(-1, 1)]), (y / scale).reshape(-1), scale.reshape(-1)


def train(xtr: np.ndarray, ytr: np.ndarray, epochs: int, seed: int):
    """A 3 x 64 tanh MLP fitted to standardised data; returns predict(x) -> y."""
    import torch

    torch.manual_seed(seed)
    mx, sx = xtr.mean(0), xtr.std(0) + 1e-12
    my, sy = ytr.mean(), ytr.std() + 1e-12
    X = torch.tensor((xtr - mx) / sx, dtype=torch.float32)
    Y = torch.tensor((ytr - my) / sy, dtype=torch.float32)[:, None]
    net = torch.nn.Sequential(torch.nn.Linear(X.shape[1], 64), torch.nn.Tanh(), torch.nn.Linear(64, 64),
                              torch.nn.Tanh(), torch.nn.Linear(64, 64), torch.nn.Tanh(), torch.nn.Linear(64, 1))
    opt = torch.optim.Adam(net.parameters(), lr=2e-3)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, epochs)
    gen = torch.Generator().manual_seed(seed)
    for _ in range(epochs):
        perm = torch.randperm(len(X), generator=gen)
        for i in range(0, len(X), 4096):
            b = perm[i:i + 4096]
            opt.zero_grad()
            loss = torch.mean((net(X[b]) - Y[b]) ** 2)
            loss.backward()
            opt.step()
        sched.step()

    def predict(x: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            out = net(torch.tensor((x - mx) / sx, dtype=torch.float32)).numpy()[:, 0]
        return out * sy + my

    return predict


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("store")
    ap.add_argument("--epochs", type=int, default=400)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--kinds", default="raw,scaled_y,groups", help="comma-separated parameterisations")
    ap.add_argument("--corner", default=None, metavar="LO-HI", help="also score held-out curves with LO < ka < HI")
    ap.add_argument("--bands", default="2.5-2.9,4.5-4.9,6.5-6.9", help="held-out diameter bands [um]")
    args = ap.parse_args()
    import torch

    torch.set_num_threads(2)
    d = load(args.store)
    n, m = d["x"].shape
    bands = [tuple(float(v) for v in b.split("-")) for b in args.bands.split(",") if b]
    in_band = np.zeros(n, dtype=bool)
    for lo, hi in bands:
        in_band |= (d["diameter"] >= lo - 1e-9) & (d["diameter"] <= hi + 1e-9)
    rng = np.random.default_rng(args.seed)
    held_set = ~in_band & (rng.random(n) < 0.1)
    train_curves = ~in_band & ~held_set
    point = lambda mask: np.repeat(mask, m)  # noqa: E731
    rows = []
    print(f"{d['setup']}: {n} ok curves, levels {np.unique(d['diameter']).size}, {int(in_band.sum())} in the held-out "
          f"bands {args.bands}, {int(held_set.sum())} held-out parameter sets")
    print(f"{'inputs':8s} {'unseen diameters':>22s} {'unseen parameter sets':>24s} {'train s':>8s}")
    groups = [("unseen_diameters", in_band), ("unseen_parameter_sets", held_set)]
    if args.corner:
        lo, hi = (float(v) for v in args.corner.split("-"))
        groups.append(("corner", (in_band | held_set) & (d["params"][:, 0] > lo) & (d["params"][:, 0] < hi)))
    for kind in args.kinds.split(","):
        X, T, scale = features(d, kind)
        t0 = time.perf_counter()
        predict = train(X[point(train_curves)], T[point(train_curves)], args.epochs, args.seed)
        seconds = time.perf_counter() - t0
        y_hat = (predict(X) * scale).reshape(n, m)
        rel = np.linalg.norm(y_hat - d["y"], axis=1) / np.linalg.norm(d["y"], axis=1)
        row = {"inputs": kind, "train_seconds": seconds}
        for name, mask in groups:
            row[name] = {"median": float(np.median(rel[mask])), "p90": float(np.quantile(rel[mask], 0.9)),
                         "n": int(mask.sum())}
        rows.append(row)
        fmt = lambda r: f"{100 * r['median']:.2f} [{100 * r['p90']:.2f}] %"  # noqa: E731
        extra = f" corner {fmt(row['corner'])} (n {row['corner']['n']})" if args.corner else ""
        print(f"{kind:8s} {fmt(row['unseen_diameters']):>22s} {fmt(row['unseen_parameter_sets']):>24s} "
              f"{seconds:8.0f}{extra}", flush=True)
    print(json.dumps({"benchmark": "diameter_inputs", "store": args.store, "setup": d["setup"], "epochs": args.epochs,
                      "bands": args.bands, "rows": rows}))


if __name__ == "__main__":
    main()
