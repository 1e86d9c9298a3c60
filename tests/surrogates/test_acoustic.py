"""The per-diameter f_res^2(k_a) acoustic surrogate: quadratic fit, LOO errors, JSON, JAX, range checks."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from bubblecal.surrogates import (
    AcousticFormatError,
    AcousticRangeError,
    AcousticRangeWarning,
    AcousticSurrogate,
    fit_quadratic,
)


def _acoustic():
    rng = np.random.default_rng(0)
    data = {}
    for d, (a0, a1, a2) in {4.68: (0.4, 2e-4, -1e-9), 11.2: (0.05, 5e-5, -2e-10)}.items():
        ka = np.linspace(2e3, 3e4, 12)
        f = np.sqrt(a0 + a1 * ka + a2 * ka**2) * (1 + 1e-3 * rng.standard_normal(ka.size))
        data[d] = (ka, f)
    return AcousticSurrogate.fit(data, name="definity", meta={"kb": 389.23, "mass_factor": 160})


def test_quadratic_fit_and_loo():
    ka = np.linspace(1e3, 2e4, 10)
    fit = fit_quadratic(ka, np.sqrt(0.3 + 1e-4 * ka + 2e-9 * ka**2), 3.2)
    assert (fit.a0, fit.a1, fit.a2) == pytest.approx((0.3, 1e-4, 2e-9), rel=1e-6)
    assert len(fit.loo_rel_errors) == 10 and fit.loo_max < 1e-8
    with pytest.raises(ValueError, match="3 distinct ka"):
        fit_quadratic([1.0, 1.0, 2.0], [1.0, 1.0, 2.0], 3.2)


def test_acoustic_json_jax_and_range(tmp_path):
    ac = _acoustic()
    assert max(ac.fits[4.68].loo_rel_errors) < 5e-3
    path = ac.save(tmp_path / "acoustic_definity.json")
    back = AcousticSurrogate.load(path)
    assert back.diameters == [4.68, 11.2] and back.meta["kb"] == 389.23
    ka = np.array([5e3, 1e4])
    np.testing.assert_allclose(back.f_res(ka, 4.68), np.sqrt(0.4 + 2e-4 * ka - 1e-9 * ka**2), rtol=3e-3)
    # vectorised over diameters; jit/grad in ka
    v = back.f_res(np.array([1e4, 1e4]), np.array([4.68, 11.2]))
    assert v.shape == (2,) and v[1] < v[0]
    g = jax.grad(lambda k: back.f_res(k, 4.68))(1e4)
    assert np.isfinite(float(g)) and float(g) > 0
    assert float(jax.jit(lambda k: back.f_res(k, 11.2))(1e4)) == pytest.approx(float(v[1]), rel=1e-6)
    # outside the fitted ka range -> flagged
    mask = np.asarray(back.in_range(np.array([1e4, 5e4]), 4.68))
    assert mask.tolist() == [True, False]
    with pytest.warns(AcousticRangeWarning, match="4.68 um: 1 ka value"):
        back.check_range(np.array([1e4, 5e4]), 4.68)
    with pytest.raises(AcousticRangeError, match="outside the fitted ka range"):
        back.check_range(1e3, 11.2, action="raise")
    with pytest.raises(AcousticRangeError, match="no fit at diameter 5"):
        back.f_res(1e4, 5.0)


def test_acoustic_bad_files(tmp_path):
    ac = _acoustic()
    d = ac.to_dict()
    d["format_version"] = 9
    p = tmp_path / "v9.json"
    p.write_text(__import__("json").dumps(d))
    with pytest.raises(AcousticFormatError, match=r"v9\.json: field 'format_version'"):
        AcousticSurrogate.load(p)
    d = ac.to_dict()
    del d["diameters"][1]["a2"]
    p.write_text(__import__("json").dumps(d))
    with pytest.raises(AcousticFormatError, match=r"diameters\[1\] lacks field 'a2'"):
        AcousticSurrogate.load(p)
