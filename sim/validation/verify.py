"""``bubblecal sim verify``: the physics checks of docs/physics.md section 6 behind one call.

Runs the fluid / gas / impermeability checks (:mod:`bubblecal.sim.validation.fluid_checks`) and the shell
checks (:data:`bubblecal.sim.validation.checks.ALL_SHELL_CHECKS`), prints a table (check, expected, measured,
tolerance, pass) and, last, one JSON line; the exit status is non-zero when any check fails (a check
that raises counts as failed, with the error in its details).
"""

from __future__ import annotations

import json
import sys
import time
import traceback
from collections.abc import Callable, Sequence

from bubblecal.sim.validation.checks import ALL_SHELL_CHECKS
from bubblecal.sim.validation.fluid_checks import ALL_FLUID_CHECKS
from bubblecal.sim.validation.result import CheckResult

__all__ = ["all_checks", "run_checks", "render_table", "summary_json", "main"]


def all_checks() -> list[Callable[..., CheckResult]]:
    """Every check, fluid checks first, then the shell checks (the shell list is looked up at call time).

    Returns
    -------
    list of callable
        ``check(quick=..., device=...) -> CheckResult``.
    """
    from bubblecal.sim.validation import checks as shell_checks

    return list(ALL_FLUID_CHECKS) + list(getattr(shell_checks, "ALL_SHELL_CHECKS", ALL_SHELL_CHECKS))


def run_checks(quick: bool = True, device: str = "cpu", only: Sequence[str] | None = None,
               progress: Callable[[CheckResult, float], None] | None = None) -> list[CheckResult]:
    """Run every check, or those whose function name contains one of ``only``.

    A check that raises counts as failed, with the error and a short traceback in its details.

    Parameters
    ----------
    quick : bool, optional
        Quick versions (CPU-sized) or full ones.
    device : str, optional
        Warp device.
    only : sequence of str, optional
        Substrings of the check function names to run.
    progress : callable, optional
        ``progress(result, seconds)`` after each check.

    Returns
    -------
    list of CheckResult
    """
    results = []
    for fn in all_checks():
        if only and not any(o in fn.__name__ for o in only):
            continue
        t0 = time.perf_counter()
        try:
            res = fn(quick=quick, device=device)
        except Exception as exc:  # a crash is a failed check, with the reason
            res = CheckResult(name=fn.__name__, expected="runs", measured=f"error: {type(exc).__name__}",
                              tolerance="-", passed=False,
                              details={"error": str(exc), "traceback": traceback.format_exc(limit=4)})
        res.details.setdefault("seconds", round(time.perf_counter() - t0, 2))
        results.append(res)
        if progress is not None:
            progress(res, time.perf_counter() - t0)
    return results


def render_table(results: Sequence[CheckResult], title: str = "bubblecal sim verify"):
    """A rich Table of the results (check, expected, measured, tolerance, pass, seconds).

    Parameters
    ----------
    results : sequence of CheckResult
        The rows.
    title : str, optional
        Table title.

    Returns
    -------
    rich.table.Table
    """
    from rich.markup import escape
    from rich.table import Table

    table = Table(title=escape(title))
    for col in ("check", "expected", "measured", "tolerance", "pass", "s"):
        table.add_column(col)
    for r in results:
        table.add_row(escape(str(r.name)), escape(str(r.expected)), escape(str(r.measured)), escape(str(r.tolerance)),
                      "[green]PASS[/]" if r.passed else "[bold red]FAIL[/]", f"{r.details.get('seconds', 0):.1f}")
    return table


def summary_json(results: Sequence[CheckResult], quick: bool, device: str, wall_s: float) -> str:
    """One JSON line summarising a run (tracebacks left out).

    Parameters
    ----------
    results : sequence of CheckResult
        The rows.
    quick : bool
        Whether the quick versions ran.
    device : str
        Warp device.
    wall_s : float
        Wall time of the run (s).

    Returns
    -------
    str
    """
    def clean(x):
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items() if k != "traceback"}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        if hasattr(x, "tolist"):
            return x.tolist()
        if isinstance(x, (str, int, float, bool)) or x is None:
            return x
        return str(x)

    payload = {"command": "sim verify", "quick": quick, "device": device, "passed": all(r.passed for r in results),
               "n_checks": len(results), "n_failed": sum(not r.passed for r in results), "wall_s": round(wall_s, 2),
               "checks": [clean(r.as_dict()) for r in results]}
    return json.dumps(payload, default=str)


def main(quick: bool = True, device: str = "cpu", only: Sequence[str] | None = None) -> int:
    """Run the checks, print the table and the JSON line.

    Parameters
    ----------
    quick : bool, optional
        Quick versions (CPU-sized) or full ones.
    device : str, optional
        Warp device.
    only : sequence of str, optional
        Substrings of the check function names to run.

    Returns
    -------
    int
        Exit status: 0 when every check passed.
    """
    from rich.console import Console

    console = Console()
    if not console.is_terminal:  # logs and pipes: do not squeeze the table into 80 columns
        console = Console(width=160)
    t0 = time.perf_counter()

    def progress(res: CheckResult, sec: float) -> None:
        mark = "[green]PASS[/]" if res.passed else "[bold red]FAIL[/]"
        console.print(f"{mark} {res.name}: {res.measured} ({sec:.1f} s)", highlight=False)

    results = run_checks(quick=quick, device=device, only=only, progress=progress)
    console.print(render_table(results, title=f"bubblecal sim verify ({'quick' if quick else 'full'}, {device})"))
    sys.stdout.flush()
    print(summary_json(results, quick, device, time.perf_counter() - t0), flush=True)
    return 0 if results and all(r.passed for r in results) else 1
