"""benchmarks/max_steps_study.py: which curves a smaller quasi-static max_steps keeps, and the FIRE work it saves."""

from __future__ import annotations

import json

import pytest


@pytest.fixture(scope="module")
def ms(load_script):
    return load_script("benchmarks/max_steps_study.py")


def _rec(status, chain, kb, cap=100):
    return {"status": status, "params": {"ka": 10.0 * kb, "kb": kb},
            "provenance": {"info": {"fire_steps_chain": chain, "settings": {"fire": {"max_steps": cap}}}}}


RECORDS = [
    _rec("ok", [10, 20, 30], 1.0),        # every point <= 30: kept at caps >= 30
    _rec("ok", [5, 60, 5], 2.0),          # point 2 needs 60: lost below 60, then costs 5 + cap
    _rec("unstable", [10, 100, 0], 3.0),  # hit the run's cap at point 2
]


def test_caps_keep_exactly_the_curves_whose_points_all_converged_within_them(ms):
    res = ms.study(RECORDS, [100, 60, 30, 10])
    by = {c["max_steps"]: c for c in res["caps"]}
    assert res["ok"] == 2 and res["run_max_steps"] == 100
    assert (by[100]["ok"], by[60]["ok"], by[30]["ok"], by[10]["ok"]) == (2, 2, 1, 0)
    assert by[30]["lost_kb"] == [2.0, 2.0] and by[30]["lost_kb_median"] == 2.0 and by[100]["lost_kb"] is None
    base = 60 + 70 + 110
    # cap 30: curve 1 unchanged (60), curve 2 ends at point 2 (5 + 30), curve 3 ends at point 2 (10 + 30)
    assert by[30]["work_fraction"] == pytest.approx((60 + 35 + 40) / base)
    # cap 10: curve 1 ends at point 2 (10 + 10), curve 2 (5 + 10), curve 3 (10 + 10)
    assert by[10]["work_fraction"] == pytest.approx((20 + 15 + 20) / base)
    assert by[100]["max_curve_work"] == 110 and by[30]["max_curve_work"] == 60


def test_reads_a_store_and_its_export_and_refuses_what_the_records_cannot_answer(ms, tmp_path, capsys):
    from bubblecal.data import CampaignStore, export_compressed, make_record

    store = CampaignStore.create(tmp_path / "s.store")
    full = {"ka": 1.0, "kb": 1.0, "b1": 0.0, "b2": 0.0, "a3": 0.0, "a4": 0.0}
    for i, r in enumerate(RECORDS):
        store.append(make_record(sample_id=f"s{i}", setup="indentation", params={**full, **r["params"]},
                                 radius_dpd=6.4, x=[0.0, 1.0, 2.0], y=[0.0, 0.1, 0.2], status=r["status"], seed=i,
                                 tier="quasistatic", provenance=r["provenance"]))
    export = export_compressed(store, tmp_path / "s.jsonl.gz")
    for path in (tmp_path / "s.store", export):
        assert ms.main([str(path), "--caps", "100,30"]) == 0
        last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
        assert [c["ok"] for c in last["caps"]] == [2, 1]
    with pytest.raises(SystemExit, match="exceed the run's own max_steps"):
        ms.study(RECORDS, [200])
    with pytest.raises(SystemExit, match="fire_steps_chain"):
        ms.study([{"status": "ok", "params": {"kb": 1.0}, "provenance": {"info": {}}}], [10])
    with pytest.raises(SystemExit, match="--caps"):
        ms.main([str(export), "--caps", "x"])
