"""The summaries' statistics on threads: same numbers as in one thread, in submission order, bounded."""

import threading

import numpy as np
import pytest

from bubblecal.inference import predictive_band, predictive_crps
from bubblecal.workflows.summary_stats import (
    MAX_STATISTICS_THREADS,
    StatisticsPool,
    dataset_statistics,
    statistics_threads,
)


def _datasets(n, s=300, p=7, g=11, seed=3):
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        mu = 1.0 + 0.1 * rng.standard_normal((s, p))
        gmu = 1.0 + 0.1 * rng.standard_normal((s, g)) if i % 2 == 0 else None
        out.append((f"d{i}", mu, np.full_like(mu, 0.05), mu[0] + 0.01, gmu,
                    None if gmu is None else np.full_like(gmu, 0.05)))
    return out


def test_crps_with_normals_equals_crps_drawn_from_the_same_generator():
    mu, sd, y = _datasets(1)[0][1:4]
    drawn = predictive_crps(mu, sd, y, replicates=4, seed=np.random.default_rng(8))
    normals = np.random.default_rng(8).standard_normal((4, *mu.shape))
    given = predictive_crps(mu, sd, y, replicates=99, normals=normals)
    np.testing.assert_array_equal(drawn.replicates, given.replicates)
    np.testing.assert_array_equal(drawn.per_point, given.per_point)
    with pytest.raises(ValueError, match="normals must have shape"):
        predictive_crps(mu, sd, y, normals=normals[:, :, :3])


@pytest.mark.parametrize("threads", [1, 3])
def test_pool_gives_the_sequential_statistics_in_submission_order(threads):
    data = _datasets(9)
    rng = np.random.default_rng(0)
    expected = {}
    for name, mu, sd, y, gmu, gsd in data:  # the order and draws of the single-threaded summaries
        crps = predictive_crps(mu, sd, y, replicates=3, seed=rng)
        expected[name] = (predictive_band(mu, sd, 0.9), crps,
                          None if gmu is None else predictive_band(gmu, gsd, 0.9))
    with StatisticsPool(np.random.default_rng(0), 3, threads=threads) as pool:
        for name, mu, sd, y, gmu, gsd in data:
            pool.submit(name, mu, sd, y, gmu, gsd)
        got = pool.results()
    assert list(got) == [d[0] for d in data]
    for name, (band, crps, gband) in expected.items():
        np.testing.assert_array_equal(got[name].band.median, band.median)
        np.testing.assert_array_equal(got[name].band.lower, band.lower)
        np.testing.assert_array_equal(got[name].crps.replicates, crps.replicates)
        if gband is None:
            assert got[name].grid_band is None and got[name].grid_model is None
        else:
            np.testing.assert_array_equal(got[name].grid_band.upper, gband.upper)
            assert got[name].grid_model.shape == (3, gband.upper.size)


def test_pool_keeps_at_most_twice_its_threads_in_flight(monkeypatch):
    import bubblecal.workflows.summary_stats as stats

    gate = threading.Event()
    running = []

    def slow(*args):
        running.append(1)
        gate.wait(5)
        return dataset_statistics(*args)

    monkeypatch.setattr(stats, "dataset_statistics", slow)
    data = _datasets(6, s=50)
    with StatisticsPool(np.random.default_rng(0), 2, threads=2) as pool:
        for name, mu, sd, y, gmu, gsd in data[:4]:
            pool.submit(name, mu, sd, y, gmu, gsd)
        assert len(pool._inflight) == 4  # 2 threads x 2: the next submit has to wait
        gate.set()
        for name, mu, sd, y, gmu, gsd in data[4:]:
            pool.submit(name, mu, sd, y, gmu, gsd)
            assert len(pool._inflight) <= 4
        assert len(pool.results()) == 6


def test_pool_raises_a_dataset_error_and_refuses_a_name_twice():
    name, mu, sd, y, gmu, gsd = _datasets(1)[0]
    with StatisticsPool(np.random.default_rng(0), 2, threads=2) as pool:
        pool.submit(name, mu, sd, y)
        with pytest.raises(ValueError, match="submitted twice"):
            pool.submit(name, mu, sd, y)
        pool.submit("bad", mu, sd, y[:3])  # y of the wrong length
        with pytest.raises(ValueError, match="y must have shape"):
            pool.results()
    with pytest.raises(ValueError, match="replicates"):
        StatisticsPool(np.random.default_rng(0), 0)


def test_statistics_threads_one_per_core_within_bounds():
    assert statistics_threads(1) == 1
    assert statistics_threads(2) == 2
    assert statistics_threads(64) == MAX_STATISTICS_THREADS
    assert statistics_threads(0) == 1
