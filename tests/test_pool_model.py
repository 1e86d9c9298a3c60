"""The slot-refill pool model (benchmarks/device/pool_model.py) on schedules with hand-computed wall times."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture(scope="module")
def pm(load_script):
    return load_script("benchmarks/device/pool_model.py")


def test_equal_curves_cost_their_batches(pm):
    # 4 curves of 10 iterations through 2 slots at 1 ms per batch iteration: 20 batch iterations
    t = pm.pool_seconds(np.full(4, 10.0), np.arange(4.0), 2, lambda R, k: 1.0)
    assert t == pytest.approx(0.020)


def test_softest_first_order(pm):
    # k_a order puts the long curve last: [1, 1] then [10] -> 11 iterations (unsorted [10, 1, 1] would take 10)
    t = pm.pool_seconds(np.array([10.0, 1.0, 1.0]), np.array([3.0, 1.0, 2.0]), 2, lambda R, k: 1.0)
    assert t == pytest.approx(0.011)


def test_last_curves_move_to_a_batch_of_their_own_size(pm):
    # 16 slots, cost = batch size in ms; 15 one-iteration curves and one of 100: 16 ms, then 99 x 1 ms once the
    # last curve (<= 1/8 of 16 slots) runs alone
    steps = np.r_[np.ones(15), 100.0]
    t = pm.pool_seconds(steps, np.arange(16.0), 16, lambda R, k: float(R))
    assert t == pytest.approx(0.016 + 0.099)


def test_cost_table_and_interpolation(pm):
    lines = [{"threads_per_replica": "a", "rows": [
        {"graph": True, "replicas": 1, "active": 1, "ms_per_iteration": 0.1},
        {"graph": True, "replicas": 10, "active": 10, "ms_per_iteration": 1.0},
        {"graph": True, "replicas": 10, "active": 1, "ms_per_iteration": 0.2},
        {"graph": False, "replicas": 10, "active": 10, "ms_per_iteration": 9.0}]},
        {"threads_per_replica": "b", "rows": [{"graph": True, "replicas": 1, "active": 1, "ms_per_iteration": 0.05}]}]
    table = pm.cost_table(lines, "a")
    assert table == {1: (0.1, 0.1), 10: (1.0, 0.2)}  # plain-launch rows ignored
    assert pm.cost_table(lines, "b") == {1: (0.05, 0.05)}
    cost = pm.iteration_cost(table)
    assert cost(10, 10) == pytest.approx(1.0) and cost(10, 1) == pytest.approx(0.2)
    assert cost(5, 5) == pytest.approx(0.1 + 0.9 * 4 / 9)  # all relaxing, between the measured sizes
    assert cost(20, 20) == pytest.approx(2.0)  # beyond the largest size: proportional


def test_cost_lines_match_on_kernels_text_too(pm):
    lines = [{"kernels": "kantor_edge, gas on the shell pass", "rows": [
        {"graph": True, "replicas": 4, "active": 4, "ms_per_iteration": 0.4}]}]
    assert pm.cost_table(lines, "kantor_edge") == {4: (0.4, 0.4)}
    assert pm.cost_table(lines, "64 threads") == {}


def test_max_steps_models_the_capped_work_and_the_kept_curves(pm, tmp_path, capsys):
    import json

    from bubblecal.data import CampaignStore, make_record

    store = CampaignStore.create(tmp_path / "s.store")
    full = {"ka": 1.0, "kb": 1.0, "b1": 0.0, "b2": 0.0, "a3": 0.0, "a4": 0.0}
    # two curves: 10 + 20 updates (ok), 5 + 60 (ok; a cap of 30 cuts it after 5 + 30)
    for i, chain in enumerate(([10, 20], [5, 60])):
        store.append(make_record(sample_id=f"s{i}", setup="indentation", params={**full, "ka": float(i + 1)},
                                 radius_dpd=6.4, x=[0.0, 1.0], y=[0.0, 0.1], status="ok", seed=i,
                                 tier="quasistatic", provenance={"info": {
                                     "fire_steps": sum(chain), "fire_steps_chain": chain,
                                     "settings": {"fire": {"max_steps": 100}}}}))
    costs = tmp_path / "c.jsonl"
    costs.write_text(json.dumps({"threads_per_replica": "t", "rows": [
        {"graph": True, "replicas": 2, "active": 2, "ms_per_iteration": 1.0},
        {"graph": True, "replicas": 2, "active": 1, "ms_per_iteration": 1.0}]}) + "\n")
    assert pm.main([str(tmp_path / "s.store"), "--costs", str(costs), "--slots", "2", "--max-steps", "30"]) == 0
    rows = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["rows"]
    by = {r["max_steps"]: r for r in rows}
    # 2 slots at 1 ms per batch iteration: the pool lasts as long as its longest curve
    assert by[None]["model_s"] == pytest.approx(0.065) and by[None]["ok"] == 2
    assert by[30]["model_s"] == pytest.approx(0.035) and by[30]["ok"] == 1
    for bad in ("x", "0"):
        with pytest.raises(SystemExit, match="--max-steps .*integers >= 1"):
            pm.main([str(tmp_path / "s.store"), "--costs", str(costs), "--max-steps", bad])
