"""Phase files written before the ArviZ groups: detected, named in one line and recomputed with the phases that
depend on them (never mixed); `.npz` files are reused as before; the joint run's chains read back concatenated."""

from __future__ import annotations

import numpy as np
import pytest

from bubblecal.inference.phase_results import PhaseResult
from bubblecal.workflows.calibrate import PhaseStore, phase_format, read_phase, write_phase

NAMES = ["phase1_a", "phase1_b", "phase2", "phase3_a", "phase3_b"]


def _store(folder, netcdf=True, said=None):
    st = PhaseStore(folder, netcdf=netcdf, say=said.append if said is not None else None)
    st.expected = {n: f"hash-{n}" for n in NAMES}
    return st


def _legacy_nc(path, samples, loglik, meta):
    """A phase file as the code before the ArviZ groups wrote it: posterior + sample_stats 'loglik' only."""
    import arviz as az

    idata = az.from_dict(posterior={k: np.asarray(v)[None] for k, v in samples.items()},
                         sample_stats={"loglik": np.asarray(loglik)[None]})
    idata.posterior.attrs.update(meta)
    idata.to_netcdf(str(path))


def test_legacy_netcdf_phase_is_named_and_recomputed_with_its_dependants(tmp_path):
    first = _store(tmp_path)
    for k, n in enumerate(NAMES):
        first.save(PhaseResult(n, {"ka": np.arange(5.0) + k}, -1.0, 0.1, "converged", 1.0))
    assert all(phase_format(tmp_path / f"{n}.nc") == 2 for n in NAMES)
    # phase1_b rewritten as the old code did (same hash in the manifest)
    _legacy_nc(tmp_path / "phase1_b.nc", {"ka": np.arange(5.0) + 1}, np.zeros(5),
               {"name": "phase1_b", "log_evidence": -1.0, "config_hash": "hash-phase1_b"})
    assert phase_format(tmp_path / "phase1_b.nc") == 0
    said = []
    st = _store(tmp_path, said=said)
    loaded = {n: st.load(n) for n in NAMES}
    assert [n for n, r in loaded.items() if r is not None] == ["phase1_a"]
    assert st.recomputed == ["phase1_b", "phase2", "phase3_a", "phase3_b"]
    (notice,) = [m for m in said if "phase1_b.nc" in m]
    assert "written before the ArviZ groups" in notice and "\n" not in notice


def test_npz_phase_files_are_reused_and_netcdf_holds_the_groups(tmp_path):
    import arviz as az

    st = _store(tmp_path, netcdf=False)
    st.save(PhaseResult("phase1_a", {"ka": np.arange(4.0)}, -2.0, 0.1, "converged", 1.0))
    again = _store(tmp_path, netcdf=False)
    assert np.array_equal(again.load("phase1_a").samples["ka"], np.arange(4.0)) and again.reused == ["phase1_a"]
    # a phase without a sampler (loaded, or from a caller) still gets the versions and its pointwise loglik
    path = write_phase(tmp_path / "x.nc", PhaseResult("x", {"m_ka": np.arange(6.0)}, -1.0, 0.1, "converged", 1.0),
                       np.zeros(6), {"phase": "x"}, pointwise={"population_likelihood": -np.ones((6, 2))})
    idata = az.from_netcdf(str(path))
    assert idata.log_likelihood["population_likelihood"].shape == (1, 6, 2)
    assert "arviz_version" in idata.posterior.attrs and "bubblecal_version" in idata.log_likelihood.attrs


def test_joint_file_chains_are_concatenated_on_read(tmp_path):
    from bubblecal.inference import build_inference_data

    by_chain = {"ka": np.arange(12.0).reshape(3, 4)}
    idata = build_inference_data(by_chain, sample_stats={"loglik": -np.arange(12.0).reshape(3, 4)})
    res = PhaseResult("joint_nuts", {"ka": by_chain["ka"].reshape(-1)}, float("nan"), float("nan"), "converged", 1.0)
    path = write_phase(tmp_path / "joint_nuts.nc", res, None, {"phase_result_chains": "all", "phase": "joint_nuts"},
                       idata=idata)
    back, loglik = read_phase(path)
    np.testing.assert_array_equal(back.samples["ka"], np.arange(12.0))
    np.testing.assert_array_equal(loglik, -np.arange(12.0))


@pytest.mark.parametrize(("writers", "started", "closing"), [(0, False, False), (2, False, False), (2, True, False),
                                                          (0, False, True), (2, True, True)],
                         ids=["thread", "processes", "processes started ahead", "thread closing soon",
                              "processes started ahead, closing soon"])
def test_background_writes_equal_the_direct_ones_and_land_in_the_manifest_after_flush(tmp_path, writers, started,
                                                                                     closing):
    """Also with the writers started (and warmed up) before the first phase, and told to end once the queued files
    are written before the flush: the same files, the same manifest."""
    import json
    import multiprocessing

    import xarray as xr

    direct, later = _store(tmp_path / "direct"), PhaseStore(tmp_path / "later", background=True, writers=writers)
    later.expected = direct.expected
    if started:
        later.start_writers()
        later.start_writers()  # a second call starts nothing more
        assert later._writer is not None and len(later._writer._warm) == writers
    for k, n in enumerate(NAMES):
        res = PhaseResult(n, {"ka": np.arange(5.0) + k, "kb": np.ones(5) * k}, -1.0 - k, 0.1, "converged", 1.0)
        direct.save(res)
        later.save(res)
    if closing:
        later.close_soon()
        later.close_soon()  # a second call changes nothing
    later.flush()
    assert later._writer is None
    assert multiprocessing.active_children() == []  # the writer processes ended with the flush
    manifest = json.loads((tmp_path / "later" / "manifest.json").read_text())
    assert sorted(manifest["phases"]) == sorted(NAMES)
    for n in NAMES:
        a, b = (xr.open_dataset(d / f"{n}.nc", group="posterior", engine="h5netcdf")
                for d in (tmp_path / "direct", tmp_path / "later"))
        assert a.equals(b) and a.attrs["log_evidence"] == b.attrs["log_evidence"]
        assert read_phase(tmp_path / "later" / f"{n}.nc")[0].log_evidence == direct.manifest["phases"][n][
            "log_evidence"]


def test_a_phase_saved_after_close_soon_is_refused_by_name(tmp_path):
    """Once the store was told that no more phases come, a late save names its file; the earlier one still lands."""
    st = PhaseStore(tmp_path, background=True, writers=0)
    st.expected = {n: f"hash-{n}" for n in NAMES}
    st.save(PhaseResult("phase1_a", {"ka": np.arange(3.0)}, -1.0, 0.1, "converged", 1.0))
    st.close_soon()
    with pytest.raises(RuntimeError, match=r"phase1_b\.nc: the phase writer was told that no more files come"):
        st.save(PhaseResult("phase1_b", {"ka": np.arange(3.0)}, -1.0, 0.1, "converged", 1.0))
    st.flush()
    assert read_phase(tmp_path / "phase1_a.nc")[0].name == "phase1_a"


def test_a_failed_background_write_is_raised_by_flush_after_the_others_landed(tmp_path):
    import json

    st = PhaseStore(tmp_path, background=True, writers=0)
    st.expected = {n: f"hash-{n}" for n in NAMES}
    st.save(PhaseResult("phase1_a", {"ka": np.arange(3.0)}, -1.0, 0.1, "converged", 1.0))
    (tmp_path / "phase1_b.nc").mkdir()  # a folder where the file must go: the atomic rename fails
    st.save(PhaseResult("phase1_b", {"ka": np.arange(3.0)}, -1.0, 0.1, "converged", 1.0))
    st.save(PhaseResult("phase2", {"m_ka": np.arange(3.0)}, -1.0, 0.1, "converged", 1.0))
    with pytest.raises(OSError):
        st.flush()
    phases = json.loads((tmp_path / "manifest.json").read_text())["phases"]
    assert sorted(phases) == ["phase1_a", "phase2"]  # the failed phase is not recorded as written
    assert read_phase(tmp_path / "phase2.nc")[0].name == "phase2"


def test_a_netcdf_write_that_finds_its_file_locked_is_retried_then_named(tmp_path, monkeypatch):
    from bubblecal.workflows.calibrate import phase_files

    monkeypatch.setattr(phase_files, "LOCK_WAIT_S", 0.0)
    calls = []

    def locked_twice():
        calls.append(1)
        if len(calls) <= 2:
            raise BlockingIOError(11, "unable to lock file")
        return tmp_path / "x.nc"

    assert phase_files._retry_locked(locked_twice, tmp_path / "x.nc") == tmp_path / "x.nc" and len(calls) == 3

    def always_locked():
        raise BlockingIOError(11, "unable to lock file")

    with pytest.raises(OSError, match="x.nc: the file stayed locked"):
        phase_files._retry_locked(always_locked, tmp_path / "x.nc")


@pytest.mark.parametrize(("cpus", "writers", "figures"), [(2, 0, 0), (7, 0, 0), (8, 2, 2), (16, 4, 5), (128, 4, 6)])
def test_helper_processes_follow_the_cores(cpus, writers, figures):
    """None below 8 cores; writers a quarter of the cores (at most 4), figure processes a third (at most 6)."""
    from bubblecal.workflows.calibrate import helper_processes

    assert helper_processes("writer", cpus) == writers and helper_processes("figure", cpus) == figures
    with pytest.raises(KeyError):
        helper_processes("reader", 16)
