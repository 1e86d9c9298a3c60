"""Surrogate files (.npz, plain weights) and bundles (a directory + manifest.json); JAX evaluation.

Nothing here imports torch or onnx: calibration code loads surrogates through :func:`load` and
:func:`load_bundle` only.

Surrogate file format (``format = "bubblecal-mlp-surrogate"``, ``format_version = 1``)
------------------------------------------------------------------------------------
One ``.npz`` (``numpy.savez``, no pickles) per (setup, diameter) with the keys

=================  ==============================================================================
``format``         0-d str, ``"bubblecal-mlp-surrogate"``
``format_version`` 0-d int, 1
``n_layers``       0-d int L (number of affine layers = hidden layers + 1)
``W_0..W_{L-1}``   float32 (fan_in, fan_out) weight matrices (input side first)
``b_0..b_{L-1}``   float32 (fan_out,) biases
``in_mean``        float64 (7,) mean of the raw inputs (ka, kb, b1, b2, a3, a4, x) in training
``in_std``         float64 (7,) their standard deviation (all > 0)
``out_mean``       float64 (1,) mean of the raw target
``out_std``        float64 (1,) its standard deviation
``metadata``       0-d str: JSON object, see below
=================  ==============================================================================

``metadata`` keys (all required): ``setup`` ('compression'|'indentation'), ``diameter_um``
(= 2 x 0.25 um x radius_dpd of the data; optional ``nominal_diameter_um``: the name used, e.g. 3.2
for data of radius 6.38), ``radius_dpd``, ``param_names`` (["ka","kb","b1","b2","a3","a4"]), ``input_names`` (param names +
the loading coordinate name), ``input_units``, ``output_name``, ``output_units``, ``param_ranges``
({name: [lo, hi]} seen in training), ``x_range`` ([lo, hi]), ``holdout_score`` (median over
held-out curves of ||y_hat - y||_2/||y||_2), ``holdout_metric``, ``data_hash`` (sha256 of the
filtered training arrays, :func:`bubblecal.surrogates.dataset.TrainingSet.data_hash`),
``architecture`` ({"hidden": [widths], "activation": "tanh"}), ``training`` (settings, seed),
``code_version``, ``created_utc``, ``source`` (where the data came from). Optional provenance
written by :mod:`bubblecal.surrogates.export`: ``n_curves_train``, ``n_points_train``,
``n_prefix_curves_train`` / ``n_prefix_points_train`` (failure-truncated curves kept by
``filter_curves(keep_failed_prefix=True)`` and their points), ``training_data``, ``filter``.

Inputs and outputs are DPD units: compression x = imposed displacement [DPD length], y = force
[DPD force]; indentation x = applied force [DPD force], y = displacement [DPD length].

Bundle format (``manifest.json``, ``format = "bubblecal-surrogate-bundle"``, version 1)
----------------------------------------------------------------------------------------
A directory holding the .npz files, acoustic JSON files (:mod:`bubblecal.surrogates.acoustic`)
and ``manifest.json``::

    {"format": "bubblecal-surrogate-bundle", "format_version": 1, "created_utc": "...",
     "surrogates": [{"file": "compression_2.1um.npz", "setup": "compression",
                     "diameter_um": 2.1, "data_hash": "...", "holdout_score": 0.004}, ...],
     "acoustic": [{"file": "acoustic_definity.json", "name": "definity"}, ...],
     "notes": "free text"}
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import shutil
import warnings
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from bubblecal.data import LOADING_PROTOCOLS, SHELL_PARAMETERS, atomic_write, code_version
from bubblecal.surrogates.mlp import mlp_forward, surrogate_inputs

__all__ = [
    "FORMAT", "FORMAT_VERSION", "BUNDLE_FORMAT", "BUNDLE_FORMAT_VERSION",
    "SurrogateFormatError", "OutOfDomainError", "SurrogateDomainWarning", "Surrogate", "Bundle",
    "save_surrogate", "load", "load_bundle", "write_bundle", "default_bundle_path", "NoDefaultBundleError",
]

FORMAT = "bubblecal-mlp-surrogate"
FORMAT_VERSION = 1
BUNDLE_FORMAT = "bubblecal-surrogate-bundle"
BUNDLE_FORMAT_VERSION = 1

REQUIRED_METADATA = (
    "setup", "diameter_um", "radius_dpd", "param_names", "input_names", "input_units", "output_name",
    "output_units", "param_ranges", "x_range", "holdout_score", "holdout_metric", "data_hash",
    "architecture", "training", "code_version", "created_utc", "source",
)


class SurrogateFormatError(ValueError):
    """A surrogate or bundle file is malformed; the message names the file and the field."""


class OutOfDomainError(ValueError):
    """Evaluation requested outside the box of parameters / loading coordinates seen in training."""


class SurrogateDomainWarning(UserWarning):
    """Evaluation outside the training box (see :meth:`Surrogate.check_domain`)."""


def _utc_now() -> str:
    return _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def _atomic_write_bytes(path: Path, writer) -> None:
    """Atomic write (:func:`bubblecal.data.files.atomic_write`) through a binary handle ``writer(fh)``."""

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            writer(fh)

    atomic_write(path, write)


# --------------------------------------------------------------------------------------------
# Surrogate
# --------------------------------------------------------------------------------------------
class Surrogate:
    """A loaded MLP surrogate: callable ``(params[..., 6], x[...]) -> y[...]``, pure JAX.

    ``params`` holds ``(ka, kb, b1, b2, a3, a4)`` in the last axis; its leading shape broadcasts
    against ``x``'s shape (e.g. ``params[:, None, :]`` with ``x[None, :]`` gives a (n_sets,
    n_points) grid). The call is jit/vmap/grad-ready (weights are constants of the trace).

    Evaluation outside the training box is never silent: use :meth:`in_training_box` (a mask,
    jit-friendly), :meth:`check_domain` (warns or raises, host side) or :meth:`evaluate` (checks,
    then evaluates). The plain call does not check, so that it can run under ``jit``.
    """

    def __init__(self, weights, biases, in_mean, in_std, out_mean, out_std, metadata: Mapping,
                 path: str | Path | None = None):
        self.weights = tuple(jnp.asarray(w) for w in weights)
        self.biases = tuple(jnp.asarray(b) for b in biases)
        self.in_mean = jnp.asarray(in_mean, dtype=jnp.float32)
        self.in_std = jnp.asarray(in_std, dtype=jnp.float32)
        self.out_mean = jnp.asarray(out_mean, dtype=jnp.float32)
        self.out_std = jnp.asarray(out_std, dtype=jnp.float32)
        self.metadata = dict(metadata)
        self.path = None if path is None else Path(path)
        md = self.metadata
        self.setup: str = md["setup"]
        self.diameter_um: float = float(md["diameter_um"])
        self.nominal_diameter_um: float = float(md.get("nominal_diameter_um", self.diameter_um))
        self.radius_dpd: float = float(md["radius_dpd"])
        self.param_names: tuple[str, ...] = tuple(md["param_names"])
        self.input_names: tuple[str, ...] = tuple(md["input_names"])
        self.param_ranges: dict[str, tuple[float, float]] = {
            k: (float(v[0]), float(v[1])) for k, v in md["param_ranges"].items()}
        self.x_range: tuple[float, float] = (float(md["x_range"][0]), float(md["x_range"][1]))
        self.holdout_score: float = float(md["holdout_score"])
        self.data_hash: str = str(md["data_hash"])
        self.architecture: dict = dict(md["architecture"])
        self._lo = np.array([self.param_ranges[k][0] for k in self.param_names])
        self._hi = np.array([self.param_ranges[k][1] for k in self.param_names])

    # -- evaluation ----------------------------------------------------------------------------
    def __call__(self, params, x):
        u = surrogate_inputs(params, x, self.param_names)
        y = mlp_forward(self.weights, self.biases, self.in_mean, self.in_std, self.out_mean,
                        self.out_std, u)
        return y[..., 0]

    def in_training_box(self, params, x, rtol: float = 1e-6):
        """Boolean mask (shape of the broadcast output) of points inside the training box.

        A point is inside when every parameter lies in ``param_ranges`` and x in ``x_range``,
        each widened by ``rtol`` times the range width (round-off allowance). jit-friendly.
        """
        params = jnp.asarray(params)
        x = jnp.asarray(x)
        width = self._hi - self._lo
        lo = jnp.asarray(self._lo - rtol * width)
        hi = jnp.asarray(self._hi + rtol * width)
        p_ok = jnp.all((params >= lo) & (params <= hi), axis=-1)
        xw = self.x_range[1] - self.x_range[0]
        x_ok = (x >= self.x_range[0] - rtol * xw) & (x <= self.x_range[1] + rtol * xw)
        shape = jnp.broadcast_shapes(p_ok.shape, x_ok.shape)
        return jnp.broadcast_to(p_ok, shape) & jnp.broadcast_to(x_ok, shape)

    def check_domain(self, params, x, action: str = "warn", rtol: float = 1e-6) -> np.ndarray:
        """Check the training box on the host; warn (``action='warn'``) or raise (``'raise'``).

        Returns the numpy mask of inside points. The message names every offending input with
        the number of points outside and the extremes requested versus the training range.
        """
        if action not in ("warn", "raise"):
            raise ValueError(f"action must be 'warn' or 'raise', got {action!r}")
        mask = np.asarray(self.in_training_box(params, x, rtol=rtol))
        if mask.all():
            return mask
        p = np.asarray(params, dtype=float).reshape(-1, len(self.param_names))
        xv = np.asarray(x, dtype=float).ravel()
        parts = []
        for j, name in enumerate(self.param_names):
            lo, hi = self.param_ranges[name]
            w = (hi - lo) * rtol
            bad = (p[:, j] < lo - w) | (p[:, j] > hi + w)
            if bad.any():
                parts.append(f"{name}: {int(bad.sum())} of {len(bad)} parameter sets outside "
                             f"[{lo:.6g}, {hi:.6g}] (requested {p[:, j].min():.6g}..{p[:, j].max():.6g})")
        lo, hi = self.x_range
        w = (hi - lo) * rtol
        bad = (xv < lo - w) | (xv > hi + w)
        if bad.any():
            xname = self.input_names[-1]
            parts.append(f"{xname}: {int(bad.sum())} of {len(bad)} points outside [{lo:.6g}, {hi:.6g}] "
                         f"(requested {xv.min():.6g}..{xv.max():.6g})")
        where = f" ({self.path})" if self.path else ""
        msg = (f"{self.setup} {self.diameter_um:g} um surrogate{where}: {int((~mask).sum())} of "
               f"{mask.size} evaluations outside the training box; " + "; ".join(parts))
        if action == "raise":
            raise OutOfDomainError(msg)
        warnings.warn(msg, SurrogateDomainWarning, stacklevel=2)
        return mask

    def evaluate(self, params, x, action: str = "warn"):
        """Check the domain (warn/raise) and evaluate; returns ``(y, inside_mask)``."""
        mask = self.check_domain(params, x, action=action)
        return self(params, x), mask

    def __repr__(self) -> str:
        return (f"Surrogate({self.setup}, {self.diameter_um:g} um, hidden={self.architecture.get('hidden')}, "
                f"holdout={self.holdout_score:.4g}, data_hash={self.data_hash[:12]})")


# --------------------------------------------------------------------------------------------
# save / load
# --------------------------------------------------------------------------------------------
def save_surrogate(path: str | Path, weights: Iterable, biases: Iterable, in_mean, in_std, out_mean,
                   out_std, metadata: Mapping) -> Path:
    """Write a surrogate ``.npz`` atomically; validates the metadata keys. Returns the path."""
    path = Path(path)
    md = dict(metadata)
    md.setdefault("code_version", code_version())
    md.setdefault("created_utc", _utc_now())
    missing = [k for k in REQUIRED_METADATA if k not in md]
    if missing:
        raise SurrogateFormatError(f"{path}: metadata lacks field(s) {', '.join(missing)}")
    weights = [np.asarray(w, dtype=np.float32) for w in weights]
    biases = [np.asarray(b, dtype=np.float32) for b in biases]
    arrays: dict[str, np.ndarray] = {
        "format": np.array(FORMAT), "format_version": np.array(FORMAT_VERSION),
        "n_layers": np.array(len(weights)),
        "in_mean": np.asarray(in_mean, dtype=np.float64), "in_std": np.asarray(in_std, dtype=np.float64),
        "out_mean": np.atleast_1d(np.asarray(out_mean, dtype=np.float64)),
        "out_std": np.atleast_1d(np.asarray(out_std, dtype=np.float64)),
        "metadata": np.array(json.dumps(md, sort_keys=True, default=_json_default)),
    }
    for i, (w, b) in enumerate(zip(weights, biases, strict=True)):
        arrays[f"W_{i}"] = w
        arrays[f"b_{i}"] = b
    _check_arrays(path, arrays, md)
    _atomic_write_bytes(path, lambda fh: np.savez(fh, **arrays))
    return path


def _json_default(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def _check_arrays(path: Path, arrays: Mapping[str, np.ndarray], md: Mapping) -> None:
    n_layers = int(arrays["n_layers"])
    if n_layers < 1:
        raise SurrogateFormatError(f"{path}: field 'n_layers' must be >= 1, got {n_layers}")
    n_in = len(md["input_names"])
    for key in ("in_mean", "in_std"):
        if arrays[key].shape != (n_in,):
            raise SurrogateFormatError(f"{path}: field '{key}' has shape {arrays[key].shape}, expected ({n_in},)")
        if not np.all(np.isfinite(arrays[key])):
            raise SurrogateFormatError(f"{path}: field '{key}' holds non-finite values")
    for key in ("in_std", "out_std"):
        if np.any(arrays[key] <= 0):
            raise SurrogateFormatError(f"{path}: field '{key}' must be > 0 (a zero-variance input "
                                       "cannot be standardised)")
    fan_in = n_in
    for i in range(n_layers):
        w, b = arrays[f"W_{i}"], arrays[f"b_{i}"]
        if w.ndim != 2 or w.shape[0] != fan_in or b.shape != (w.shape[1],):
            raise SurrogateFormatError(f"{path}: field 'W_{i}'/'b_{i}' shapes {w.shape}/{b.shape} do not "
                                       f"chain from fan_in {fan_in}")
        if not (np.all(np.isfinite(w)) and np.all(np.isfinite(b))):
            raise SurrogateFormatError(f"{path}: field 'W_{i}'/'b_{i}' holds non-finite values")
        fan_in = w.shape[1]
    if fan_in != arrays["out_mean"].shape[0]:
        raise SurrogateFormatError(f"{path}: last layer width {fan_in} != out_mean length "
                                   f"{arrays['out_mean'].shape[0]}")
    if md["setup"] not in LOADING_PROTOCOLS:
        raise SurrogateFormatError(f"{path}: metadata field 'setup' must be one of {LOADING_PROTOCOLS}, got {md['setup']!r}")
    if tuple(md["param_names"]) != SHELL_PARAMETERS:
        raise SurrogateFormatError(f"{path}: metadata field 'param_names' must be {list(SHELL_PARAMETERS)}, "
                                   f"got {md['param_names']}")
    for name in SHELL_PARAMETERS:
        if name not in md["param_ranges"]:
            raise SurrogateFormatError(f"{path}: metadata field 'param_ranges' lacks '{name}'")


def load(path: str | Path) -> Surrogate:
    """Load a surrogate ``.npz``; errors name the file and the missing/invalid field."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"surrogate file not found: {path}")
    try:
        npz = np.load(path, allow_pickle=False)
    except Exception as exc:
        raise SurrogateFormatError(f"{path}: not a readable .npz file ({exc})") from exc
    with npz:
        keys = set(npz.files)
        for key in ("format", "format_version"):
            if key not in keys:
                raise SurrogateFormatError(f"{path}: missing field '{key}' (not a bubblecal surrogate file)")
        fmt = str(npz["format"])
        if fmt != FORMAT:
            raise SurrogateFormatError(f"{path}: field 'format' is {fmt!r}, expected {FORMAT!r}")
        version = int(npz["format_version"])
        if version != FORMAT_VERSION:
            raise SurrogateFormatError(f"{path}: field 'format_version' is {version}, this code reads "
                                       f"version {FORMAT_VERSION}")
        for key in ("n_layers", "in_mean", "in_std", "out_mean", "out_std", "metadata"):
            if key not in keys:
                raise SurrogateFormatError(f"{path}: missing field '{key}'")
        n_layers = int(npz["n_layers"])
        for i in range(n_layers):
            for key in (f"W_{i}", f"b_{i}"):
                if key not in keys:
                    raise SurrogateFormatError(f"{path}: missing field '{key}' (n_layers = {n_layers})")
        arrays = {k: npz[k] for k in keys}
    try:
        md = json.loads(str(arrays["metadata"]))
    except json.JSONDecodeError as exc:
        raise SurrogateFormatError(f"{path}: field 'metadata' is not valid JSON ({exc})") from exc
    missing = [k for k in REQUIRED_METADATA if k not in md]
    if missing:
        raise SurrogateFormatError(f"{path}: field 'metadata' lacks key(s) {', '.join(missing)}")
    _check_arrays(path, arrays, md)
    weights = [arrays[f"W_{i}"] for i in range(n_layers)]
    biases = [arrays[f"b_{i}"] for i in range(n_layers)]
    return Surrogate(weights, biases, arrays["in_mean"], arrays["in_std"], arrays["out_mean"],
                     arrays["out_std"], md, path=path)


# --------------------------------------------------------------------------------------------
# bundles
# --------------------------------------------------------------------------------------------
@dataclass
class Bundle:
    """A loaded bundle: mechanical surrogates keyed by (setup, diameter_um) and acoustic surrogates."""

    path: Path
    manifest: dict
    surrogates: dict[tuple[str, float], Surrogate] = field(default_factory=dict)
    acoustic: dict[str, object] = field(default_factory=dict)

    def get(self, setup: str, diameter_um: float, atol: float = 0.025) -> Surrogate:
        """The surrogate for ``setup`` nearest ``diameter_um``, within ``atol`` um of its data diameter
        or its nominal one (the "3.2 um" SonoVue set has data diameter 3.19 um)."""
        best, best_gap = None, math.inf
        for (s, d), sur in self.surrogates.items():
            if s != setup:
                continue
            nominal = float(sur.metadata.get("nominal_diameter_um", d))
            gap = min(abs(d - float(diameter_um)), abs(nominal - float(diameter_um)))
            if gap < best_gap:
                best, best_gap = sur, gap
        if best is not None and best_gap <= atol:
            return best
        have = ", ".join(f"{s} {d:g} um" for s, d in sorted(self.surrogates))
        raise KeyError(f"bundle {self.path} has no {setup} surrogate at {diameter_um:g} um (has: {have or 'none'})")

    def keys(self):
        return sorted(self.surrogates)


def read_versioned_json(path: Path, fmt: str, version: int, error: type[Exception], what: str) -> dict:
    """Read a JSON file whose 'format'/'format_version' fields must equal ``fmt``/``version``."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{what} not found: {path}")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise error(f"{path}: not valid JSON ({exc})") from exc
    if data.get("format") != fmt:
        raise error(f"{path}: field 'format' is {data.get('format')!r}, expected {fmt!r}")
    if data.get("format_version") != version:
        raise error(f"{path}: field 'format_version' is {data.get('format_version')!r}, this code reads version {version}")
    return data


def load_bundle(path: str | Path) -> Bundle:
    """Load a bundle directory (``manifest.json`` + files); checks each file's data hash."""
    from bubblecal.surrogates.acoustic import AcousticSurrogate

    path = Path(path)
    mpath = path / "manifest.json"
    manifest = read_versioned_json(mpath, BUNDLE_FORMAT, BUNDLE_FORMAT_VERSION, SurrogateFormatError, "bundle manifest")
    bundle = Bundle(path=path, manifest=manifest)
    for i, entry in enumerate(manifest.get("surrogates", [])):
        for key in ("file", "setup", "diameter_um", "data_hash"):
            if key not in entry:
                raise SurrogateFormatError(f"{mpath}: surrogates[{i}] lacks field '{key}'")
        sur = load(path / entry["file"])
        if sur.data_hash != entry["data_hash"]:
            raise SurrogateFormatError(f"{mpath}: surrogates[{i}] field 'data_hash' {entry['data_hash'][:12]}... "
                                       f"does not match {entry['file']} ({sur.data_hash[:12]}...)")
        if sur.setup != entry["setup"] or not math.isclose(sur.diameter_um, float(entry["diameter_um"]),
                                                           abs_tol=1e-9):
            raise SurrogateFormatError(f"{mpath}: surrogates[{i}] setup/diameter_um disagree with {entry['file']}")
        key = (sur.setup, sur.diameter_um)
        if key in bundle.surrogates:
            raise SurrogateFormatError(f"{mpath}: two surrogates for {sur.setup} {sur.diameter_um:g} um")
        bundle.surrogates[key] = sur
    for i, entry in enumerate(manifest.get("acoustic", [])):
        for key in ("file", "name"):
            if key not in entry:
                raise SurrogateFormatError(f"{mpath}: acoustic[{i}] lacks field '{key}'")
        bundle.acoustic[entry["name"]] = AcousticSurrogate.load(path / entry["file"])
    return bundle


def write_bundle(path: str | Path, surrogate_files: Iterable[str | Path] = (),
                 acoustic_files: Mapping[str, str | Path] | None = None, notes: str = "") -> Path:
    """Copy surrogate ``.npz`` files and acoustic JSON files into ``path`` and write manifest.json.

    ``acoustic_files`` maps a name (e.g. ``'definity'``) to a JSON file. Files already inside
    ``path`` are not copied. Returns the manifest path.
    """
    from bubblecal.surrogates.acoustic import AcousticSurrogate

    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    entries = []
    for f in surrogate_files:
        f = Path(f)
        sur = load(f)
        dest = path / f.name
        if f.resolve() != dest.resolve():
            shutil.copyfile(f, dest)
        entries.append({"file": f.name, "setup": sur.setup, "diameter_um": sur.diameter_um,
                        "data_hash": sur.data_hash, "holdout_score": sur.holdout_score,
                        "architecture": sur.architecture})
    acoustic_entries = []
    for name, f in (acoustic_files or {}).items():
        f = Path(f)
        AcousticSurrogate.load(f)  # validate
        dest = path / f.name
        if f.resolve() != dest.resolve():
            shutil.copyfile(f, dest)
        acoustic_entries.append({"file": f.name, "name": name})
    manifest = {"format": BUNDLE_FORMAT, "format_version": BUNDLE_FORMAT_VERSION, "created_utc": _utc_now(),
                "code_version": code_version(), "surrogates": entries, "acoustic": acoustic_entries,
                "notes": notes}
    mpath = path / "manifest.json"
    _atomic_write_bytes(mpath, lambda fh: fh.write(json.dumps(manifest, indent=2).encode()))
    return mpath


class NoDefaultBundleError(FileNotFoundError):
    """The shipped surrogate bundle (package data ``bubblecal/surrogates/bundle/``) is not installed."""


def default_bundle_path(must_exist: bool = False) -> Path:
    """Directory of the shipped surrogate bundle (package data ``bubblecal/surrogates/bundle/``).

    With ``must_exist=True`` raise :class:`NoDefaultBundleError` (a clear message pointing at
    ``--bundle DIR`` and ``bubblecal surrogates synthetic-bundle DIR``) when it holds no ``manifest.json``.
    """
    path = Path(__file__).resolve().parent / "bundle"
    if must_exist and not (path / "manifest.json").is_file():
        raise NoDefaultBundleError(
            f"no shipped surrogate bundle found at {path}; pass --bundle DIR (e.g. a development bundle written "
            "by `bubblecal surrogates synthetic-bundle DIR`, SYNTHETIC closed-form laws, not DPD)")
    return path
