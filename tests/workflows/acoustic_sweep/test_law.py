"""`bubblecal surrogates acoustic ROWS --law` and `info`: the law from row CSVs, and the shipped 1.5-8 um rows."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from bubblecal.surrogates import AcousticLawSurrogate, AcousticSurrogate, fit_law
from bubblecal.workflows.acoustic_sweep import ROW_FIELDS, law_rows, sweeps_from_rows_csv
from bubblecal.workflows.cli import app

runner = CliRunner()
TRAINING = Path(__file__).resolve().parents[3] / "data" / "training"


def _write_rows(path: Path) -> Path:
    """A rows CSV of f = sqrt(ka) / D * 0.07 over 5 diameters x 8 ka (one failed fit, which is skipped)."""
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=["diameter_um", *ROW_FIELDS])
        w.writeheader()
        for d in (2.0, 3.0, 4.0, 5.0, 6.0):
            for ka in np.linspace(4000.0, 30000.0, 8):
                row = {k: "1.0" for k in ROW_FIELDS}
                ok = not (d == 3.0 and ka == 4000.0)
                row.update(diameter_um=f"{d:g}", ka=f"{ka:.10g}", kb="389.23", status="ok", fit_success=str(ok),
                           f_res_MHz=f"{0.07 * np.sqrt(ka) / d:.10g}")
                w.writerow(row)
    return path


def test_cli_law_from_rows_and_info(tmp_path):
    rows = _write_rows(tmp_path / "definity_test_rows.csv")
    out = tmp_path / "law.json"
    res = runner.invoke(app, ["surrogates", "acoustic", str(rows), "--law", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "form gas-coupled" in res.output and "diameter 2-6 um (5 simulated)" in res.output
    sur = AcousticSurrogate.load(out)
    assert isinstance(sur, AcousticLawSurrogate) and sur.name == "definity" and sur.law.n_points == 39
    assert sur.ka_ranges(3.0)[0] == pytest.approx(np.linspace(4000.0, 30000.0, 8)[1])
    assert float(sur.f_res(10000.0, 4.5)) == pytest.approx(0.07 * 100 / 4.5, rel=1e-5)
    meta = json.loads(out.read_text())["meta"]
    assert meta["sources"][0]["path"] == str(rows) and len(meta["sources"][0]["sha256"]) == 64
    res = runner.invoke(app, ["surrogates", "info", str(out)])
    assert res.exit_code == 0 and "ka 4000-30000 DPD" in res.output and "leave one diameter out: median" in res.output
    res = runner.invoke(app, ["surrogates", "acoustic", str(rows), "--law", "--form", "cubic", "--out", str(out)],
                        env={"COLUMNS": "250"})
    assert res.exit_code == 2 and "'cubic' is not one of 'scale-free', 'gas'" in res.output
    res = runner.invoke(app, ["surrogates", "acoustic", str(rows), "--form", "gas", "--out", str(out)])
    assert res.exit_code != 0 and "--form needs --law" in res.output


@pytest.mark.parametrize("agent", ["definity", "sonovue"])
def test_shipped_rows_give_a_law_under_one_percent_median(agent):
    sweeps = sweeps_from_rows_csv(TRAINING / f"{agent}_ringdown_1.5-8um_rows.csv")
    assert [s.diameter_um for s in sweeps] == list(np.arange(1.5, 8.01, 0.5))
    assert sum(len(s.rows) for s in sweeps) == 392
    law = fit_law(*law_rows(sweeps))
    assert law.holdout["median"] < 0.01 and law.holdout["bands"][0]["median"] < 0.01
