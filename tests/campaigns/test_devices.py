"""A campaign checks its device before any task: no GPU, no records, a message that says so."""

from __future__ import annotations

from pathlib import Path

import pytest

from bubblecal.campaigns import (
    CampaignError,
    CampaignSummary,
    check_device,
    cuda_device_count,
    load_campaign_file,
    run_campaign,
)
from bubblecal.data import CampaignStore

TINY = Path(__file__).parent / "tiny_campaign.toml"


def test_check_device_names_what_the_machine_has():
    check_device("cpu", n_cuda=0)
    check_device("cuda:1", n_cuda=2)
    with pytest.raises(CampaignError, match="'cuda': this machine has no CUDA device; nothing was simulated"):
        check_device("cuda", n_cuda=0)
    with pytest.raises(CampaignError, match=r"'cuda:2': worker a has 2 CUDA device\(s\) \(cuda:0 - cuda:1\)"):
        check_device("cuda:2", n_cuda=2, where="worker a")


@pytest.mark.skipif(cuda_device_count() > 0, reason="this machine has a CUDA device")
def test_a_cuda_campaign_on_a_cpu_machine_writes_nothing(tmp_path):
    import dataclasses

    config = load_campaign_file(TINY, store=tmp_path / "s").config
    config = dataclasses.replace(config, device="cuda")
    with pytest.raises(CampaignError, match="no CUDA device"):
        run_campaign(config, scheduler_address="inline", progress=False)
    assert CampaignStore(tmp_path / "s").read() == []


def test_a_run_whose_samples_all_failed_is_not_a_success():
    base = dict(name="x", store="s", n_design=4, n_done_before=0, n_pending=4, n_submitted=4, n_tasks=1,
                store_counts={}, wall_seconds=1.0, startup_seconds=0.0, compute_seconds=1.0, task_seconds=[1.0],
                n_workers=1, scheduler="inline")
    assert CampaignSummary(**base, n_written=4, counts={"failed": 3, "invalid": 1}).all_failed
    assert not CampaignSummary(**base, n_written=4, counts={"failed": 3, "ok": 1}).all_failed
    assert not CampaignSummary(**base, n_written=0, counts={}).all_failed
