"""Per-curve loss weights (``TrainConfig.curve_weights``): the weights against hand-computed ones, the default path
unchanged, the recorded recipe, bad values, and a fit whose few large curves no longer take the loss."""

from __future__ import annotations

import numpy as np
import pytest

from bubblecal.surrogates.training import CURVE_WEIGHTS, curve_weights

torch = pytest.importorskip("torch")

from bubblecal.surrogates.training import TrainConfig, train_mlp  # noqa: E402


def test_capped_weights_by_hand():
    # mean squares 5/3, 500/3, 0.05/3: median 5/3, so the large curve weighs 0.01 and the others 1, then mean 1
    y = np.array([0.0, 1.0, 2.0, 0.0, 10.0, 20.0, 0.0, 0.1, 0.2])
    w = curve_weights(y, np.repeat([0, 1, 2], 3), "capped")
    expected = np.repeat([1.0, 0.01, 1.0], 3)
    np.testing.assert_allclose(w, expected / expected.mean(), rtol=1e-12)
    assert w.mean() == pytest.approx(1.0)
    assert curve_weights(y, np.repeat([0, 1, 2], 3), "none") is None


@pytest.mark.parametrize(("target", "curve", "kind", "match"), [
    ([1.0], [0], "relative", "curve_weights must be one of"),
    ([1.0, 2.0], [0], "capped", "one value per point"),
    ([0.0, 0.0], [0, 1], "capped", "non-zero response"),
])
def test_bad_inputs(target, curve, kind, match):
    with pytest.raises(ValueError, match=match):
        curve_weights(np.array(target), np.array(curve), kind)


def test_config_records_the_setting_only_when_used():
    assert "curve_weights" not in TrainConfig().as_dict()  # earlier recipes and checkpoint keys read unchanged
    assert TrainConfig(curve_weights="capped").as_dict()["curve_weights"] == "capped"
    assert set(CURVE_WEIGHTS) == {"none", "capped"}
    with pytest.raises(ValueError, match="TrainConfig.curve_weights"):
        TrainConfig(curve_weights="relative")


def _families(n_small=40, n_large=4, seed=0):
    """Points of curves y = a x^2 (a in [0.5, 1.5]) and a few y = 50 sin(5 x) curves, told apart by an input flag."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, 15)
    u, y, curve = [], [], []
    for c in range(n_small + n_large):
        large = c >= n_small
        a = rng.uniform(0.5, 1.5)
        u.append(np.column_stack([np.full_like(x, a), np.full_like(x, float(large)), x]))
        y.append(50.0 * np.sin(5.0 * x) * a if large else a * x ** 2)
        curve.append(np.full(x.size, c))
    return np.concatenate(u), np.concatenate(y), np.concatenate(curve), n_small


def _small_curve_error(model, u, y, curve, n_small):
    from bubblecal.surrogates.training import numpy_forward

    pred = numpy_forward(model.weights, model.biases, model.in_mean, model.in_std, model.out_mean, model.out_std,
                         u)[:, 0]
    errs = [np.linalg.norm(pred[curve == c] - y[curve == c]) / np.linalg.norm(y[curve == c]) for c in range(n_small)]
    return float(np.median(errs))


def test_default_path_is_unchanged_and_capped_fits_the_typical_curves_better():
    u, y, curve, n_small = _families()
    cfg = TrainConfig(max_epochs=150, batch_size=64, lr=3e-3)
    plain = train_mlp(u, y, (8,), cfg, seed=0, progress=False)
    with_index = train_mlp(u, y, (8,), cfg, seed=0, progress=False, curve=curve)
    for a, b in zip(plain.weights, with_index.weights, strict=True):
        np.testing.assert_array_equal(a, b)
    capped = train_mlp(u, y, (8,), TrainConfig(max_epochs=150, batch_size=64, lr=3e-3, curve_weights="capped"),
                       seed=0, progress=False, curve=curve)
    e_plain, e_capped = (_small_curve_error(m, u, y, curve, n_small) for m in (plain, capped))
    # the 4 large curves hold ~99.9 % of the plain loss; capped, the 40 small ones are fitted at least twice as well
    assert e_capped < 0.5 * e_plain, (e_capped, e_plain)
    with pytest.raises(ValueError, match="needs the curve index"):
        train_mlp(u, y, (8,), TrainConfig(max_epochs=1, curve_weights="capped"), progress=False)
