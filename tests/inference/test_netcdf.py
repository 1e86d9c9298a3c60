"""write_netcdf against ArviZ's to_netcdf: the same datasets read back (values, dtypes, dims, coords, attributes,
encodings, group and variable order), the same HDF5 layout (dimension scales, chunks, filters), files no larger;
phase files read back as before; unsupported dtypes and attributes refused before anything is written."""

from __future__ import annotations

import warnings

import arviz as az
import numpy as np
import pytest
import xarray as xr

from bubblecal.inference import PhaseResult, build_inference_data, write_netcdf
from bubblecal.inference.idata import ExportInfo


def _idata(stage_coords: bool = True):
    """A TMCMC-like export: every group, a stage table, a bool statistic, text coordinates, scalars, units, attrs."""
    rng = np.random.default_rng(0)
    chains, draws, points, stages = 2, 60, 7, 4
    info = ExportInfo(dims={"y": ("points",), "loading": ("points",), "theta": ("param",)},
                      coords={"points": np.arange(points), "param": np.array(["ka", "kb", "d0"])},
                      units={"ka": "DPD energy", "theta": "1", "y": "nN", "loading": "um", "diameter_um": "um"},
                      constant_data={"loading": np.linspace(0.0, 1.0, points), "diameter_um": 3.2,
                                     "n_points": np.int64(points)},
                      attrs={"dataset": "toy", "kind": "indentation", "num_particles": 60, "target_cov": 0.6,
                             "stage_seconds": [1.5, 2.5], "num_list": [1, 2, 3], "names": ["a", "bc"],
                             "log_evidence_se": float("nan"), "flag": True, "text": "µm²", "empty": []})
    extra = {f"stage_{c}": (("chain", "stage"), rng.normal(size=(chains, stages))) for c in ("beta", "ess")}
    return build_inference_data(
        {"ka": rng.normal(size=(chains, draws)).astype(np.float32), "kb": rng.normal(size=(chains, draws)),
         "theta": rng.normal(size=(chains, draws, 3)).astype(np.float32)},
        sample_stats={"lp": rng.normal(size=(chains, draws)).astype(np.float32),
                      "loglik": rng.normal(size=(chains, draws)).astype(np.float32),
                      "diverging": rng.random((chains, draws)) < 0.1,
                      "num_steps": rng.integers(0, 9, (chains, draws))},
        log_likelihood={"y": rng.normal(size=(chains, draws, points)).astype(np.float32)},
        observed_data={"y": rng.normal(size=points).astype(np.float32)}, info=info, extra_stats=extra,
        attrs={"log_evidence": -3.5, "log_evidences": [-3.5, -3.6], "status": "converged"},
        stats_coords={"stage": np.arange(stages)} if stage_coords else None)


def _layout(path) -> list:
    """Every group, dataset and attribute of an HDF5 file in creation order, object references as paths."""
    import h5py

    out = []

    def walk(g):
        names = []
        g.id.links.iterate(lambda n: names.append(n.decode()), idx_type=h5py.h5.INDEX_CRT_ORDER)
        out.append((g.name, names, [(k, str(g.attrs.get_id(k).dtype), repr(g.attrs[k])) for k in g.attrs
                                    if k != "_NCProperties"]))
        for n in names:
            o = g[n]
            if isinstance(o, h5py.Group):
                walk(o)
                continue
            attrs = {}
            for k in o.attrs:
                v = o.attrs[k]
                if k == "DIMENSION_LIST":
                    v = [[o.file[r].name for r in row] for row in v]
                elif k == "REFERENCE_LIST":
                    v = sorted((o.file[r].name, int(d)) for r, d in v)
                attrs[k] = (str(o.attrs.get_id(k).dtype), o.attrs.get_id(k).shape, repr(v))
            out.append((o.name, o.shape, str(o.dtype), o.chunks, o.compression, o.compression_opts, o.shuffle,
                        repr(o.fillvalue), attrs, [k for k in o.attrs if k in attrs and not k.isupper()
                                                   and not k.startswith("_Netcdf4")]))
            if o.size:
                out.append((o.name, repr(o[()].tolist())))
    with h5py.File(path, "r") as f:
        walk(f)
    return out


def _assert_same_read_back(ours, theirs):
    a, b = az.from_netcdf(str(ours)), az.from_netcdf(str(theirs))
    assert a.groups() == b.groups()
    assert dict(a.attrs) == dict(b.attrs)
    for g in a.groups():
        x, y = getattr(a, g), getattr(b, g)
        assert x.identical(y), g
        assert list(x.variables) == list(y.variables) and list(x.attrs) == list(y.attrs), g
        for k in x.variables:
            enc = [{e: v for e, v in var.encoding.items() if e != "source"} for var in (x[k], y[k])]
            assert repr(enc[0]) == repr(enc[1]), (g, k)


@pytest.mark.parametrize("stage_coords", [True, False], ids=["stage coordinate", "stage without coordinate"])
def test_write_netcdf_reads_back_identical_to_arviz_with_its_layout_and_size(tmp_path, stage_coords):
    import h5netcdf

    idata = _idata(stage_coords)
    if not stage_coords:
        idata.attrs["note"] = "root attributes too"
    ours, theirs = tmp_path / "ours.nc", tmp_path / "theirs.nc"
    assert write_netcdf(idata, ours) == ours
    idata.to_netcdf(str(theirs))
    _assert_same_read_back(ours, theirs)
    assert _layout(ours) == _layout(theirs)
    assert ours.stat().st_size <= theirs.stat().st_size
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with h5netcdf.File(ours, "r") as f:
            assert list(f.groups) == idata.groups()
            for g in f.groups.values():
                assert all(v.dimensions is not None for v in g.variables.values()) and dict(g.attrs)
        for g in idata.groups():
            with xr.open_dataset(ours, group=g, engine="h5netcdf") as ds:
                assert ds.load().identical(getattr(idata, g))


def test_phase_files_read_back_as_the_arviz_written_ones(tmp_path):
    from bubblecal.workflows.calibrate import phase_format, read_phase, read_pointwise, write_phase

    idata = _idata()
    res = PhaseResult("phase3_toy", {k: idata.posterior[k].values[0] for k in ("ka", "kb")}, -3.5, float("nan"),
                      "converged", 1.25)
    ours = write_phase(tmp_path / "phase3_toy.nc", res, None, {"phase": "phase3_toy", "config_hash": "abc",
                                                               "ess": {"ka": 50.0}}, idata=idata)
    theirs = tmp_path / "arviz.nc"
    idata.to_netcdf(str(theirs))  # write_phase put the run's attributes on this InferenceData
    _assert_same_read_back(ours, theirs)
    (a, la), (b, lb) = read_phase(ours), read_phase(theirs)
    assert (a.name, a.status, a.seconds, a.log_evidence) == (b.name, b.status, b.seconds, b.log_evidence)
    assert np.isnan(a.log_evidence_se) and np.isnan(b.log_evidence_se)
    assert a.samples.keys() == b.samples.keys() == {"ka", "kb", "theta"}
    for k in a.samples:
        np.testing.assert_array_equal(a.samples[k], b.samples[k])
        assert a.samples[k].dtype == b.samples[k].dtype
    np.testing.assert_array_equal(la, lb)
    np.testing.assert_array_equal(la, idata.sample_stats["loglik"].values[0])
    pa, pb = read_pointwise(ours), read_pointwise(theirs)
    assert pa.keys() == pb.keys() == {"y"}
    np.testing.assert_array_equal(pa["y"], pb["y"])
    assert phase_format(ours) == phase_format(theirs) == 2


@pytest.mark.parametrize(("where", "value", "error", "match"), [
    ("posterior", np.array([[1 + 2j, 3j]]), TypeError, "group 'posterior', variable 'bad': dtype complex128"),
    ("constant_data", np.array(["2024-01-01"], dtype="datetime64[ns]"), TypeError,
     "group 'constant_data', variable 'bad': dtype datetime64"),
    ("attr", True, TypeError, "attribute 'bad' = True"),
    ("attr", {"a": 1}, TypeError, "attribute 'bad'"),
    ("varattr", "x", ValueError, "attribute name '_FillValue'"),
], ids=["complex", "datetime", "bool attribute", "dict attribute", "reserved attribute"])
def test_unsupported_dtypes_and_attributes_are_named_and_nothing_is_written(tmp_path, where, value, error, match):
    idata = build_inference_data({"ka": np.zeros((1, 3))})
    if where == "posterior":
        idata.posterior["bad"] = (("chain", "draw_2"), value)
    elif where == "constant_data":
        idata.add_groups({"constant_data": xr.Dataset({"bad": ("t", value)})})
    elif where == "attr":
        idata.posterior.attrs["bad"] = value
    else:
        idata.posterior["ka"].attrs["_FillValue"] = value
    with pytest.raises(error, match=match) as info:
        write_netcdf(idata, tmp_path / "x.nc")
    assert str(info.value).startswith(f"{tmp_path / 'x.nc'}: ")
    assert not (tmp_path / "x.nc").exists()
