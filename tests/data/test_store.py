"""Campaign store: append/read, resume, torn writes, checksums, schema errors."""

from __future__ import annotations

import json
import math

import pytest

from bubblecal.data import CampaignStore, StoreError, make_record

P = {"ka": 15000.0, "kb": 900.0, "b1": 1.0, "b2": 0.5, "a3": -0.3, "a4": 1.7}


def rec(i, status="ok", **kw):
    return make_record(sample_id=f"lhs-{i:04d}", setup="compression", params=P, radius_dpd=4.2,
                       x=[0.0, 0.12, 0.24], y=[50.0 + i, 400.0, 1000.0 + 1e-13 * i], status=status, seed=i,
                       tier="explicit", provenance={"host": "test"}, **kw)


def test_append_read_roundtrip_exact(tmp_path):
    store = CampaignStore.create(tmp_path / "s", description="unit test", fsync=False)
    store.append(rec(0))
    store.append_many([rec(1), rec(2, status="ruptured", message="shell broke")])
    again = CampaignStore(tmp_path / "s")
    records = again.read()
    assert [r["sample_id"] for r in records] == ["lhs-0000", "lhs-0001", "lhs-0002"]
    assert records[2]["y"][2] == 1000.0 + 2e-13  # floats round-trip exactly
    assert records[2]["message"] == "shell broke"
    assert again.header()["description"] == "unit test"
    assert again.counts()["ruptured"] == 1
    assert again.finished_ids() == {"lhs-0000", "lhs-0001", "lhs-0002"}


def test_resume_last_record_wins(tmp_path):
    store = CampaignStore.create(tmp_path / "s", fsync=False)
    store.append(rec(0, status="failed", message="NaN at step 1000"))
    store.append(rec(1))
    assert store.finished_ids() == {"lhs-0001"}  # the failed sample is to be retried
    store.append(rec(0))
    assert store.finished_ids() == {"lhs-0000", "lhs-0001"}
    assert [r["status"] for r in store.read()] == ["ok", "ok"]


def test_crash_mid_write_is_skipped_and_repaired(tmp_path):
    store = CampaignStore.create(tmp_path / "s", fsync=False)
    store.append_many([rec(0), rec(1)])
    full = (json.dumps(rec(2)))
    with open(store.records_path, "a") as fh:  # a torn write: half a line, no newline
        fh.write(full[: len(full) // 2])
    reader = CampaignStore(tmp_path / "s")
    with pytest.warns(UserWarning, match="1 line"):
        records = reader.read()
    assert len(records) == 2 and "unreadable" in reader.problems[0]
    writer = CampaignStore(tmp_path / "s", fsync=False)
    writer.append(rec(3))  # terminates the torn line, then appends
    with pytest.warns(UserWarning):
        ids = [r["sample_id"] for r in CampaignStore(tmp_path / "s").read()]
    assert ids == ["lhs-0000", "lhs-0001", "lhs-0003"]


def test_checksum_detects_edit(tmp_path):
    store = CampaignStore.create(tmp_path / "s", fsync=False)
    store.append_many([rec(0), rec(1)])
    lines = store.records_path.read_text().splitlines()
    lines[0] = lines[0].replace('"seed":0', '"seed":7')
    store.records_path.write_text("\n".join(lines) + "\n")
    with pytest.warns(UserWarning, match="checksum"):
        assert [r["sample_id"] for r in store.read()] == ["lhs-0001"]


def test_schema_errors_name_field(tmp_path):
    with pytest.raises(StoreError, match="field 'status'"):
        rec(0, status="done")
    with pytest.raises(StoreError, match="field 'params' lacks 'a4'"):
        make_record(sample_id="a", setup="compression", params={k: 1.0 for k in P if k != "a4"}, radius_dpd=4.2,
                    x=[0.0], y=[1.0], status="ok", seed=0, tier="explicit")
    with pytest.raises(StoreError, match="non-finite"):
        make_record(sample_id="a", setup="compression", params=P, radius_dpd=4.2, x=[0.0, 1.0],
                    y=[1.0, math.nan], status="ok", seed=0, tier="explicit")
    # a failed record may carry NaN
    r = make_record(sample_id="a", setup="indentation", params=P, radius_dpd=6.38, x=[0.0, 1.0],
                    y=[0.0, math.nan], status="failed", seed=0, tier="implicit")
    s = CampaignStore(tmp_path / "bare.jsonl", fsync=False)
    s.append(r)
    assert math.isnan(s.read()[0]["y"][1])
    (tmp_path / "notastore").mkdir()
    with pytest.raises(StoreError, match="not a campaign store"):
        CampaignStore(tmp_path / "notastore").append(r)


def test_invalid_status_and_ringdown_setup_roundtrip(tmp_path):
    """Extensions of format 1: 'invalid' (non-finite curve) and 'ringdown' records (x = t, y = R(t))."""
    store = CampaignStore.create(tmp_path / "s", fsync=False)
    bad = make_record(sample_id="c-0", setup="compression", params=P, radius_dpd=4.2, x=[0.0, 0.12],
                      y=[0.0, math.nan], status="invalid", seed=1, tier="quasistatic", message="non-finite")
    ring = make_record(sample_id="r-0", setup="ringdown", params=P, radius_dpd=9.36, x=[0.0, 0.1, 0.2],
                       y=[9.36, 9.40, 9.33], status="ok", seed=2, tier="implicit")
    store.append_many([bad, ring, rec(5)])
    back = {r["sample_id"]: r for r in CampaignStore(tmp_path / "s").read()}
    assert back["c-0"]["status"] == "invalid" and math.isnan(back["c-0"]["y"][1])
    assert back["r-0"]["setup"] == "ringdown" and back["r-0"]["y"] == [9.36, 9.40, 9.33]
    assert store.counts()["invalid"] == 1
    assert store.finished_ids() == {"r-0", "lhs-0005"}  # default: ok + ruptured
    assert store.finished_ids(statuses=("ok", "invalid")) == {"c-0", "r-0", "lhs-0005"}
    with pytest.raises(StoreError, match="field 'setup'"):
        make_record(sample_id="x", setup="shear", params=P, radius_dpd=1.0, x=[0.0], y=[0.0], status="ok", seed=0,
                    tier="explicit")


def test_compressed_export_is_exact_deterministic_and_read_only(tmp_path):
    from bubblecal.data import export_compressed

    store = CampaignStore.create(tmp_path / "s", fsync=False)
    store.append_many([rec(0, status="failed"), rec(1), rec(2, status="ruptured")])
    store.append(rec(0))  # the retried sample: only its latest record is exported
    out = export_compressed(store, tmp_path / "set.jsonl.gz")
    packed = CampaignStore(out)
    assert packed.compressed and packed.read() == store.read()
    assert export_compressed(tmp_path / "s", tmp_path / "again.jsonl.gz").read_bytes() == out.read_bytes()
    with pytest.raises(StoreError, match="read-only"):
        packed.append(rec(3))
    with pytest.raises(StoreError, match="must end in .jsonl.gz"):
        export_compressed(store, tmp_path / "set.gz")
