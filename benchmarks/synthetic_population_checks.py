"""The checks of the synthetic population study (benchmarks/synthetic_population.py, docs/synthetic-study.md).

Pure functions of the truth (``truth.json`` of ``generate``) and the rows of a calibration's ``summary.csv``
(workflows/summary.py: one row per (dataset, parameter) with ``mean``, ``q05``, ``q95``; the dataset
``hyperparameters`` holds ``m_ka``, ``tau_ka``, ...; a bubble's dataset is its id):

(a) the true m_ka and tau_ka inside their 90 % intervals [q05, q95];
(b) the number of bubbles whose [q05, q95] of k_a covers the true k_a inside the central binomial 95 % range of
    Binomial(n, 0.9) (``scipy.stats.binom.interval``);
(c) the same for k_b, reported beside the verdict (k_b is weakly identified by compression curves).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

from scipy.stats import binom

#: Nominal level of the posterior intervals (q05, q95) and the range of the coverage count.
NOMINAL = 0.9
RANGE_LEVEL = 0.95
HYPERPARAMETERS = "hyperparameters"


class StudyError(ValueError):
    """A study input is invalid or incomplete; the message names the file, the bubble or the value."""


def read_summary(path: str | Path) -> list[dict]:
    """The rows of a calibration's ``summary.csv``.

    Parameters
    ----------
    path : str or pathlib.Path
        The calibration folder ``OUT/<agent>/<workflow>`` or the ``summary.csv`` itself.

    Returns
    -------
    list of dict
        One dict per row (column -> text).

    Raises
    ------
    StudyError
        If the file is missing or lacks a column ``dataset``, ``parameter``, ``q05`` or ``q95``.
    """
    path = Path(path)
    path = path / "summary.csv" if path.is_dir() else path
    if not path.is_file():
        raise StudyError(f"{path}: no such file (give the calibration folder OUT/<agent>/<workflow>)")
    with open(path, newline="", encoding="utf-8") as handle:
        reader = csv.DictReader(handle)
        missing = [c for c in ("dataset", "parameter", "q05", "q95") if c not in (reader.fieldnames or [])]
        if missing:
            raise StudyError(f"{path}: missing columns {missing} (found {reader.fieldnames})")
        return list(reader)


def binomial_range(n: int, p: float = NOMINAL, level: float = RANGE_LEVEL) -> tuple[int, int]:
    """Central ``level`` range of Binomial(n, p): the counts a calibrated interval produces.

    Parameters
    ----------
    n : int
        Number of bubbles.
    p : float
        Nominal coverage of each interval.
    level : float
        Probability of the range (each tail at most (1 - level) / 2).

    Returns
    -------
    (int, int)
        Smallest and largest count inside the range.
    """
    lo, hi = binom.interval(level, n, p)
    return int(lo), int(hi)


def _interval(rows: list[dict], dataset: str, parameter: str) -> tuple[float, float]:
    """(q05, q95) of one summary row."""
    found = [r for r in rows if r["dataset"] == dataset and r["parameter"] == parameter]
    if len(found) != 1:
        raise StudyError(f"summary.csv: {len(found)} rows for dataset {dataset!r}, parameter {parameter!r} "
                         "(expected one)")
    return float(found[0]["q05"]), float(found[0]["q95"])


def hyper_check(truth: dict, rows: list[dict], name: str) -> dict:
    """Whether a true hyperparameter lies in its 90 % interval.

    Parameters
    ----------
    truth : dict
        ``truth.json``: ``population[k]["m"]`` and ``["tau"]`` in DPD units.
    rows : list of dict
        ``summary.csv`` rows.
    name : str
        ``m_ka``, ``tau_ka``, ``m_kb`` or ``tau_kb``.

    Returns
    -------
    dict
        ``true``, ``q05``, ``q95`` (DPD units) and ``pass`` (q05 <= true <= q95).

    Raises
    ------
    StudyError
        If the summary has no row (or several) for the hyperparameter.
    """
    what, k = name.split("_", 1)
    true = float(truth["population"][k][what])
    q05, q95 = _interval(rows, HYPERPARAMETERS, name)
    return {"true": true, "q05": q05, "q95": q95, "pass": bool(q05 <= true <= q95)}


def coverage_check(truth: dict, rows: list[dict], parameter: str) -> dict:
    """How many bubbles' 90 % intervals cover their true value, against the binomial range.

    Parameters
    ----------
    truth : dict
        ``truth.json``: ``bubbles`` with ``id`` and the parameter's true value (DPD units).
    rows : list of dict
        ``summary.csv`` rows; every bubble id must be a dataset.
    parameter : str
        ``ka`` or ``kb``.

    Returns
    -------
    dict
        ``hits``, ``n``, the range ``lo``, ``hi`` (:func:`binomial_range`), ``missed`` (ids not covered) and
        ``pass`` (lo <= hits <= hi).

    Raises
    ------
    StudyError
        If a bubble of the truth has no row (or several) in the summary.
    """
    missed = []
    for b in truth["bubbles"]:
        q05, q95 = _interval(rows, b["id"], parameter)
        if not q05 <= float(b[parameter]) <= q95:
            missed.append(b["id"])
    n = len(truth["bubbles"])
    lo, hi = binomial_range(n)
    hits = n - len(missed)
    return {"hits": hits, "n": n, "lo": lo, "hi": hi, "missed": missed, "pass": bool(lo <= hits <= hi)}


def evaluate(truth: dict, rows: list[dict]) -> dict:
    """Every check of the study.

    Parameters
    ----------
    truth : dict
        ``truth.json`` of ``generate``.
    rows : list of dict
        ``summary.csv`` rows of the calibration of ``curves.csv``.

    Returns
    -------
    dict
        ``checks`` (m_ka, tau_ka, coverage_ka: the verdict), ``reported`` (m_kb, tau_kb, coverage_kb) and
        ``pass`` (every check passed).

    Raises
    ------
    StudyError
        If the summary lacks a row the checks need.
    """
    checks = {"m_ka": hyper_check(truth, rows, "m_ka"), "tau_ka": hyper_check(truth, rows, "tau_ka"),
              "coverage_ka": coverage_check(truth, rows, "ka")}
    reported = {"m_kb": hyper_check(truth, rows, "m_kb"), "tau_kb": hyper_check(truth, rows, "tau_kb"),
                "coverage_kb": coverage_check(truth, rows, "kb")}
    return {"checks": checks, "reported": reported, "pass": all(c["pass"] for c in checks.values())}


def print_evaluation(result: dict) -> None:
    """Print the checks of :func:`evaluate` as a table and one JSON line."""
    print(f"{'check':14s} {'true':>10s} {'q05':>10s} {'q95':>10s} {'result':>14s} verdict")
    verdicts = [(n, c, "pass" if c["pass"] else "FAIL") for n, c in result["checks"].items()]
    verdicts += [(n, c, f"{'in' if c['pass'] else 'out'} (reported)") for n, c in result["reported"].items()]
    for name, c, verdict in verdicts:
        if "hits" in c:
            counts = f"{c['hits']:>3d}/{c['n']:<3d}[{c['lo']},{c['hi']}]"
            print(f"{name:14s} {'':>10s} {'':>10s} {'':>10s} {counts:>14s} {verdict}")
        else:
            print(f"{name:14s} {c['true']:10.4g} {c['q05']:10.4g} {c['q95']:10.4g} {'':>14s} {verdict}")
    print(json.dumps({"benchmark": "synthetic_population", "command": "evaluate", **result}))
