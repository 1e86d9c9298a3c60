"""Acoustic sweeps from ringdown campaign stores and fitted-row CSVs: refit, acoustic surrogate, CLI, bundle."""

from __future__ import annotations

import math

import numpy as np
from typer.testing import CliRunner

from bubblecal.data import DEFAULT_UNITS
from bubblecal.workflows.acoustic_sweep import ROW_FIELDS
from bubblecal.workflows.cli import app


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
    sur, _ = acoustic_surrogate_from_stores([tmp_path / "rd.store"], tmp_path / "ac.json",
                                            rows_csv=tmp_path / "definity_r.csv")
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

    folder = Path(__file__).resolve().parents[3] / "data" / "training"
    for agent in ("definity", "sonovue"):
        sweeps = sweeps_from_rows_csv(folder / f"{agent}_ringdown_rows.csv")
        # every acoustic diameter of the agent's data has its 28-point sweep
        assert {round(o.diameter_um, 2) for o in acoustic_observations(agent)} <= {s.diameter_um for s in sweeps}
        for s in sweeps:
            assert s.valid.all() and len(s.rows) == 28
            f = s.column("f_res_MHz")
            assert np.all(np.diff(f) > 0)  # stiffer shell, higher resonance
            assert np.all(np.abs(s.column("check7_ratio") - 1) < 0.06)  # docs/physics.md section 6, check 7


def test_bundle_cli_assembles_and_refuses_bad_input(tmp_path):
    from bubblecal.surrogates import load_bundle

    _ringdown_store(tmp_path / "rd.store", diameters=(4.68,))
    runner = CliRunner()
    assert runner.invoke(app, ["surrogates", "acoustic", str(tmp_path / "rd.store"), "--out",
                               str(tmp_path / "a.json")]).exit_code == 0
    res = runner.invoke(app, ["surrogates", "bundle", str(tmp_path / "B"), "--acoustic",
                              f"definity={tmp_path / 'a.json'}",
                              "--notes", "test"])
    assert res.exit_code == 0, res.output
    b = load_bundle(tmp_path / "B")
    assert b.acoustic["definity"].diameters == [4.68] and b.manifest["notes"] == "test"
    res = runner.invoke(app, ["surrogates", "bundle", str(tmp_path / "C"), "--acoustic", "water=x.json"])
    assert res.exit_code == 1 and "expected definity=FILE" in res.output
    res = runner.invoke(app, ["surrogates", "bundle", str(tmp_path / "C"), "--surrogate", str(tmp_path / "no.npz")])
    assert res.exit_code == 1 and "no such file" in res.output
