"""Run a shipped campaign in-process on a GPU machine (no CLI / Dask needed there), resumable: campaign throughput.

    python benchmarks/run_campaign.py NAME STORE_DIR [--limit N] [--device cuda] [--diameter D ...]
        [--replicas-per-task N] [--max-replicas R] [--workers W]

Prints one progress line per finished task and the campaign summary as JSON.  Same records as
``bubblecal sim campaign NAME --scheduler inline --store STORE_DIR`` (no Dask needed there); with ``--workers W``
a Dask LocalCluster of W processes sharing the device (``bubblecal sim campaign NAME --workers W``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("name")
    ap.add_argument("store")
    ap.add_argument("--limit", type=int, default=None)
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--diameter", type=float, action="append", default=None, help="only this diameter [um]")
    ap.add_argument("--replicas-per-task", type=int, default=None, help="override (not part of the design)")
    ap.add_argument("--max-replicas", type=int, default=None,
                    help="quasi-static slot refill: replicas relaxing at once (not part of the design)")
    ap.add_argument("--workers", type=int, default=None,
                    help="Dask LocalCluster processes on the device (default: in-process, no Dask)")
    ap.add_argument("--tier-setting", action="append", default=[], metavar="KEY=VALUE",
                    help="override one [tier] setting (a measurement: changes the design, so use a fresh store)")
    args = ap.parse_args(argv)
    from bubblecal.campaigns import load_campaign_file, parse_tier_settings, run_campaign

    overrides = {} if args.max_replicas is None else {"max_replicas": args.max_replicas}
    overrides.update(parse_tier_settings(args.tier_setting))
    cf = load_campaign_file(args.name, store=args.store, tier_overrides=overrides)
    config = dataclasses.replace(cf.config, device=args.device)
    if args.replicas_per_task is not None:
        config = dataclasses.replace(config, replicas_per_task=args.replicas_per_task)
    summary = run_campaign(config, scheduler_address="inline" if args.workers is None else "local",
                           n_workers=args.workers, progress=True, limit=args.limit, diameters=args.diameter)
    print(json.dumps(dataclasses.asdict(summary) if dataclasses.is_dataclass(summary) else vars(summary),
                     default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
