"""When each process of the main job does what: `bubblecal calibrate` with its worker and writer processes on one
clock.

    python benchmarks/main_job_timeline.py --out /tmp/tl                              # default main job, CPU
    BUBBLECAL_CACHE_DIR=C python benchmarks/main_job_timeline.py --paper --device gpu --out /tmp/tl

Every argument goes to ``bubblecal calibrate``, run in this process. The steps of the run (plan, preflight, the
wait for the workers, each TMCMC phase, the phase files' exports, writes and final wait, summaries, each figure,
the report, the process's end) are timed in every process: the hooks are installed when this file is imported, and
the command's spawned processes import it again as their ``__mp_main__``. A hook wraps a function when its module
is first imported, so the order of imports stays the command's own. Prints one row per step (start and end in
seconds from this process's start, process: caller, worker, writer, figures, or helper for one that only started,
step) and per process its first and last step, then one JSON line.
"""

from __future__ import annotations

import functools
import importlib.abc
import importlib.util
import json
import os
import sys
import time

#: This process's start on the shared clock (children measure from the parent's start).
_EPOCH = float(os.environ.setdefault("BUBBLECAL_TIMELINE_EPOCH", repr(time.time())))
_T0 = time.perf_counter() - (time.time() - _EPOCH)

#: module -> names to time ("Class.method" for methods).
HOOKS = {
    "bubblecal.workflows.calibrate.plan": ["make_plan"],
    "bubblecal.workflows.calibrate.preflight": ["preflight"],
    "bubblecal.workflows.calibrate.parallel": ["AgentProcesses.prestart", "AgentProcesses.start",
                                               "AgentProcesses.wait_ready"],
    "bubblecal.workflows.calibrate.agent_worker": ["preload", "_work"],
    "bubblecal.workflows.calibrate.run": ["run_agent"],
    "bubblecal.inference.hierarchical": ["run_phase"],
    "bubblecal.inference._phase_batch": ["_compile_ahead"],
    "bubblecal.workflows.calibrate.store": ["PhaseStore.save", "PhaseStore.flush"],
    "bubblecal.workflows.calibrate.writer": ["_write"],
    "bubblecal.workflows.summary": ["summarise_agent"],
    "bubblecal.workflows.figures": ["agent_figures", "fit_figure", "forest_figure", "diameter_figure",
                                    "ka_kb_figure", "population_figure", "acoustic_figure"],
    "bubblecal.workflows.calibrate.figure_processes": ["FigureProcesses.draw", "_draw"],
    "bubblecal.workflows.report": ["write_report"],
    "bubblecal.workflows.console": ["end_process"],
}


def _record(name: str, t0: float, t1: float) -> None:
    """Append one step (seconds on the shared clock) to the timeline file; O_APPEND lines do not interleave."""
    path = os.environ.get("BUBBLECAL_TIMELINE")
    if not path:
        return
    line = json.dumps({"pid": os.getpid(), "name": name, "t0": round(t0 - _T0, 4), "t1": round(t1 - _T0, 4)})
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        os.write(fd, (line + "\n").encode())
    finally:
        os.close(fd)


def _timed(fn, label: str):
    @functools.wraps(fn)
    def timed(*args, **kwargs):
        name = args[0] if label == "run_phase" and args and isinstance(args[0], str) else label
        t0 = time.perf_counter()
        if label == "end_process":  # it never returns: the step is the moment of the exit
            _record(name, t0, t0)
        try:
            return fn(*args, **kwargs)
        finally:
            _record(name, t0, time.perf_counter())

    return timed


def _patch(module) -> None:
    """Wrap the functions of ``module`` named in :data:`HOOKS`."""
    for target in HOOKS.get(module.__name__, ()):
        owner, _, attr = target.rpartition(".")
        holder = getattr(module, owner, None) if owner else module
        fn = getattr(holder, attr, None) if holder is not None else None
        if fn is not None and not getattr(fn, "_timeline", False):
            wrapped = _timed(fn, attr)
            wrapped._timeline = True
            setattr(holder, attr, wrapped)


class _Finder(importlib.abc.MetaPathFinder):
    """Patches a hooked module right after it is executed."""

    def find_spec(self, fullname, path, target=None):
        if fullname not in HOOKS:
            return None
        sys.meta_path.remove(self)
        try:
            spec = importlib.util.find_spec(fullname)
        finally:
            sys.meta_path.insert(0, self)
        if spec is None or spec.loader is None:
            return None
        exec_module = spec.loader.exec_module

        def exec_and_patch(module):
            exec_module(module)
            _patch(module)

        spec.loader.exec_module = exec_and_patch
        return spec


sys.meta_path.insert(0, _Finder())
for _name in HOOKS:
    if _name in sys.modules:
        _patch(sys.modules[_name])


def _report(path: str, total: float) -> dict:
    """Print the steps in order and each process's span; return the JSON record."""
    with open(path, encoding="utf-8") as fh:
        rows = [json.loads(line) for line in fh]
    rows.sort(key=lambda r: r["t0"])
    me = os.getpid()
    steps: dict[int, set] = {}
    for r in rows:
        steps.setdefault(r["pid"], set()).add(r["name"])

    def role(pid: int) -> str:
        if pid == me:
            return "caller"
        return next((who for step, who in (("_work", "worker"), ("_draw", "figures"), ("_write", "writer"))
                     if step in steps[pid]), "helper")

    roles = {pid: role(pid) for pid in steps}
    print(f"\n{'start s':>8} {'end s':>8} {'s':>6}  {'process':<14} step")
    for r in rows:
        print(f"{r['t0']:>8.2f} {r['t1']:>8.2f} {r['t1'] - r['t0']:>6.2f}  {roles[r['pid']] + ':' + str(r['pid']):<14} "
              f"{r['name']}")
    spans = {}
    for r in rows:
        s = spans.setdefault(r["pid"], [r["t0"], r["t1"]])
        s[0], s[1] = min(s[0], r["t0"]), max(s[1], r["t1"])
    print(f"\n{'process':<14} {'first s':>8} {'last s':>8}")
    for pid, (a, b) in sorted(spans.items(), key=lambda kv: kv[1][0]):
        print(f"{roles[pid] + ':' + str(pid):<14} {a:>8.2f} {b:>8.2f}")
    print(f"total (this process) {total:.2f} s")
    return {"benchmark": "main_job_timeline", "wall_s": round(total, 2),
            "steps": [{**r, "process": roles[r["pid"]]} for r in rows]}


def main(argv=None) -> dict:
    """Run ``bubblecal calibrate`` with ``argv`` under the hooks; print the timeline and a JSON line."""
    import tempfile

    argv = sys.argv[1:] if argv is None else argv
    fd, path = tempfile.mkstemp(prefix="bubblecal-timeline-", suffix=".jsonl")
    os.close(fd)
    os.environ["BUBBLECAL_TIMELINE"] = path
    from bubblecal.workflows.cli import app

    try:
        app(["calibrate", *argv], standalone_mode=False)
    finally:
        total = time.perf_counter() - _T0
        record = _report(path, total)
        print(json.dumps({**record, "args": list(argv)}))
        os.unlink(path)
    return record


if __name__ == "__main__":
    main()
