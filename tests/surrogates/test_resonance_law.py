"""The diameter-continuous acoustic law: fit, leave-diameters-out, file format version 2, range checks, JAX."""

from __future__ import annotations

import json
import math

import jax
import numpy as np
import pytest

from bubblecal.surrogates import (
    LAW_FORMS,
    AcousticFormatError,
    AcousticLawSurrogate,
    AcousticRangeError,
    AcousticRangeWarning,
    AcousticSurrogate,
    classical_f0,
    compare_forms,
    diameter_exponent,
    fit_law,
)
from bubblecal.surrogates.law_fit import law_predict

#: Known coefficients of the 'gas-coupled' form: f^2 = c0/D^2 + c1/D + (c2/D^2 + c3/D) ka + c4/D^2 ka^2.
TRUE = (-0.5, 0.08, 4.6e-3, -1.0e-5, -2.0e-8)
DIAMETERS = np.arange(1.5, 8.01, 0.5)
KA = np.linspace(3500.0, 34000.0, 12)


def _rows(noise: float = 0.0, seed: int = 0):
    d, ka = (v.ravel() for v in np.meshgrid(DIAMETERS, KA, indexing="ij"))
    f = law_predict(TRUE, d, ka, "gas-coupled")
    rng = np.random.default_rng(seed)
    return d, ka, f * (1.0 + noise * rng.standard_normal(f.size))


@pytest.fixture(scope="module")
def law():
    return fit_law(*_rows(), "gas-coupled", meta={"agent": "test"})


def test_exact_law_is_recovered_with_vanishing_holdout_errors(law):
    assert law.coefficients == pytest.approx(TRUE, rel=1e-7)
    assert law.diameter_range == (1.5, 8.0) and law.ka_range == (3500.0, 34000.0) and law.n_points == 168
    assert law.holdout["max"] < 1e-7 and len(law.holdout["per_diameter"]) == 14
    assert law.holdout["bands"][0]["diameters_um"] == [3.5, 4.0, 4.5] and law.holdout["bands"][0]["max"] < 1e-7


def test_noisy_holdout_median_matches_the_noise():
    # |N(0, s)| has median 0.6745 s; 5 coefficients from 168 rows add little (one-diameter hold-out: extrapolating
    # at the ends, which widens it somewhat)
    s = 2e-3
    d, ka, f = _rows(noise=s, seed=1)
    law = fit_law(d, ka, f, "gas-coupled")
    # the coefficients are correlated (1/D^2 against 1/D), the law they make is not: within the noise everywhere
    truth = law_predict(TRUE, d, ka, "gas-coupled")
    assert np.max(np.abs(law_predict(law.coefficients, d, ka, "gas-coupled") / truth - 1)) < s
    assert 0.6745 * s * 0.8 < law.holdout["median"] < 0.6745 * s * 1.5


def test_compare_forms_prefers_the_generating_form():
    out = compare_forms(*_rows(noise=1e-3, seed=2), forms=["scale-free", "gas", "gas-coupled", "liquid-inertia"])
    assert out["gas-coupled"]["ldo_median"] < 2e-3
    assert out["scale-free"]["ldo_median"] > 1.5 * out["gas-coupled"]["ldo_median"]
    assert out["liquid-inertia"]["ldo_median"] > 10 * out["gas-coupled"]["ldo_median"]


def test_fit_law_refuses_too_few_diameters_and_unknown_forms():
    d, ka, f = _rows()
    two = d <= 2.0
    with pytest.raises(ValueError, match=">= 3 simulated diameters"):
        fit_law(d[two], ka[two], f[two])
    with pytest.raises(ValueError, match="unknown resonance-law form 'cubic'"):
        fit_law(d, ka, f, "cubic")
    with pytest.raises(ValueError, match=r"band \[9, 10\] um holds no simulated diameter"):
        fit_law(d, ka, f, bands_um=[(9.0, 10.0)])


def test_surrogate_at_a_diameter_never_simulated(law, tmp_path):
    sur = AcousticLawSurrogate(law, name="definity")
    c = sur.coefficients(3.7)
    expect = (TRUE[0] / 3.7**2 + TRUE[1] / 3.7, TRUE[2] / 3.7**2 + TRUE[3] / 3.7, TRUE[4] / 3.7**2)
    np.testing.assert_allclose(c, expect, rtol=1e-6)
    assert sur.coefficients(np.array([3.7, 5.2])).shape == (2, 3)
    ka = np.array([5e3, 2e4])
    np.testing.assert_allclose(sur.f_res(ka, 3.7), np.sqrt(c[0] + c[1] * ka + c[2] * ka**2), rtol=1e-5)
    # version 2 round trip; the class comes back from the file's version
    back = AcousticSurrogate.load(sur.save(tmp_path / "law.json"))
    assert isinstance(back, AcousticLawSurrogate) and back.law.form == "gas-coupled" and back.name == "definity"
    np.testing.assert_allclose(back.f_res(ka, 3.7), sur.f_res(ka, 3.7), rtol=1e-7)
    assert json.loads((tmp_path / "law.json").read_text())["format_version"] == 2


def test_ka_range_between_simulated_diameters_is_the_intersection():
    d, ka, f = _rows()
    keep = ~((d == 2.0) & (ka < 4000.0)) & ~((d == 2.5) & (ka > 33000.0))  # 2.0 um starts later, 2.5 um ends sooner
    sur = AcousticLawSurrogate(fit_law(d[keep], ka[keep], f[keep]), name="x")
    r = sur.ka_ranges(np.array([1.5, 1.75, 2.0, 2.25, 2.5, 3.0]))
    lo2, hi25 = KA[1], KA[-2]
    np.testing.assert_allclose(r[:, 0], [3500.0, lo2, lo2, lo2, 3500.0, 3500.0])
    np.testing.assert_allclose(r[:, 1], [34000.0, 34000.0, 34000.0, hi25, hi25, 34000.0])
    assert not bool(sur.in_range(3600.0, 2.25)) and bool(sur.in_range(3600.0, 2.6))


def test_diameter_and_ka_range_errors(law):
    sur = AcousticLawSurrogate(law, name="definity")
    for call in (lambda: sur.coefficients(8.5), lambda: sur.ka_ranges([3.0, 1.2]), lambda: sur.f_res(1e4, 9.0),
                 lambda: sur.check_range(1e4, 8.5)):
        with pytest.raises(AcousticRangeError, match=r"diameter\(s\) .* um outside the law's range \[1.5, 8\] um"):
            call()
    assert not bool(sur.in_range(1e4, 8.5)) and bool(sur.in_range(1e4, 8.0))
    with pytest.warns(AcousticRangeWarning, match=r"3.7 um: 1 ka value\(s\) 40000"):
        mask = sur.check_range(np.array([1e4, 4e4]), 3.7)
    assert mask.tolist() == [True, False]
    with pytest.raises(AcousticRangeError, match="outside the fitted ka range"):
        sur.check_range(4e4, 3.7, action="raise")


def test_jit_and_grad_at_a_new_diameter(law):
    sur = AcousticLawSurrogate(law, name="definity")
    f = jax.jit(lambda k, d: sur.f_res(k, d))
    assert float(f(1.2e4, 3.7)) == pytest.approx(float(sur.f_res(1.2e4, 3.7)), rel=1e-6)
    dk, dd = jax.grad(lambda k, d: sur.f_res(k, d), argnums=(0, 1))(1.2e4, 3.7)

    def exact(k, d):
        return math.sqrt(TRUE[0] / d**2 + TRUE[1] / d + (TRUE[2] / d**2 + TRUE[3] / d) * k + TRUE[4] / d**2 * k * k)

    h = 1e-4
    assert float(dd) == pytest.approx((exact(1.2e4, 3.7 + h) - exact(1.2e4, 3.7 - h)) / (2 * h), rel=1e-3)
    assert float(dk) == pytest.approx((exact(1.2e4 + 1, 3.7) - exact(1.2e4 - 1, 3.7)) / 2, rel=1e-3)
    # a traced diameter is masked by in_range, not raised on
    masked = jax.jit(lambda d: sur.in_range(1.2e4, d))
    assert bool(masked(3.7)) and not bool(masked(9.0))


def test_version_1_files_still_load_as_per_diameter_quadratics(tmp_path):
    data = {d: (KA, np.sqrt(0.4 / d + 2e-4 * KA / d)) for d in (2.0, 4.0)}
    path = AcousticSurrogate.fit(data, name="definity").save(tmp_path / "v1.json")
    assert json.loads(path.read_text())["format_version"] == 1
    back = AcousticSurrogate.load(path)
    assert type(back) is AcousticSurrogate and back.diameters == [2.0, 4.0]
    with pytest.raises(AcousticRangeError, match="no fit at diameter 3 um"):
        back.coefficients(3.0)


@pytest.mark.parametrize("edit, field", [
    (lambda d: d["law"].pop("coefficients"), "'law.coefficients' is missing"),
    (lambda d: d["law"]["coefficients"].__setitem__(2, float("nan")), r"'law.coefficients\[2\]' must be a finite"),
    (lambda d: d["law"].__setitem__("diameter_range_um", [8.0, 1.5]), "'law.diameter_range_um' must be"),
    (lambda d: d["law"]["diameters"].reverse(), "'law.diameters': diameters must increase"),
    (lambda d: d["law"]["diameters"][3].__setitem__("ka_max", 10.0), r"'law.diameters\[3\]': ka_min"),
    (lambda d: d["law"]["coefficients"].pop(), "'law.coefficients' must hold 5 numbers"),
    (lambda d: d.pop("law"), "field 'law' is missing"),
    (lambda d: d.__setitem__("diameter_units", "m"), "field 'diameter_units' must be 'um'"),
    (lambda d: d.__setitem__("format_version", 3), "this code reads version 1 or 2"),
])
def test_version_2_validation_names_file_and_field(law, tmp_path, edit, field):
    d = AcousticLawSurrogate(law, name="definity").to_dict()
    edit(d)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(d))
    with pytest.raises(AcousticFormatError, match=f"bad.json: .*{field}"):
        AcousticSurrogate.load(path)


def test_classical_f0_limits_and_exponents():
    # no shell: Minnaert with the polytropic gas, f ~ 1/D exactly
    d = np.array([2.0, 4.0, 8.0])
    f = classical_f0(0.0, d, kappa=1.0, rho_kg_m3=1000.0)
    np.testing.assert_allclose(f, np.sqrt(3 * 101_325.0 / 1000.0) / (2 * np.pi * d * 0.5e-6) / 1e6, rtol=1e-12)
    assert diameter_exponent(d, f) == pytest.approx(-1.0, abs=1e-12)
    # shell-dominated: f ~ D^-1.5; a real shell lies between
    assert diameter_exponent(d, classical_f0(1e9, d)) == pytest.approx(-1.5, abs=1e-3)
    assert -1.5 < diameter_exponent(d, classical_f0(15000.0, d)) < -1.0
    with pytest.raises(ValueError, match="diameters > 0"):
        classical_f0(1e4, 0.0)


def test_every_form_names_its_physics():
    for form in LAW_FORMS.values():
        assert form.description and form.expression().startswith("f_res^2 = ") and len(form.powers) == 3
