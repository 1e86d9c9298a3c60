"""benchmarks/synthetic_population.py: the population draws, the noise model, the tidy file and the checks.

The simulation itself (the quasi-static tier) is not run here; its CPU smoke is recorded in docs/synthetic-study.md.
"""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from scipy.stats import binom, norm

from bubblecal.data import read_bubble_curves
from bubblecal.priors import load_priors


@pytest.fixture(scope="module")
def sp(load_script):
    return load_script("benchmarks/synthetic_population.py")


@pytest.fixture(scope="module")
def checks(sp):
    import synthetic_population_checks

    return synthetic_population_checks


@pytest.fixture(scope="module")
def spec():
    return load_priors("definity_reduced")


def _truncnorm_moments(m, tau, lo, hi):
    """Analytic mean and sd of Normal(m, tau^2) truncated to [lo, hi]."""
    a, b = (lo - m) / tau, (hi - m) / tau
    z = norm.cdf(b) - norm.cdf(a)
    pa, pb = norm.pdf(a), norm.pdf(b)
    mean = m + tau * (pa - pb) / z
    var = tau ** 2 * (1 + (a * pa - b * pb) / z - ((pa - pb) / z) ** 2)
    return mean, math.sqrt(var)


@pytest.mark.parametrize("m, tau, lo, hi", [
    (15000.0, 4000.0, 5580.0, 27900.0),   # the study's k_a: mild truncation on both sides
    (6000.0, 8000.0, 5580.0, 27900.0),    # strong truncation at the lower end
    (500.0, 150.0, 100.0, 1000.0),        # the study's k_b
])
def test_truncated_normal_draws_match_the_analytic_moments(sp, m, tau, lo, hi):
    n = 200_000
    x = sp.truncnorm_draw(np.random.default_rng(7), m, tau, lo, hi, n)
    mean, sd = _truncnorm_moments(m, tau, lo, hi)
    assert np.all((x >= lo) & (x <= hi))
    # 5 standard errors: the mean's sd / sqrt(n); the sd's ~ sd / sqrt(2 n) (doubled for the non-normal kurtosis)
    assert abs(x.mean() - mean) < 5 * sd / math.sqrt(n)
    assert abs(x.std() - sd) < 5 * 2 * sd / math.sqrt(2 * n)


def test_truncated_normal_refuses_a_degenerate_population(sp, checks):
    with pytest.raises(checks.StudyError, match="tau > 0"):
        sp.truncnorm_draw(np.random.default_rng(0), 1.0, 0.0, 0.0, 2.0, 3)
    with pytest.raises(checks.StudyError, match="no mass"):
        sp.truncnorm_draw(np.random.default_rng(0), 0.0, 1.0, 50.0, 60.0, 3)


def test_noise_sd_is_the_likelihoods(sp):
    from bubblecal.models.likelihood import noise_sd, sd_floor_for

    yhat = np.array([0.0, 3.0, 40.0, 250.0, 900.0])
    ours = sp.noise_sd(yhat, 0.05)
    theirs = np.asarray(noise_sd(yhat, 0.05, sd_floor_for(np.max(np.abs(yhat)))))
    np.testing.assert_allclose(ours, theirs, rtol=1e-6)
    assert ours[0] > 0  # the floor: a zero prediction still has noise


def test_observations_are_relative_normal(sp):
    rng = np.random.default_rng(11)
    yhat = np.linspace(0.0, 500.0, 15)
    many = np.tile(yhat, (20_000, 1))  # one curve's floor: every row has the same max|yhat|
    z = (sp.observe(rng, many, 0.08) - many) / sp.noise_sd(many, 0.08)
    n = z.size
    assert abs(z.mean()) < 5 / math.sqrt(n)          # standard normal z: mean 0 within 5 standard errors
    assert abs(z.std() - 1.0) < 5 / math.sqrt(2 * n)  # sd 1 within 5 standard errors
    rel = (z * sp.noise_sd(yhat, 0.08))[:, -1] / yhat[-1]
    assert abs(rel.std() - 0.08) < 5 * 0.08 / math.sqrt(2 * len(rel))  # relative: sd = sigma * yhat at the top


def test_bubbles_are_drawn_inside_their_ranges(sp, spec):
    bubbles = sp.draw_bubbles(np.random.default_rng(3), sp.Population(), spec, 500)
    d = np.array([b["diameter_um"] for b in bubbles])
    d0 = np.array([b["d0"] for b in bubbles])
    assert d.min() >= sp.DIAMETER_RANGE_UM[0] and d.max() <= sp.DIAMETER_RANGE_UM[1]
    assert d0.min() >= 0.125 and d0.max() <= 0.375  # inner half of the d0 prior [0, 0.5]
    for k in ("ka", "kb"):
        v = np.array([b[k] for b in bubbles])
        assert np.all(spec.parameters[k].prior.contains(v))
    assert {b["sigma"] for b in bubbles} == {sp.SIGMA}


def test_population_must_lie_well_inside_the_hyperprior_boxes(sp, checks, spec):
    sp.check_population(sp.Population(), spec)
    with pytest.raises(checks.StudyError, match="tau_ka = 100"):
        sp.check_population(sp.Population(tau_ka=100.0), spec)
    with pytest.raises(checks.StudyError, match="m_kb = 990"):
        sp.check_population(sp.Population(m_kb=990.0), spec)


def _bubbles():
    grid = np.linspace(0.0, 2.0, 12)
    return [{"id": "syn-001", "diameter_um": 2.345678901234, "x": grid + 0.2, "y": 10.0 + 300.0 * grid ** 1.5},
            {"id": "syn-002", "diameter_um": 5.5, "x": 1.3 * grid + 0.31, "y": 5.0 + 90.0 * grid}]


def test_tidy_file_round_trips_through_the_reader(sp, tmp_path):
    bubbles = _bubbles()
    path = sp.write_tidy(tmp_path / "curves.csv", sp.tidy_rows(bubbles, "lab-x"))
    read = read_bubble_curves(path)
    assert [b.bubble for b in read] == ["syn-001", "syn-002"]
    for r, b in zip(read, bubbles, strict=True):
        assert r.agent == "lab-x" and r.protocol == "compression" and r.diameter_um == b["diameter_um"]
        np.testing.assert_allclose(r.x, b["x"], rtol=1e-12)
        np.testing.assert_allclose(r.y, b["y"], rtol=1e-12)
        assert r.retained.all()
    sp.check_tidy(path, bubbles, "lab-x")


def test_check_tidy_catches_a_file_that_differs(sp, checks, tmp_path):
    bubbles = _bubbles()
    path = sp.write_tidy(tmp_path / "curves.csv", sp.tidy_rows(bubbles, "lab-x"))
    bubbles[1]["y"] = bubbles[1]["y"] * 1.001
    with pytest.raises(checks.StudyError, match="syn-002"):
        sp.check_tidy(path, bubbles, "lab-x")


def test_a_file_that_fails_its_check_never_replaces_the_last_good_one(sp, checks, tmp_path):
    bubbles = _bubbles()
    path = sp.write_tidy(tmp_path / "curves.csv", sp.tidy_rows(bubbles, "lab-x"))
    good = path.read_text()
    changed = [dict(b, y=b["y"] * 2.0) for b in bubbles]
    with pytest.raises(checks.StudyError, match="syn-001"):
        sp.write_tidy(path, sp.tidy_rows(changed, "lab-x"), lambda tmp: sp.check_tidy(tmp, bubbles, "lab-x"))
    assert path.read_text() == good and [p.name for p in tmp_path.iterdir()] == ["curves.csv"]


def test_binomial_range_is_the_central_95_percent(checks):
    for n in (10, 40, 100):
        lo, hi = checks.binomial_range(n)
        assert binom.cdf(lo - 1, n, 0.9) <= 0.025 < binom.cdf(lo, n, 0.9)
        assert binom.sf(hi, n, 0.9) <= 0.025 < binom.sf(hi - 1, n, 0.9)


def _truth(n=40):
    rng = np.random.default_rng(5)
    bubbles = [{"id": f"syn-{i + 1:03d}", "ka": float(v), "kb": float(w)}
               for i, (v, w) in enumerate(zip(rng.uniform(8e3, 2e4, n), rng.uniform(200, 800, n), strict=True))]
    return {"population": {"ka": {"m": 15000.0, "tau": 4000.0}, "kb": {"m": 500.0, "tau": 150.0}},
            "bubbles": bubbles}


def _summary(truth, covered_ka: int, m_ka_interval=(14000.0, 16000.0)):
    """Summary rows: the first ``covered_ka`` bubbles' k_a intervals cover the truth, the others lie above it."""
    rows = []
    for i, b in enumerate(truth["bubbles"]):
        lo = b["ka"] - 500.0 if i < covered_ka else b["ka"] + 100.0
        rows.append({"dataset": b["id"], "parameter": "ka", "q05": repr(lo), "q95": repr(lo + 1000.0)})
        rows.append({"dataset": b["id"], "parameter": "kb", "q05": repr(b["kb"] - 50), "q95": repr(b["kb"] + 50)})
    hyper = {"m_ka": m_ka_interval, "tau_ka": (3000.0, 5000.0), "m_kb": (450.0, 550.0), "tau_kb": (100.0, 200.0)}
    rows += [{"dataset": "hyperparameters", "parameter": k, "q05": repr(a), "q95": repr(b)} for k, (a, b) in
             hyper.items()]
    return rows


def test_coverage_inside_and_outside_the_binomial_range(checks):
    truth = _truth()
    good = checks.coverage_check(truth, _summary(truth, 36), "ka")
    assert good["pass"] and good["hits"] == 36 and len(good["missed"]) == 4
    low = checks.coverage_check(truth, _summary(truth, 25), "ka")
    assert not low["pass"] and low["hits"] == 25
    full = checks.coverage_check(truth, _summary(truth, 40), "ka")  # 40 of 40: intervals too wide, outside too
    assert full["hits"] == 40 and not full["pass"]


def test_hyperparameter_inside_and_outside_its_interval(checks):
    truth = _truth()
    assert checks.hyper_check(truth, _summary(truth, 36), "m_ka")["pass"]
    miss = checks.hyper_check(truth, _summary(truth, 36, m_ka_interval=(15500.0, 17000.0)), "m_ka")
    assert not miss["pass"] and miss["true"] == 15000.0


def test_evaluate_verdict_and_missing_rows(checks):
    truth = _truth()
    assert checks.evaluate(truth, _summary(truth, 36))["pass"]
    assert not checks.evaluate(truth, _summary(truth, 20))["pass"]
    assert not checks.evaluate(truth, _summary(truth, 36, m_ka_interval=(1.0, 2.0)))["pass"]
    rows = [r for r in _summary(truth, 36) if r["dataset"] != "syn-007"]
    with pytest.raises(checks.StudyError, match="syn-007"):
        checks.evaluate(truth, rows)


def test_evaluate_command_reads_the_calibration_folder(sp, tmp_path, capsys):
    truth = _truth()
    (tmp_path / "truth.json").write_text(json.dumps(truth))
    for name, covered in (("good", 36), ("bad", 10)):
        folder = tmp_path / name / "definity" / "reduced"
        folder.mkdir(parents=True)
        with open(folder / "summary.csv", "w", newline="") as handle:
            out = csv.DictWriter(handle, fieldnames=["dataset", "parameter", "q05", "q95"])
            out.writeheader()
            out.writerows(_summary(truth, covered))
        code = sp.main(["evaluate", "--truth", str(tmp_path / "truth.json"), "--calibration", str(folder)])
        last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
        assert (code, last["pass"]) == ((0, True) if name == "good" else (1, False))
    assert sp.main(["evaluate", "--truth", str(tmp_path / "truth.json"), "--calibration", str(tmp_path)]) == 2
    assert "no such file" in capsys.readouterr().err
