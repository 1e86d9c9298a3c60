"""benchmarks/qs_host_overhead.py on a tiny pool (the figures are the benchmark's, not asserted here)."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("warp")


def test_a_small_pool_runs_and_reports(load_script, capsys):
    mod = load_script("benchmarks/qs_host_overhead.py")
    mod.main(["--sizes", "12", "--points", "4"])
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    (row,) = out["rows"]
    assert out["benchmark"] == "qs_host_overhead" and row["curves"] == 12 and row["ok"] == 12
    assert row["evaluations_per_curve"] > 0 and row["ms_per_curve"] > 0
