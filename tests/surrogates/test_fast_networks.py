"""The fast networks over the diameter beside the accurate ones: roles in the manifest, lookup, agreement."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from bubblecal.surrogates import (
    NETWORK_ROLES,
    SurrogateFormatError,
    default_bundle_path,
    load_bundle,
    radius_of_diameter,
    write_bundle,
)
from bubblecal.surrogates.training import fast_choice

PATH = default_bundle_path()
pytestmark = pytest.mark.skipif(not (PATH / "manifest.json").is_file(), reason="no shipped bundle in this checkout")
#: Shipped networks over the diameter: (accurate file, fast file, fast architecture).
SHIPPED = {"compression": ("compression_1.5-8um.npz", "compression_1.5-8um_fast.npz", [64] * 3),
           "indentation": ("indentation_1.5-8um.npz", "indentation_1.5-8um_fast.npz", [64] * 4)}


@pytest.fixture(scope="module")
def bundle():
    return load_bundle(PATH)


@pytest.mark.parametrize("setup", sorted(SHIPPED))
def test_shipped_bundle_has_both_roles_and_get_binds_the_asked_one(bundle, setup):
    acc_file, fast_file, fast_hidden = SHIPPED[setup]
    assert bundle.networks(setup) == NETWORK_ROLES == ("accurate", "fast")
    assert bundle.over_diameter[setup].path.name == acc_file and bundle.fast[setup].path.name == fast_file
    acc, fast = bundle.over_diameter[setup], bundle.fast[setup]
    # same data, same split: the fast network is the smaller architecture of the same sweep
    assert fast.data_hash == acc.data_hash and fast.diameter_range_um == acc.diameter_range_um
    assert fast.metadata["training"]["holdout_seed"] == acc.metadata["training"]["holdout_seed"]
    for d in (1.7, 4.5, 7.9):  # diameters without a per-diameter network
        f = bundle.get(setup, d, network="fast")
        a = bundle.get(setup, d)  # default: the accurate network
        assert list(f.architecture["hidden"]) == fast_hidden and f.diameter_um == pytest.approx(d)
        assert a.architecture == acc.architecture and a.diameter_um == pytest.approx(d)
        assert bundle.get(setup, d, network="accurate").architecture == acc.architecture


@pytest.mark.parametrize("setup", sorted(SHIPPED))
def test_shipped_fast_network_is_the_sweeps_fast_choice(bundle, setup):
    """The fast file is what the library's rule picks from the accurate network's own sweep rows."""
    acc = bundle.over_diameter[setup]
    rows = acc.metadata["training"]["sweep"]
    best = next(i for i, r in enumerate(rows) if [r["width"]] * r["depth"] == list(acc.architecture["hidden"]))
    fast = fast_choice(rows, best)
    assert fast is not None and [rows[fast]["width"]] * rows[fast]["depth"] == SHIPPED[setup][2]


def test_fast_choice_rule():
    rows = [dict(n_params=100, holdout_median=0.010, holdout_p90=0.020),
            dict(n_params=50, holdout_median=0.014, holdout_p90=0.050),  # median close, tail 2.5x: no
            dict(n_params=60, holdout_median=0.014, holdout_p90=0.030),  # the smallest that stays close
            dict(n_params=10, holdout_median=0.020, holdout_p90=0.020),  # 2x the median: no
            dict(n_params=70, holdout_median=0.012, holdout_p90=0.020, ldo_median=0.016)]  # its LDO median: no
    assert fast_choice(rows, 0) == 2
    assert fast_choice(rows[:2], 0) is None  # nothing smaller qualifies
    assert fast_choice(rows, 3) is None  # only larger networks than the selection


def test_fast_keeps_the_per_diameter_preference(bundle):
    # a published diameter keeps its per-diameter network (no role) unless the network over the diameter is preferred
    per = bundle.get("compression", 2.1, network="fast")
    assert not per.over_diameter and per.diameter_um == pytest.approx(2.1)
    wide = bundle.get("compression", 2.1, prefer="over-diameter", network="fast")
    assert wide.over_diameter and list(wide.architecture["hidden"]) == SHIPPED["compression"][2]


@pytest.mark.parametrize("bad", ["Fast", "slow", "", None])
def test_unknown_role_is_a_value_error_naming_the_allowed_ones(bundle, bad):
    with pytest.raises(ValueError, match=r"network must be one of 'accurate', 'fast', got"):
        bundle.get("compression", 4.5, network=bad)


def _copy(tmp_path, *names):
    for n in names:
        shutil.copyfile(PATH / n, tmp_path / n)
    return [tmp_path / n for n in names]


def test_manifest_round_trip_and_fallback_without_a_fast_network(tmp_path):
    acc_c, fast_c = _copy(tmp_path, "compression_1.5-8um.npz", "compression_1.5-8um_fast.npz")
    out = tmp_path / "b"
    manifest = json.loads(write_bundle(out, [acc_c], fast_files=[fast_c]).read_text())
    assert [(e["file"], e["network"]) for e in manifest["surrogates"]] == [
        ("compression_1.5-8um.npz", "accurate"), ("compression_1.5-8um_fast.npz", "fast")]
    b = load_bundle(out)
    assert b.networks("compression") == ("accurate", "fast") and b.networks("indentation") == ()
    assert list(b.get("compression", 5.0, network="fast").architecture["hidden"]) == SHIPPED["compression"][2]
    # rewritten from the loaded bundle: the same manifest entries
    again = json.loads(write_bundle(tmp_path / "c", [b.over_diameter["compression"].path],
                                    fast_files=[b.fast["compression"].path]).read_text())
    assert again["surrogates"] == manifest["surrogates"]
    # a bundle without a fast network answers 'fast' with the accurate one (no error)
    only = load_bundle(write_bundle(tmp_path / "d", [acc_c]).parent)
    assert only.networks("compression") == ("accurate",) and not only.fast
    sur = only.get("compression", 5.0, network="fast")
    accurate = load_bundle(PATH).over_diameter["compression"].architecture["hidden"]
    assert list(sur.architecture["hidden"]) == list(accurate) and sur.diameter_um == pytest.approx(5.0)
    # a manifest without 'network' fields (written before the roles) reads as accurate
    m = json.loads((out / "manifest.json").read_text())
    m["surrogates"] = [{k: v for k, v in e.items() if k != "network"} for e in m["surrogates"][:1]]
    (out / "manifest.json").write_text(json.dumps(m))
    assert load_bundle(out).networks("compression") == ("accurate",)


def test_manifest_roles_are_validated(tmp_path):
    acc_c, fast_c, per = _copy(tmp_path, "compression_1.5-8um.npz", "compression_1.5-8um_fast.npz",
                               "compression_3um.npz")
    out = tmp_path / "b"
    write_bundle(out, [acc_c, per], fast_files=[fast_c])
    # a per-diameter file of the same protocol is no second network over the diameter, in either order
    assert len(json.loads(write_bundle(tmp_path / "g", [per, acc_c]).read_text())["surrogates"]) == 2
    mpath = out / "manifest.json"
    good = json.loads(mpath.read_text())

    def with_entries(edit):
        m = json.loads(json.dumps(good))
        edit(m["surrogates"])
        mpath.write_text(json.dumps(m))

    with_entries(lambda es: es[2].update(network="turbo"))
    with pytest.raises(SurrogateFormatError, match=r"surrogates\[2\] \(compression_1.5-8um_fast.npz\) field "
                                                   r"'network' is 'turbo'; allowed: 'accurate', 'fast'"):
        load_bundle(out)
    with_entries(lambda es: es[1].update(network="fast"))  # the per-diameter entry
    with pytest.raises(SurrogateFormatError, match=r"surrogates\[1\] \(compression_3um.npz\) .* only networks over "
                                                   r"the diameter"):
        load_bundle(out)
    with_entries(lambda es: es[0].update(network="fast"))  # two fast compression networks
    with pytest.raises(SurrogateFormatError, match=r"surrogates\[2\] .* a second 'fast' compression network"):
        load_bundle(out)
    # write_bundle refuses the same before writing anything
    with pytest.raises(SurrogateFormatError, match="must be a network over the diameter"):
        write_bundle(tmp_path / "e", [acc_c], fast_files=[per])
    with pytest.raises(SurrogateFormatError, match="a second 'accurate' compression network"):
        write_bundle(tmp_path / "f", [acc_c, fast_c])
    assert not (tmp_path / "e" / "manifest.json").exists() and not (tmp_path / "f" / "manifest.json").exists()


@pytest.mark.parametrize("setup", sorted(SHIPPED))
def test_fast_network_agrees_with_the_accurate_one_inside_the_box(bundle, setup):
    acc, fast = bundle.over_diameter[setup], bundle.fast[setup]
    # each network's held-out median error vs the simulations bounds their median disagreement (triangle
    # inequality per curve, loosely per point): allow 1.5x their sum, and never more than the 2 % noise floor
    tol = min(1.5 * (acc.holdout_score + fast.holdout_score), 0.02)
    rng = np.random.default_rng(7)
    n = 400
    lo = np.array([acc.param_ranges[k][0] for k in acc.param_names])
    hi = np.array([acc.param_ranges[k][1] for k in acc.param_names])
    params = lo + rng.random((n, 6)) * (hi - lo)
    d = rng.uniform(*acc.diameter_range_um, n)
    size = 2 * np.asarray(radius_of_diameter(d)) if setup == "compression" else 1.0
    x = rng.uniform(0.2, 1.0, n) * acc.loading_range_per_size[1] * size  # away from the zero response at x = 0
    assert np.all(np.asarray(acc.in_training_box(params, x, diameter_um=d)))
    y_acc, y_fast = np.asarray(acc(params, x, d)), np.asarray(fast(params, x, d))
    rel = np.abs(y_fast - y_acc) / np.abs(y_acc)
    assert np.median(rel) < tol, (setup, float(np.median(rel)), tol)


@pytest.mark.parametrize("setup", sorted(SHIPPED))
def test_check_domain_on_the_host_agrees_with_the_jit_friendly_mask(bundle, setup):
    import warnings

    sur = bundle.over_diameter[setup]
    rng = np.random.default_rng(11)
    n = 600
    lo = np.array([sur.param_ranges[k][0] for k in sur.param_names])
    hi = np.array([sur.param_ranges[k][1] for k in sur.param_names])
    width = hi - lo
    params = lo - 0.1 * width + rng.random((n, 6)) * 1.2 * width  # about half the points outside somewhere
    d = rng.uniform(sur.diameter_range_um[0] - 0.5, sur.diameter_range_um[1] + 0.5, n)
    size = 2 * np.asarray(radius_of_diameter(d)) if setup == "compression" else 1.0
    x = rng.uniform(-0.1, 1.2, n) * sur.loading_range_per_size[1] * size
    jit_mask = np.asarray(sur.in_training_box(params, x, diameter_um=d))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        host_mask = sur.check_domain(params, x, diameter_um=d)
    assert 0.2 < jit_mask.mean() < 0.8 and np.array_equal(host_mask, jit_mask)
