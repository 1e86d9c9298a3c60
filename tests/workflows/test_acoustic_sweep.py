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
    # 42-vertex mesh: check 7 x A_mesh / (4 pi r^2) = 0.928 (tests/sim/test_ringdown.py)
    assert abs(summary["check7_ratio_mesh_median"] - 1.0) < 0.05
    for name in ("ringdown_definity_1.5um.csv", "ringdown_definity_1.5um.json", "ringdown_definity_1.5um.png",
                 "ringdown_definity_1.5um_traces.npz"):
        assert (out / name).exists(), name
    bad = runner.invoke(app, ["sim", "ringdown", "--agent", "optison", "--diameter", "4.68", "--out", str(out)])
    assert bad.exit_code != 0 and "agent" in bad.output


def _ringdown_store(path, diameters=(4.68, 5.18), n=6):
    """A ringdown campaign store whose R(t) are damped cosines with f_res^2 = 0.1 + 2e-4 ka [MHz^2]."""
    from bubblecal.data import CampaignStore, make_record

    conv = float(DEFAULT_UNITS.frequency_to_physical(1.0, 160.0)) / 1e6
    st = CampaignStore.create(path, meta={"campaign": {"name": "definity_ringdown"}})
    t = np.linspace(0, 4.0, 400)
    recs, truth = [], {}
    for d in diameters:
        ka = np.linspace(3500, 34000, n)
        f = np.sqrt(0.1 + 2e-4 * ka * (4.68 / d))
        truth[d] = (ka, f)
        for i, (k, fi) in enumerate(zip(ka, f, strict=True)):
            lam = 0.2
            wd = math.sqrt((2 * math.pi * fi / conv) ** 2 + lam**2)
            r = 9.36 + 0.1 * np.exp(-lam * t) * np.cos(wd * t)
            info = {"mass_factor": 160.0, "radius_equilibrium": 9.36, "p_gas": 3.0, "shell_mass": 1.0e4,
                    "prediction": {"area_ratio": [0.9988]}, "mesh_subdivisions": 4}
            recs.append(make_record(sample_id=f"definity_ringdown-{d}-{i}", setup="ringdown",
                                    params={"ka": k, "kb": 389.23, "b1": 0, "b2": 0, "a3": 0, "a4": 0},
                                    radius_dpd=9.36, x=t, y=r, status="ok", seed=i, tier="implicit",
                                    provenance={"campaign": "definity_ringdown", "diameter_um": d, "info": info}))
    st.append_many(recs)
    return truth


def test_acoustic_surrogate_from_a_store_and_from_its_rows(tmp_path):
    from bubblecal.surrogates import AcousticSurrogate
    from bubblecal.workflows.acoustic_sweep import acoustic_surrogate_from_stores, sweeps_from_store

    truth = _ringdown_store(tmp_path / "rd.store")
    sweeps = sweeps_from_store(tmp_path / "rd.store")
    assert [s.diameter_um for s in sweeps] == [4.68, 5.18] and sweeps[0].agent == "definity"
    for s in sweeps:
        ka, f = truth[s.diameter_um]
        np.testing.assert_allclose(s.column("ka"), ka)
        np.testing.assert_allclose(s.column("f_res_MHz"), f, rtol=2e-3)  # the damped-sine fit recovers f_res
    sur, _ = acoustic_surrogate_from_stores([tmp_path / "rd.store"], tmp_path / "ac.json", rows_csv=tmp_path / "definity_r.csv")
    loaded = AcousticSurrogate.load(tmp_path / "ac.json")
    assert loaded.diameters == [4.68, 5.18] and loaded.meta["synthetic"] is False
    np.testing.assert_allclose(np.asarray(loaded.f_res(np.array([20000.0]), 5.18)),
                               math.sqrt(0.1 + 2e-4 * 20000 * 4.68 / 5.18), rtol=3e-3)
    again, _ = acoustic_surrogate_from_stores([tmp_path / "definity_r.csv"], tmp_path / "ac2.json")
    ka = np.linspace(3500, 34000, 7)
    np.testing.assert_allclose(again.f_res(ka, 4.68), sur.f_res(ka, 4.68), rtol=1e-8)  # CSV keeps 10 digits


def test_acoustic_cli_and_bad_inputs(tmp_path):
    _ringdown_store(tmp_path / "rd.store", diameters=(4.68,))
    res = CliRunner().invoke(app, ["surrogates", "acoustic", str(tmp_path / "rd.store"), "--out",
                                   str(tmp_path / "a.json")])
    assert res.exit_code == 0, res.output
    assert "4.68 um: 6/6 valid" in res.output
    res = CliRunner().invoke(app, ["surrogates", "acoustic", str(tmp_path / "nope"), "--out", str(tmp_path / "b.json")])
    assert res.exit_code == 1 and "no such ringdown store" in res.output
    bad = tmp_path / "definity_rows.csv"
    bad.write_text("diameter_um," + ",".join(ROW_FIELDS) + "\n4.68," + ",".join(["x"] * len(ROW_FIELDS)) + "\n")
    res = CliRunner().invoke(app, ["surrogates", "acoustic", str(bad), "--out", str(tmp_path / "c.json")])
    assert res.exit_code == 1 and "row 2" in res.output


def test_shipped_ringdown_rows_are_physical():
    from pathlib import Path

    from bubblecal.data import acoustic_observations
    from bubblecal.workflows.acoustic_sweep import sweeps_from_rows_csv

    folder = Path(__file__).resolve().parents[2] / "data" / "training"
    for agent in ("definity", "sonovue"):
        sweeps = sweeps_from_rows_csv(folder / f"{agent}_ringdown_rows.csv")
        # every acoustic diameter of the agent's data has its 28-point sweep
        assert {round(o.diameter_um, 2) for o in acoustic_observations(agent)} <= {s.diameter_um for s in sweeps}
        for s in sweeps:
            assert s.valid.all() and len(s.rows) == 28
            f = s.column("f_res_MHz")
            assert np.all(np.diff(f) > 0)  # stiffer shell, higher resonance
            assert np.all(np.abs(s.column("check7_ratio") - 1) < 0.06)  # physics.md check 7


def test_bundle_cli_assembles_and_refuses_bad_input(tmp_path):
    from bubblecal.surrogates import load_bundle

    _ringdown_store(tmp_path / "rd.store", diameters=(4.68,))
    runner = CliRunner()
    assert runner.invoke(app, ["surrogates", "acoustic", str(tmp_path / "rd.store"), "--out",
                               str(tmp_path / "a.json")]).exit_code == 0
    res = runner.invoke(app, ["surrogates", "bundle", str(tmp_path / "B"), "--acoustic", f"definity={tmp_path / 'a.json'}",
                              "--notes", "test"])
    assert res.exit_code == 0, res.output
    b = load_bundle(tmp_path / "B")
    assert b.acoustic["definity"].diameters == [4.68] and b.manifest["notes"] == "test"
    res = runner.invoke(app, ["surrogates", "bundle", str(tmp_path / "C"), "--acoustic", "water=x.json"])
    assert res.exit_code == 1 and "expected definity=FILE" in res.output
    res = runner.invoke(app, ["surrogates", "bundle", str(tmp_path / "C"), "--surrogate", str(tmp_path / "no.npz")])
    assert res.exit_code == 1 and "no such file" in res.output
