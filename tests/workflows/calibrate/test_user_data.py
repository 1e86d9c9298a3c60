"""`bubblecal calibrate --data`: measured bubbles from tidy files, one hierarchy per agent label, on the shipped
bundle's networks over the diameter; every bad input named at once before any sampling."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from bubblecal.data import DEFAULT_UNITS, PUBLISHED_AGENT_OF_PROTOCOL
from bubblecal.workflows.calibrate import (
    CalibrationConfig,
    CalibrationError,
    agent_seed,
    make_plan,
    run_calibration,
)
from bubblecal.workflows.cli import app

runner = CliRunner()
PUBLISHED = Path(__file__).resolve().parents[3] / "data" / "reference" / "published_curves.csv"
HEADER = ["bubble", "agent", "protocol", "diameter_um", "displacement_nm", "force_nN", "retained"]


def _published_rows(prefix: str) -> list[dict]:
    return [r for r in csv.DictReader(PUBLISHED.open()) if r["bubble"].startswith(prefix)]


def _write(path: Path, rows: list[dict]) -> Path:
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=HEADER)
        w.writeheader()
        w.writerows(rows)
    return path


def _curves(tmp_path: Path, bubbles: dict) -> Path:
    """bubbles: id -> (agent, published curve prefix, diameter)."""
    rows = []
    for bubble, (agent, prefix, d) in bubbles.items():
        rows += [{**r, "bubble": bubble, "agent": agent, "diameter_um": d} for r in _published_rows(prefix)]
    return _write(tmp_path / "curves.csv", rows)


def _cli(*args):
    return runner.invoke(app, ["calibrate", *map(str, args)])


@pytest.fixture(scope="module")
def two_agents(tmp_path_factory) -> tuple[Path, Path]:
    tmp = tmp_path_factory.mktemp("two_agents")
    curves = _curves(tmp, {"A1": ("lipidX", "definity-2.1", 2.4), "A2": ("lipidX", "definity-2.9", 3.7),
                           "B1": ("polyY", "sonovue-3.4", 4.1)})
    res = tmp / "resonance.csv"
    res.write_text("agent,diameter_um,frequency_MHz,source\nlipidX,5.0,1.6,lab\nlipidX,6.5,1.2,\n")
    return curves, res


def test_plan_one_hierarchy_per_agent_on_networks_over_the_diameter(tmp_path, two_agents):
    curves, res = two_agents
    plan = make_plan(CalibrationConfig(data=curves, acoustic_data=res, population=200, out=tmp_path))
    lipid, poly = plan.agents
    assert (lipid.agent, lipid.workflow, poly.agent, poly.workflow) == ("lipidX", "reduced-acoustic", "polyY",
                                                                        "reduced")
    assert [c.name for c in lipid.curves] == ["A1", "A2"] and [c.name for c in poly.curves] == ["B1"]
    # every bubble gets the network over the diameter bound to its own size (the bundle's per-diameter ones sit at
    # 2.1, 2.9, 3.0 / 3.2, 3.4, 5.8 um)
    assert [s.diameter_um for s in lipid.surrogates] == [2.4, 3.7] and poly.surrogates[0].diameter_um == 4.1
    assert all(s.over_diameter for s in (*lipid.surrogates, *poly.surrogates))
    # the bundle's fast networks by default, its accurate ones on request
    fast, accurate = (plan.bundle.get(p, 3.0, prefer="over-diameter", network=n) for p, n in
                      (("compression", "fast"), ("compression", "accurate")))
    assert lipid.surrogates[0].architecture == fast.architecture != accurate.architecture
    # curves in DPD units, converted from the file's nm / nN
    first = _published_rows("definity-2.1")
    kept = [r for r in first if r["retained"] == "1"]
    np.testing.assert_allclose(lipid.curves[0].x, DEFAULT_UNITS.nm_to_dpd(np.array([float(r["displacement_nm"])
                                                                                     for r in kept])))
    # one acoustic dataset per resonance row, served by the published compression agent's law
    assert [d.name for d in lipid.acoustic] == ["lipidX_resonance_1", "lipidX_resonance_2"]
    assert lipid.acoustic_name == PUBLISHED_AGENT_OF_PROTOCOL["compression"] and lipid.f_res is not None
    assert lipid.out_dir == tmp_path / "lipidX" / "reduced-acoustic"
    # the report says which priors and workflow each agent got
    assert any("definity_reduced_acoustic" in n for n in lipid.notes)
    assert any("sonovue_reduced" in n for n in poly.notes) and any("no resonance rows" in n for n in poly.notes)
    # a compression bubble above the sizes checked against the explicit tier is noted; one inside is not
    assert any("bubble 'A2': compression at 3.7 um is outside 1.8-3 um" in w for w in lipid.domain_warnings)
    assert not any("'A1'" in w and "outside" in w for w in lipid.domain_warnings)


def test_every_problem_named_at_once_before_sampling(tmp_path):
    rows = [{**r, "bubble": "A1", "agent": "lipidX", "diameter_um": 9.5} for r in _published_rows("definity-2.1")]
    rows += [{**r, "bubble": "bad/id", "agent": "lipidX", "diameter_um": 2.5} for r in _published_rows("definity-2.9")]
    far = _published_rows("definity-3um")
    last = far[-1]
    far += [{**last, "displacement_nm": float(last["displacement_nm"]) + 400 * k,
             "force_nN": float(last["force_nN"]) * (1 + k)} for k in (1, 2)]
    rows += [{**r, "bubble": "A3", "agent": "lipidX", "diameter_um": 2.4} for r in far]
    curves = _write(tmp_path / "bad.csv", rows)
    out = tmp_path / "out"
    with pytest.raises(CalibrationError) as info:
        make_plan(CalibrationConfig(data=curves, population=200, out=out, priors={"nosuch": "x.toml"}))
    msg = str(info.value)
    assert "4 problem(s)" in msg
    assert "bubble 'A1'" in msg and "9.5 um" in msg and "1.5-8 um" in msg  # diameter and the bundle's range
    assert "'bad/id'" in msg and "letters, digits" in msg
    assert "bubble 'A3'" in msg and "loading box" in msg and "displacement_nm" in msg and " nm" in msg
    assert "--priors nosuch=x.toml" in msg and "lipidX" in msg
    r = _cli("--data", curves, "--population", 200, "--out", out)
    assert r.exit_code == 1 and "bad.csv" in r.output
    assert not list(out.rglob("phase*"))


def test_resonance_rows_of_a_mixed_agent_and_priors_of_the_wrong_protocol(tmp_path):
    curves = _curves(tmp_path, {"A1": ("mix", "definity-2.1", 2.4), "B1": ("mix", "sonovue-3.4", 4.1)})
    res = tmp_path / "res.csv"
    res.write_text("agent,diameter_um,frequency_MHz\nmix,5.0,1.6\n")
    with pytest.raises(CalibrationError, match="both protocols"):
        make_plan(CalibrationConfig(data=curves, acoustic_data=res, population=200, out=tmp_path / "o"))
    # without resonance rows: two hierarchies, named by protocol
    plan = make_plan(CalibrationConfig(data=curves, workflow="reduced", population=200, out=tmp_path / "o"))
    assert [a.agent for a in plan.agents] == ["mix-compression", "mix-indentation"]
    # one priors file for every agent: the indentation hierarchy refuses compression priors
    with pytest.raises(CalibrationError, match="are indentation curves"):
        make_plan(CalibrationConfig(data=curves, workflow="reduced", population=200, out=tmp_path / "o",
                                    priors={"*": "definity_reduced"}))


def test_options_of_the_published_study_refused_with_data(tmp_path, two_agents):
    curves, res = two_agents
    for kwargs, flag in (({"agents": ("definity",)}, "--agent"), ({"curves": ("definity_compression_2.1um",)},
                                                                  "--curve")):
        with pytest.raises(CalibrationError, match=flag):
            make_plan(CalibrationConfig(data=curves, population=200, out=tmp_path, **kwargs))
    with pytest.raises(CalibrationError, match="reduced-acoustic"):
        make_plan(CalibrationConfig(data=curves, acoustic_data=res, workflow="reduced", population=200, out=tmp_path))
    with pytest.raises(CalibrationError, match=r"--networks must be one of fast, accurate, got 'tiny'"):
        make_plan(CalibrationConfig(data=curves, networks="tiny", population=200, out=tmp_path))
    with pytest.raises(CalibrationError, match="goes with --data"):
        make_plan(CalibrationConfig(acoustic_data=res, population=200, out=tmp_path))
    r = _cli("--data", curves, "--priors", "lipidX=a.toml", "--priors", "lipidX=b.toml", "--out", tmp_path)
    assert r.exit_code == 1 and "two files for lipidX" in r.output
    r = _cli("--priors", "lipidX=a.toml", "--out", tmp_path)
    assert r.exit_code == 1 and "LABEL=FILE names an agent of --data" in r.output


def test_agent_seed_keeps_the_published_seeds_and_separates_labels():
    assert agent_seed(0, "definity") == 0 and agent_seed(5, "sonovue") == 1005
    assert agent_seed(0, "lipidX") == agent_seed(0, "lipidX") != agent_seed(0, "lipidY")
    assert 0 <= agent_seed(2**32 - 1, "lipidX") < 2**32


@pytest.mark.slow
def test_tiny_calibration_of_one_measured_bubble_and_resume(tmp_path):
    curves = _curves(tmp_path, {"A1": ("lipidX", "definity-2.1", 2.4)})
    out = tmp_path / "cal"
    config = CalibrationConfig(data=curves, workflow="reduced", population=120, phase2_samples=120,
                               predictive_samples=100, num_mcmc_steps=2, out=out)
    (res,) = run_calibration(make_plan(config))
    run_dir = out / "lipidX" / "reduced"
    assert sorted(p.name for p in run_dir.glob("phase*.nc")) == ["phase1_A1.nc", "phase2.nc", "phase3_A1.nc"]
    summary = pd.read_csv(run_dir / "summary.csv")
    assert set(summary["agent"]) == {"lipidX"} and "A1" in set(summary["dataset"])
    assert summary.loc[summary["dataset"] == "A1", "diameter_um"].iloc[0] == pytest.approx(2.4)
    manifest = json.loads((run_dir / "manifest.json").read_text())
    assert manifest["run"]["config"]["data"] == str(curves)
    report = (run_dir / "report.md").read_text()
    assert str(curves) in report and "note: priors: the shipped definity_reduced priors" in report
    assert (run_dir / "figures" / "forest.png").is_file() and (run_dir / "figures" / "fit.png").is_file()
    (again,) = run_calibration(make_plan(config))
    assert sorted(again.reused) == ["phase1_A1", "phase2", "phase3_A1"]
    # another diameter is another bubble: the network's input changed, so phase 1 reruns
    other = _curves(tmp_path, {"A1": ("lipidX", "definity-2.1", 2.6)})
    (moved,) = run_calibration(make_plan(CalibrationConfig(**{**config.__dict__, "data": other})))
    assert "phase1_A1" not in moved.reused


def test_measured_bubbles_on_cpu_cores_pad_to_length_buckets():
    from types import SimpleNamespace

    from bubblecal.workflows.calibrate.run import LENGTH_BUCKET, _curve_arguments, _pad_curves

    curves = [SimpleNamespace(x=np.arange(n, dtype=float) + 1, y=np.ones(n)) for n in (5, 8, 13, 17)]
    ap = SimpleNamespace(curves=curves, surrogates=[lambda p, x: x] * 4, spec=None)
    args = _curve_arguments(ap, LENGTH_BUCKET)
    assert [len(a[0]) for a, _ in args] == [8, 8, 16, 24]
    assert [int(k["mask"].sum()) for _, k in args] == [5, 8, 13, 17]
    assert all(np.array_equal(a[0][:len(c.x)], c.x) for (a, _), c in zip(args, curves, strict=True))
    assert _pad_curves(CalibrationConfig(data=Path("c.csv"))) == LENGTH_BUCKET
    assert _pad_curves(CalibrationConfig()) is False and _pad_curves(CalibrationConfig(device="gpu")) is True


def test_bubbles_outside_the_validated_sizes_are_noted():
    """A compression bubble above 3 um and an indentation bubble above 5.8 um get a note naming the range and the
    bubble; sizes inside get none."""
    from bubblecal.workflows.domain import TIER_VALIDATED_DIAMETERS_UM, tier_validation_warnings

    assert tier_validation_warnings("compression", 2.5, "b") == []
    assert tier_validation_warnings("indentation", 5.8, "b") == []
    (note,) = tier_validation_warnings("compression", 4.5, "bubble 'big'")
    assert "bubble 'big': compression at 4.5 um is outside 1.8-3 um" in note and "buckle" in note
    (note,) = tier_validation_warnings("indentation", 7.0, "bubble 'x'")
    assert "outside 1.8-5.8 um" in note and "buckle" not in note
    assert tier_validation_warnings("indentation", 1.5, "s") and TIER_VALIDATED_DIAMETERS_UM["compression"][1] == 3.0
