"""Where the main job's time goes: `bubblecal calibrate` in this process, split into sections, compile vs run.

    python benchmarks/main_job_profile.py --out /tmp/prof                      # default main job, CPU
    python benchmarks/main_job_profile.py --out /tmp/prof --paper --device gpu --npz

Every argument goes to ``bubblecal calibrate``. Sections: imports, the plan (bundle load, data and prior checks,
domain warnings), the likelihood preflight (with every phase-1 program compiled ahead), the programs of each later
phase compiled ahead, each TMCMC phase, each phase's export (pointwise log likelihood, handing the file to the writer)
and the wait for the writer, summaries, figures, report.md, and the rest (printing). JAX logs every XLA
compilation (``jax_log_compiles``); each one's seconds are charged to the section that was running, so "run s" =
wall - compile (negative where several programs compiled at once). A program read back from the persistent
compilation cache counts as a cache hit (its load seconds still count as compile seconds). Prints a table and one
JSON line.
"""

from __future__ import annotations

import json
import logging
import os
import re
import sys
import time

_T0 = time.perf_counter()

_COMPILE = re.compile(r"Finished XLA compilation of (\S+) in ([0-9.eE+-]+) sec")
_HIT = re.compile(r"Persistent compilation cache hit for '([^']+)'")


class _Profile(logging.Handler):
    """Sections in order with wall, compile seconds, compilations and cache hits (a logging handler of JAX)."""

    def __init__(self):
        super().__init__(logging.DEBUG)
        self.rows: dict[str, dict] = {}
        self.stack = ["rest"]

    def row(self, name):
        return self.rows.setdefault(name, {"wall_s": 0.0, "compile_s": 0.0, "compiles": 0, "cache_hits": 0,
                                           "programs": {}})

    def emit(self, record):
        msg = record.getMessage()
        m = _COMPILE.search(msg)
        r = self.row(self.stack[-1])
        if m:
            r["compile_s"] += float(m.group(2))
            r["compiles"] += 1
            r["programs"][m.group(1)] = r["programs"].get(m.group(1), 0) + 1
        elif _HIT.search(msg):
            r["cache_hits"] += 1

    def wrap(self, owner, attr, name):
        """Replace ``owner.attr`` by a timed call charged to section ``name`` (a callable of the args too)."""
        fn = getattr(owner, attr)
        prof = self

        def timed(*args, **kwargs):
            label = name(*args, **kwargs) if callable(name) else name
            prof.stack.append(label)
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                prof.stack.pop()
                dt = time.perf_counter() - t0
                prof.row(label)["wall_s"] += dt
                for outer in prof.stack[1:]:  # nested sections: the outer one keeps only its own time
                    prof.row(outer)["wall_s"] -= dt

        setattr(owner, attr, timed)


def main(argv=None) -> dict:
    """Profile one ``bubblecal calibrate`` run with ``argv``; print the table and a JSON line."""
    argv = sys.argv[1:] if argv is None else argv
    prof = _Profile()
    logging.getLogger("jax").addHandler(prof)
    logging.getLogger("jax").setLevel(logging.WARNING)
    os.environ.setdefault("JAX_LOG_COMPILES", "1")
    t0 = time.perf_counter()
    import jax

    jax.config.update("jax_log_compiles", True)
    import bubblecal.inference._phase_batch as phase_batch
    import bubblecal.inference.hierarchical as hierarchical
    import bubblecal.workflows.calibrate as calibrate
    import bubblecal.workflows.calibrate.plan as plan_module
    import bubblecal.workflows.calibrate.preflight as preflight_module
    import bubblecal.workflows.figures as figures
    import bubblecal.workflows.report as report
    import bubblecal.workflows.summary as summary
    from bubblecal.workflows.cli import app

    prof.row("imports")["wall_s"] = time.perf_counter() - t0 + (t0 - _T0)
    prof.wrap(calibrate, "make_plan", "plan (bundle, checks)")
    prof.wrap(plan_module, "preflight", "preflight")
    prof.wrap(preflight_module, "preflight", "preflight")  # the command's own agents (agent processes)
    prof.wrap(calibrate.AgentProcesses, "wait_ready", "wait for the worker processes' preflight")
    prof.wrap(hierarchical, "run_phase", lambda name, *a, **k: name)
    prof.wrap(phase_batch, "_compile_ahead", "compile ahead (phases)")
    prof.wrap(calibrate.PhaseStore, "save", "phase files (export)")
    prof.wrap(calibrate.PhaseStore, "flush", "phase files (wait)")
    prof.wrap(summary, "summarise_agent", "summaries")
    prof.wrap(figures, "agent_figures", "figures")
    prof.wrap(report, "write_report", "report")
    t_cmd = time.perf_counter()
    try:
        app(["calibrate", *argv], standalone_mode=False)
    finally:
        total = time.perf_counter() - _T0
        accounted = sum(r["wall_s"] for k, r in prof.rows.items() if k != "rest")
        prof.row("rest")["wall_s"] = total - accounted
        _print(prof, total, time.perf_counter() - t_cmd, argv)
    return prof.rows


def _print(prof: _Profile, total: float, command: float, argv) -> None:
    """The table (one row per section) and the JSON line."""
    print(f"\n{'section':<44} {'wall s':>8} {'compile s':>10} {'run s':>8} {'compiles':>9} {'hits':>5}")
    for name, r in prof.rows.items():
        print(f"{name:<44} {r['wall_s']:>8.1f} {r['compile_s']:>10.1f} {r['wall_s'] - r['compile_s']:>8.1f} "
              f"{r['compiles']:>9} {r['cache_hits']:>5}")
    n = sum(r["compiles"] for r in prof.rows.values())
    hits = sum(r["cache_hits"] for r in prof.rows.values())
    distinct = {p for r in prof.rows.values() for p in r["programs"]}
    print(f"{'total':<44} {total:>8.1f} {sum(r['compile_s'] for r in prof.rows.values()):>10.1f} {'':>8} {n:>9} "
          f"{hits:>5}")
    print(f"{n - hits} programs compiled ({len(distinct)} distinct names), {hits} read from the cache; "
          f"load average {os.getloadavg()[0]:.2f}")
    rows = {k: {kk: (round(v, 2) if isinstance(v, float) else v) for kk, v in r.items() if kk != "programs"}
            for k, r in prof.rows.items()}
    print(json.dumps({"benchmark": "main_job_profile", "args": list(argv), "wall_s": round(total, 1),
                      "command_s": round(command, 1), "compiled": n - hits, "cache_hits": hits,
                      "load": round(os.getloadavg()[0], 2), "sections": rows}))


if __name__ == "__main__":
    main()
