"""`bubblecal calibrate` plan validation: bad inputs fail with one clear error before any sampling."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from bubblecal.workflows.calibrate import CalibrationConfig, CalibrationError, make_plan
from bubblecal.workflows.cli import app

runner = CliRunner()


def _phase_files(root: Path) -> list[Path]:
    return sorted(root.rglob("phase*.nc")) + sorted(root.rglob("phase*.npz"))


def _cli(*args):
    return runner.invoke(app, ["calibrate", *map(str, args)])


# -------------------------------------------------------------------------------------------------
# bad inputs: one clear error before any sampling (no phase files)
# -------------------------------------------------------------------------------------------------
def test_broken_priors_file(tmp_path, synthetic_bundle):
    bad = tmp_path / "broken.toml"
    bad.write_text("[workflow]\nagent = 'definity'\nsetup = 'compression'\nshell = 'reduced'\nacoustic = false\n"
                   "[parameters.ka]\nprior = [3.0e4, 1.0e3]\n")
    out = tmp_path / "out"
    r = _cli("--agent", "definity", "--workflow", "reduced", "--priors", bad, "--bundle", synthetic_bundle,
             "--population", 200, "--out", out)
    assert r.exit_code == 1, r.output
    assert "broken.toml" in r.output and "ka" in r.output
    assert not _phase_files(out)


def test_bad_data_rows(tmp_path, synthetic_bundle):
    data = tmp_path / "data"
    data.mkdir()
    (data / "definity_compression_2.9um_dpd.csv").write_text(
        "displacement_dpd,force_dpd\n0.3,600\n0.5,abc\n0.4,-5\n0.9,3000\n")
    with pytest.raises(CalibrationError, match=r"definity_compression_2\.9um_dpd\.csv.*\n.*row"):
        make_plan(CalibrationConfig(agents=("definity",), workflow="reduced", bundle=synthetic_bundle, population=200,
                                    data_dir=data, out=tmp_path / "out"))
    r = _cli("--agent", "definity", "--workflow", "reduced", "--data-dir", data, "--bundle", synthetic_bundle,
             "--population", 200, "--out", tmp_path / "out")
    assert r.exit_code == 1 and "abc" in r.output
    assert not _phase_files(tmp_path / "out")


def test_bundle_missing_a_diameter(tmp_path, synthetic_bundle):
    partial = tmp_path / "partial"
    shutil.copytree(synthetic_bundle, partial)
    manifest = json.loads((partial / "manifest.json").read_text())
    manifest["surrogates"] = [e for e in manifest["surrogates"] if not (e["setup"] == "indentation"
                                                                         and abs(e["diameter_um"] - 3.4) < 0.01)]
    (partial / "manifest.json").write_text(json.dumps(manifest))
    r = _cli("--agent", "sonovue", "--bundle", partial, "--population", 500, "--out", tmp_path / "out")
    assert r.exit_code == 1
    assert "no indentation surrogate at 3.4 um" in r.output and "sonovue_indentation_3.4um" in r.output
    assert not _phase_files(tmp_path / "out")


def test_population_too_small_and_other_fields(tmp_path, synthetic_bundle):
    r = _cli("--agent", "definity", "--bundle", synthetic_bundle, "--population", 50, "--out", tmp_path / "out")
    assert r.exit_code == 1 and "--population 50 is too small" in r.output and "phase" in r.output
    assert not _phase_files(tmp_path / "out")
    for kwargs, match in (({"workflow": "medium"}, "--workflow"), ({"sampler": "hmc"}, "--sampler"),
                          ({"phase3": "joint"}, "--phase3"), ({"phase3_start": "phase2"}, "--phase3-start"),
                          ({"agents": ("optison",)}, "--agent"), ({"bundle": tmp_path}, "manifest.json")):
        base = {"agents": ("definity",), "bundle": synthetic_bundle, "population": 200, "out": tmp_path / "o"}
        with pytest.raises(CalibrationError, match=match):
            make_plan(CalibrationConfig(**{**base, **kwargs}))


def test_no_shipped_bundle_message(tmp_path, monkeypatch):
    import bubblecal.surrogates.bundle as bundle_mod

    monkeypatch.setattr(bundle_mod, "__file__", str(tmp_path / "nowhere" / "bundle.py"))
    with pytest.raises(CalibrationError, match="no shipped surrogate bundle found at .*synthetic-bundle"):
        make_plan(CalibrationConfig(agents=("definity",), out=tmp_path / "o"))


def test_priors_of_another_protocol_or_acoustic_flag_are_named(tmp_path, synthetic_bundle):
    """A priors file written for indentation and for the acoustic workflow, given to compression curves without
    acoustic data: both fields named, for the published curves and for measured bubbles alike."""
    from bubblecal.priors import prior_path

    text = Path(prior_path("definity_reduced_acoustic")).read_text()
    wrong = tmp_path / "wrong.toml"
    wrong.write_text(text.replace('setup = "compression"', 'setup = "indentation"'))
    with pytest.raises(CalibrationError) as err:
        make_plan(CalibrationConfig(agents=("definity",), workflow="reduced", bundle=synthetic_bundle,
                                    priors={"definity": str(wrong)}, population=200, out=tmp_path / "o"))
    msg = str(err.value)
    assert "wrong.toml: field workflow.setup is 'indentation', but the definity curves are compression" in msg
    assert "field workflow.acoustic is true, but workflow 'reduced' of the definity curves needs false" in msg
    curves = tmp_path / "c.csv"
    curves.write_text("bubble,agent,protocol,diameter_um,displacement_nm,force_nN\n"
                      + "".join(f"b1,lab,compression,2.5,{x:.1f},{0.02 * x:.3f}\n" for x in (10.0, 40.0, 80.0)))
    with pytest.raises(CalibrationError) as err:
        make_plan(CalibrationConfig(workflow="reduced", data=curves, priors={"lab": str(wrong)},
                                    population=200, out=tmp_path / "o"))
    assert "but the bubbles of agent 'lab' are compression curves" in str(err.value)
    assert "workflow 'reduced' of the bubbles of agent 'lab' needs false" in str(err.value)
