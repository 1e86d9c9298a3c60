"""Acoustic ringdown sweep: fitting + MHz conversion + quadratic (synthetic), and the CLI on a tiny implicit run."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from bubblecal.data import DEFAULT_UNITS
from bubblecal.workflows.acoustic_sweep import (
    AGENT_KB,
    ROW_FIELDS,
    SweepResult,
    default_ka_values,
    fit_sweep,
    write_sweep_outputs,
)
from bubblecal.workflows.cli import app


def _synthetic_result(n=8, mass_factor=160.0):
    """Rows whose f_res follows an exact quadratic f^2 = a0 + a1 ka + a2 ka^2 [MHz^2]."""
    from bubblecal.surrogates import fit_ringdown

    ka = np.linspace(3500, 34000, n)
    f2 = 0.1 + 2e-4 * ka - 1e-10 * ka**2
    rows, traces, fits = [], [], []
    conv = float(DEFAULT_UNITS.frequency_to_physical(1.0, mass_factor)) / 1e6
    t = np.linspace(0, 4.0, 400)
    for k, f in zip(ka, np.sqrt(f2), strict=True):
        f_dpd = f / conv
        lam = 0.2
        wd = math.sqrt((2 * math.pi * f_dpd) ** 2 + lam**2)  # so that f_res = f exactly
        r = 3.0 + 0.04 * np.exp(-lam * t) * np.cos(wd * t)
        fit = fit_ringdown(t, r)
        mhz = fit.physical_MHz(mass_factor)
        row = {key: float("nan") for key in ROW_FIELDS}
        row.update({"ka": k, "kb": 389.23, "mu": k / 3, "seed": 0, "status": "ok", "fit_success": fit.success,
                    "f_res_MHz": mhz["f_res"], "f_0_MHz": mhz["f_0"], "r2": fit.r2, "check7_ratio": 1.0,
                    "check7_ratio_mesh": 1.0})
        rows.append(row)
        traces.append((t, r))
        fits.append(fit)
    return SweepResult("definity", 4.68, "implicit", mass_factor, rows, traces, fits), ka, np.sqrt(f2)


def test_conversion_and_quadratic(tmp_path):
    res, ka, f = _synthetic_result()
    assert np.allclose(res.column("f_res_MHz"), f, rtol=1e-4)
    fit = fit_sweep(res)[4.68]
    assert fit.a1 == pytest.approx(2e-4, rel=1e-3) and fit.loo_max < 1e-3
    assert fit.meta["n_valid"] == len(ka)
    paths = write_sweep_outputs(res, tmp_path, fit=fit, plot=False)
    with open(paths["csv"], newline="") as fh:
        got = list(csv.DictReader(fh))
    assert len(got) == len(ka) and tuple(got[0]) == ROW_FIELDS
    doc = json.loads(paths["json"].read_text())
    assert doc["fit"]["a1"] == pytest.approx(fit.a1) and doc["summary"]["n_valid"] == len(ka)


def test_invalid_rows_are_left_out():
    res, ka, _ = _synthetic_result()
    res.rows[2]["status"] = "ruptured"
    res.rows[3]["fit_success"] = False
    assert res.valid.sum() == len(ka) - 2
    assert fit_sweep(res)[4.68].n_points == len(ka) - 2


def test_default_ka_values():
    ka = default_ka_values("definity", 28)
    assert ka.size == 28 and ka[0] == pytest.approx(3500.0) and ka[-1] == pytest.approx(34000.0)
    assert default_ka_values("SonoVue", 5)[0] == pytest.approx(617.0)
    assert AGENT_KB == {"definity": 389.23, "sonovue": 7850.29}
    with pytest.raises(ValueError, match="agent"):
        default_ka_values("optison")
    with pytest.raises(ValueError, match="n_ka"):
        default_ka_values("definity", 2)


def test_cli_ringdown_tiny(tmp_path):
    runner = CliRunner()
    out = tmp_path / "rd"
    result = runner.invoke(app, ["sim", "ringdown", "--agent", "definity", "--diameter", "1.5", "--n-ka", "4",
                                 "--subdivisions", "1", "--equilibration-steps", "200", "--out", str(out)])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output.strip().splitlines()[-1])
    assert summary["n_valid"] == 4 and summary["tier"] == "implicit"
    # 42-vertex mesh: check 7 x A_mesh / (4 pi r^2) = 0.928 (tests/sim/protocols/test_ringdown.py)
    assert abs(summary["check7_ratio_mesh_median"] - 1.0) < 0.05
    for name in ("ringdown_definity_1.5um.csv", "ringdown_definity_1.5um.json", "ringdown_definity_1.5um.png",
                 "ringdown_definity_1.5um_traces.npz"):
        assert (out / name).exists(), name
    bad = runner.invoke(app, ["sim", "ringdown", "--agent", "optison", "--diameter", "4.68", "--out", str(out)])
    assert bad.exit_code != 0 and "agent" in bad.output
