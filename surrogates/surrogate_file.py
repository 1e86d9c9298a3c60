"""The surrogate file: one ``.npz`` of plain weights per (loading protocol, diameter); save, load, validate.

Format ``bubblecal-mlp-surrogate``, version 1 (docs/data-formats.md). One ``.npz`` (``numpy.savez``, no
pickles) with the keys

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

``metadata`` keys (all required, :data:`REQUIRED_METADATA`): ``setup`` ('compression'|'indentation'),
``diameter_um`` (= 2 x 0.25 um x radius_dpd of the data; optional ``nominal_diameter_um``: the name used,
e.g. 3.2 for data of radius 6.38), ``radius_dpd``, ``param_names`` (["ka","kb","b1","b2","a3","a4"]),
``input_names`` (param names + the loading coordinate name), ``input_units``, ``output_name``,
``output_units`` (:mod:`bubblecal.surrogates.axes`), ``param_ranges`` ({name: [lo, hi]} seen in training),
``x_range`` ([lo, hi]), ``holdout_score`` (median over held-out curves of ||y_hat - y||_2/||y||_2),
``holdout_metric``, ``data_hash`` (sha256 of the filtered training arrays,
:meth:`bubblecal.surrogates.training.TrainingSet.data_hash`), ``architecture`` ({"hidden": [widths],
"activation": "tanh"}), ``training`` (settings, seed), ``code_version``, ``created_utc``, ``source`` (where the
data came from). Optional provenance written by :func:`bubblecal.surrogates.training.export_npz`:
``n_curves_train``, ``n_points_train``, ``n_prefix_curves_train`` / ``n_prefix_points_train``
(failure-truncated curves kept by ``filter_curves(keep_failed_prefix=True)`` and their points),
``training_data``, ``filter``.

Version 2 is a network over the diameter (:mod:`bubblecal.surrogates.features`): the same arrays with 8 inputs
(the 7 above and ``diameter_um`` [um]); its metadata holds ``inputs`` = ``"diameter"``, ``response_scale``
(``"ka * radius_dpd"`` for compression, ``"radius_dpd"`` for indentation: the network predicts the response over
it), ``diameter_range_um`` and ``loading_range_per_size`` ([lo, hi] of the displacement over the diameter for
compression, of the force for indentation) instead of ``diameter_um`` and ``radius_dpd``, and optionally
``ldo_score`` / ``ldo_bands_um`` (the leave-diameters-out median and its bands).

Version 3 is a network (of either input kind) that takes some moduli as natural logarithms: its metadata holds a
non-empty ``log_inputs`` (names from ``["ka", "kb"]``, in that order; their ``param_ranges`` start above 0), and
``in_mean`` / ``in_std`` standardise the logged columns.  Code that reads only versions 1 and 2 refuses such a
file instead of feeding it linear moduli.

Inputs and outputs are DPD units: compression x = imposed displacement [DPD length], y = force [DPD force];
indentation x = applied force [DPD force], y = displacement [DPD length].
"""

from __future__ import annotations

import json
import zipfile
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from bubblecal.data import LOADING_PROTOCOLS, SHELL_PARAMETERS, code_version
from bubblecal.surrogates.features import INPUT_KINDS, LOG_INPUT_CHOICES, RESPONSE_SCALES, check_log_inputs
from bubblecal.surrogates.fileio import atomic_write_bytes, utc_now
from bubblecal.surrogates.surrogate import Surrogate

__all__ = ["FORMAT", "FORMAT_VERSION", "FORMAT_VERSION_DIAMETER", "FORMAT_VERSION_LOG_INPUTS", "REQUIRED_METADATA",
           "DIAMETER_METADATA", "SurrogateFormatError", "save_surrogate", "load"]

#: ``format`` of a surrogate file.
FORMAT = "bubblecal-mlp-surrogate"
#: ``format_version`` of a per-diameter network (read and written).
FORMAT_VERSION = 1
#: ``format_version`` of a network over the diameter (read and written).
FORMAT_VERSION_DIAMETER = 2
#: ``format_version`` of a network that takes logged moduli (metadata ``log_inputs``; read and written).
FORMAT_VERSION_LOG_INPUTS = 3

#: Metadata keys every surrogate file holds.
REQUIRED_METADATA = (
    "setup", "diameter_um", "radius_dpd", "param_names", "input_names", "input_units", "output_name",
    "output_units", "param_ranges", "x_range", "holdout_score", "holdout_metric", "data_hash",
    "architecture", "training", "code_version", "created_utc", "source",
)
#: Metadata keys of a network over the diameter (version 2): these replace ``diameter_um`` and ``radius_dpd``.
DIAMETER_METADATA = ("inputs", "response_scale", "diameter_range_um", "loading_range_per_size")


def _required(md: Mapping) -> tuple[str, ...]:
    """The metadata keys a file of this input kind must hold."""
    if md.get("inputs", "raw") == "diameter":
        return tuple(k for k in REQUIRED_METADATA if k not in ("diameter_um", "radius_dpd")) + DIAMETER_METADATA
    return REQUIRED_METADATA


def _version(md: Mapping) -> int:
    """The format version of a file with this metadata."""
    if md.get("log_inputs"):
        return FORMAT_VERSION_LOG_INPUTS
    return FORMAT_VERSION_DIAMETER if md.get("inputs", "raw") == "diameter" else FORMAT_VERSION


class SurrogateFormatError(ValueError):
    """A surrogate or bundle file is malformed; the message names the file and the field."""


def save_surrogate(path: str | Path, weights: Iterable, biases: Iterable, in_mean, in_std, out_mean,
                   out_std, metadata: Mapping) -> Path:
    """Write a surrogate ``.npz`` atomically, after validating the arrays and the metadata keys.

    Parameters
    ----------
    path : str or Path
        Output file.
    weights, biases : iterable of array_like
        Layer weights (fan_in, fan_out) and biases (fan_out,), input side first; stored as float32.
    in_mean, in_std : array_like, shape (7,)
        Standardisation of the raw inputs (ka, kb, b1, b2, a3, a4, x) [DPD units]; stored as float64.
    out_mean, out_std : array_like, shape (1,)
        Standardisation of the raw output [DPD force or DPD length].
    metadata : Mapping
        Metadata (module docstring); ``code_version`` and ``created_utc`` are added when missing.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    SurrogateFormatError
        For missing metadata keys, shapes that do not chain, non-finite values or a zero standard deviation.
    """
    path = Path(path)
    md = dict(metadata)
    md.setdefault("code_version", code_version())
    md.setdefault("created_utc", utc_now())
    missing = [k for k in _required(md) if k not in md]
    if missing:
        raise SurrogateFormatError(f"{path}: metadata lacks field(s) {', '.join(missing)}")
    weights = [np.asarray(w, dtype=np.float32) for w in weights]
    biases = [np.asarray(b, dtype=np.float32) for b in biases]
    arrays: dict[str, np.ndarray] = {
        "format": np.array(FORMAT), "format_version": np.array(_version(md)),
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
    atomic_write_bytes(path, lambda fh: np.savez(fh, **arrays))
    return path


def _json_default(obj):
    """JSON form of numpy scalars/arrays and paths in the metadata."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def _check_arrays(path: Path, arrays: Mapping[str, np.ndarray], md: Mapping) -> None:
    """Raise SurrogateFormatError unless the arrays chain, are finite and match the metadata."""
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
        raise SurrogateFormatError(f"{path}: metadata field 'setup' must be one of {LOADING_PROTOCOLS}, "
                                   f"got {md['setup']!r}")
    if tuple(md["param_names"]) != SHELL_PARAMETERS:
        raise SurrogateFormatError(f"{path}: metadata field 'param_names' must be {list(SHELL_PARAMETERS)}, "
                                   f"got {md['param_names']}")
    for name in SHELL_PARAMETERS:
        if name not in md["param_ranges"]:
            raise SurrogateFormatError(f"{path}: metadata field 'param_ranges' lacks '{name}'")
    inputs = md.get("inputs", "raw")
    if inputs not in INPUT_KINDS:
        raise SurrogateFormatError(f"{path}: metadata field 'inputs' must be one of {INPUT_KINDS}, got {inputs!r}")
    _check_log_inputs(path, md)
    if inputs == "diameter":
        if n_in != len(SHELL_PARAMETERS) + 2 or md["input_names"][-1] != "diameter_um":
            raise SurrogateFormatError(f"{path}: metadata field 'input_names' of a network over the diameter must "
                                       f"end with the loading coordinate and 'diameter_um', got {md['input_names']}")
        if md["response_scale"] != RESPONSE_SCALES[md["setup"]]:
            raise SurrogateFormatError(f"{path}: metadata field 'response_scale' must be "
                                       f"{RESPONSE_SCALES[md['setup']]!r} for {md['setup']}, got "
                                       f"{md['response_scale']!r}")
        for key in ("diameter_range_um", "loading_range_per_size"):
            lo_hi = np.asarray(md[key], dtype=float)
            if lo_hi.shape != (2,) or not np.all(np.isfinite(lo_hi)) or lo_hi[0] > lo_hi[1]:
                raise SurrogateFormatError(f"{path}: metadata field '{key}' must be [lo, hi] finite with lo <= hi, "
                                           f"got {md[key]}")
        if md["diameter_range_um"][0] <= 0:
            raise SurrogateFormatError(f"{path}: metadata field 'diameter_range_um' must be > 0 um, got "
                                       f"{md['diameter_range_um']}")
    elif n_in != len(SHELL_PARAMETERS) + 1:
        raise SurrogateFormatError(f"{path}: metadata field 'input_names' must hold the 6 shell parameters and the "
                                   f"loading coordinate, got {md['input_names']}")


def _check_log_inputs(path: Path, md: Mapping) -> None:
    """Raise SurrogateFormatError unless ``log_inputs`` names positive-ranged moduli once each, in order."""
    given = md.get("log_inputs", [])
    try:
        names = check_log_inputs(given)
    except (TypeError, ValueError):
        names = None
    if isinstance(given, str) or names is None or list(names) != list(given):
        raise SurrogateFormatError(f"{path}: metadata field 'log_inputs' must list names from "
                                   f"{list(LOG_INPUT_CHOICES)} once each, in that order, got {given!r}")
    for name in names:
        lo = float(md["param_ranges"][name][0])
        if not lo > 0:
            raise SurrogateFormatError(f"{path}: metadata field 'param_ranges' of the logged input '{name}' must "
                                       f"start above 0, got {md['param_ranges'][name]}")


def _read_fields(path: Path, npz) -> tuple[dict, int]:
    """The arrays of an opened surrogate archive, its format and fields checked; returns (arrays, n_layers)."""
    with npz:
        keys = set(npz.files)
        for key in ("format", "format_version"):
            if key not in keys:
                raise SurrogateFormatError(f"{path}: missing field '{key}' (not a bubblecal surrogate file)")
        fmt = str(npz["format"])
        if fmt != FORMAT:
            raise SurrogateFormatError(f"{path}: field 'format' is {fmt!r}, expected {FORMAT!r}")
        version = int(npz["format_version"])
        versions = (FORMAT_VERSION, FORMAT_VERSION_DIAMETER, FORMAT_VERSION_LOG_INPUTS)
        if version not in versions:
            raise SurrogateFormatError(f"{path}: field 'format_version' is {version}, this code reads "
                                       f"versions {', '.join(str(v) for v in versions)}")
        for key in ("n_layers", "in_mean", "in_std", "out_mean", "out_std", "metadata"):
            if key not in keys:
                raise SurrogateFormatError(f"{path}: missing field '{key}'")
        n_layers = int(npz["n_layers"])
        for i in range(n_layers):
            for key in (f"W_{i}", f"b_{i}"):
                if key not in keys:
                    raise SurrogateFormatError(f"{path}: missing field '{key}' (n_layers = {n_layers})")
        arrays = {k: npz[k] for k in keys}
    return arrays, n_layers


def load(path: str | Path) -> Surrogate:
    """Load a surrogate ``.npz`` (module docstring) as a JAX-callable :class:`~bubblecal.surrogates.Surrogate`.

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    Surrogate
        The loaded surrogate.

    Raises
    ------
    FileNotFoundError
        When ``path`` is not a file.
    SurrogateFormatError
        For an unreadable file, a wrong format or version, or a missing or invalid field (named in the message).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"surrogate file not found: {path}")
    if not zipfile.is_zipfile(path):  # numpy would otherwise try, and suggest, unpickling it
        raise SurrogateFormatError(f"{path}: not a .npz archive (a bubblecal surrogate file is a zip of arrays, "
                                   "written by `bubblecal surrogates train` or `export`)")
    try:
        npz = np.load(path, allow_pickle=False)
    except Exception as exc:
        raise SurrogateFormatError(f"{path}: not a readable .npz file ({exc})") from exc
    try:
        arrays, n_layers = _read_fields(path, npz)
    except SurrogateFormatError:
        raise
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as exc:  # a field's bytes are damaged
        raise SurrogateFormatError(f"{path}: damaged .npz ({type(exc).__name__}: {exc}); restore or re-export "
                                   "the file") from None
    try:
        md = json.loads(str(arrays["metadata"]))
    except json.JSONDecodeError as exc:
        raise SurrogateFormatError(f"{path}: field 'metadata' is not valid JSON ({exc})") from exc
    missing = [k for k in _required(md) if k not in md]
    if missing:
        raise SurrogateFormatError(f"{path}: field 'metadata' lacks key(s) {', '.join(missing)}")
    if int(arrays["format_version"]) != _version(md):
        raise SurrogateFormatError(f"{path}: field 'format_version' {int(arrays['format_version'])} does not match "
                                   f"metadata 'inputs' {md.get('inputs', 'raw')!r} and 'log_inputs' "
                                   f"{md.get('log_inputs', [])} (version {_version(md)})")
    _check_arrays(path, arrays, md)
    weights = [arrays[f"W_{i}"] for i in range(n_layers)]
    biases = [arrays[f"b_{i}"] for i in range(n_layers)]
    return Surrogate(weights, biases, arrays["in_mean"], arrays["in_std"], arrays["out_mean"],
                     arrays["out_std"], md, path=path)
