"""Main-job wall time: `bubblecal calibrate` (staged TMCMC, both agents, all phases) on this machine.

    python benchmarks/calibrate.py                       # default population (N = 1000), CPU
    python benchmarks/calibrate.py --paper --device gpu --out /tmp/bench   # published N = 50,000 on a GPU

Runs :func:`bubblecal.workflows.calibrate.run_calibration` for Definity and SonoVue (default workflow
reduced-acoustic) with ``force=True`` (nothing reused). Without ``--bundle`` it first writes the SYNTHETIC
development bundle (closed-form laws, quick settings; its build time is reported separately and not
counted). Phase files are ArviZ NetCDF when ArviZ imports, else ``.npz`` (``--npz`` forces it; the device
image may lack ArviZ); ``--no-figures`` skips figures/report. Needs jax, numpyro, scipy, pandas,
matplotlib. Prints progress with an ETA, a table and a final JSON line; writes ``OUT/benchmark.json``.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--population", type=int, default=None, help="particles per phase (default: the CLI's)")
    ap.add_argument("--paper", action="store_true", help="published settings: N = 50,000, CoV 0.8/0.6, s2 0.04")
    ap.add_argument("--device", default="cpu", choices=("cpu", "gpu", "cuda"))
    ap.add_argument("--workflow", default="reduced-acoustic", choices=("reduced-acoustic", "reduced", "full"))
    ap.add_argument("--agents", default="definity,sonovue")
    ap.add_argument("--bundle", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=Path("benchmark_calibrate"))
    ap.add_argument("--npz", action="store_true", help="phase files as .npz (no ArviZ needed)")
    ap.add_argument("--no-figures", action="store_true")
    ap.add_argument("--phase2-samples", type=int, default=None)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--chunk-size", type=int, default=None, help="TMCMC particles per likelihood batch (memory)")
    args = ap.parse_args(argv)
    device = "gpu" if args.device in ("gpu", "cuda") else "cpu"

    import jax

    from bubblecal.workflows.calibrate import CalibrationConfig, make_plan, run_agent

    netcdf = not args.npz
    if netcdf:
        try:
            import arviz  # noqa: F401
        except ImportError:
            print("arviz not importable: writing .npz phase files", flush=True)
            netcdf = False
    summaries = True
    try:
        import pandas  # noqa: F401
        import scipy  # noqa: F401
    except ImportError:
        print("pandas/scipy not importable: timing the phases only (no summaries, figures)", flush=True)
        summaries = False
        args.no_figures = True
    if args.paper and args.chunk_size is None:
        args.chunk_size = 10_000  # phase 2 at N = 50,000: 50,000 x (6 x 2,000) densities per evaluation
    args.out.mkdir(parents=True, exist_ok=True)
    bundle_seconds = 0.0
    bundle = args.bundle
    if bundle is None:
        from bubblecal.surrogates import write_synthetic_bundle

        t0 = time.perf_counter()
        bundle = write_synthetic_bundle(args.out / "synthetic_bundle", quick=True, progress=lambda m: print("  " + m))
        bundle_seconds = time.perf_counter() - t0
        print(f"synthetic bundle written in {bundle_seconds:.1f} s (not counted)", flush=True)
    config = CalibrationConfig(agents=tuple(args.agents.split(",")), workflow=args.workflow, population=args.population,
                               paper=args.paper, out=args.out / "runs", device=device, bundle=bundle, force=True,
                               seed=args.seed, netcdf=netcdf, figures=not args.no_figures, summaries=summaries,
                               phase2_samples=args.phase2_samples, chunk_size=args.chunk_size)
    t_plan = time.perf_counter()
    plan = make_plan(config)
    t_plan = time.perf_counter() - t_plan
    n_phases = sum(2 * len(a.dataset_names) + 1 for a in plan.agents)
    print(f"N = {config.num_particles} per phase, {n_phases} phases, device {device} "
          f"({jax.devices()[0].device_kind}), workflow {args.workflow}", flush=True)
    t_start = time.perf_counter()
    done = [0]

    def progress(msg: str) -> None:
        if ": running" not in msg:
            done[0] += 1
        el = time.perf_counter() - t_start
        eta = el / done[0] * (n_phases - done[0]) if done[0] else float("nan")
        print(f"[{el:7.1f} s | {done[0]}/{n_phases} phases | ETA {eta:6.0f} s] {msg}", flush=True)

    rows = []
    for agent_plan in plan.agents:
        t0 = time.perf_counter()
        result = run_agent(plan, agent_plan, progress=progress)
        t_fig = 0.0
        if config.figures:
            from bubblecal.workflows.figures import agent_figures
            from bubblecal.workflows.report import write_report

            tf = time.perf_counter()
            result.figures = agent_figures(result, plan)
            result.report = write_report(result, plan)
            t_fig = time.perf_counter() - tf
        s = result.seconds
        rows.append({"agent": agent_plan.agent, "phase1_s": sum(v for k, v in s.items() if k.startswith("phase1")),
                     "phase2_s": s.get("phase2", 0.0),
                     "phase3_s": sum(v for k, v in s.items() if k.startswith("phase3")),
                     "summaries_s": s["summaries"], "figures_s": t_fig, "total_s": time.perf_counter() - t0,
                     "n_datasets": len(agent_plan.dataset_names)})
    total = time.perf_counter() - t_start
    print(f"\n{'agent':10s} {'datasets':>8s} {'phase1':>8s} {'phase2':>8s} {'phase3':>8s} {'summ.':>7s} {'fig.':>6s} "
          f"{'total':>8s}  [s]")
    for r in rows:
        print(f"{r['agent']:10s} {r['n_datasets']:8d} {r['phase1_s']:8.1f} {r['phase2_s']:8.1f} {r['phase3_s']:8.1f} "
              f"{r['summaries_s']:7.1f} {r['figures_s']:6.1f} {r['total_s']:8.1f}")
    print(f"{'both':10s} {'':8s} {'':8s} {'':8s} {'':8s} {'':7s} {'':6s} {total:8.1f}")
    out = {"benchmark": "calibrate", "num_particles": config.num_particles, "paper": args.paper,
           "workflow": args.workflow, "device": device, "device_kind": jax.devices()[0].device_kind,
           "platform": platform.platform(), "python": sys.version.split()[0], "jax": jax.__version__,
           "plan_s": t_plan, "bundle_build_s": bundle_seconds, "total_s": total, "agents": rows,
           "phase2_samples": config.phase2_samples or min(config.num_particles, 2000), "netcdf": netcdf,
           "chunk_size": args.chunk_size, "summaries": summaries,
           "utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    (args.out / "benchmark.json").write_text(json.dumps(out, indent=1))
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
