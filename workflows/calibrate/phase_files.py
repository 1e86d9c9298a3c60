"""Phase files of a calibration run: ArviZ NetCDF (``.nc``) or plain ``.npz``, written atomically and read back.

The NetCDF layout (groups, dimensions, attributes) is ``docs/data-formats.md``, section "Calibration outputs".
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from bubblecal.data import atomic_write
from bubblecal.workflows.calibrate.imports import import_turn

__all__ = ["PhaseFileError", "write_phase", "phase_inference_data", "phase_inference_parts", "read_phase",
           "read_pointwise", "phase_format"]


class PhaseFileError(ValueError):
    """A stored phase file cannot be read (truncated, damaged, not a phase file); the message names it."""


def phase_inference_parts(result, loglik, *, info=None, pointwise=None) -> dict:
    """The arrays of a phase file's InferenceData (the keyword arguments of ``build_inference_data``).

    Traces the phase's model (observed values, pointwise log likelihood): call it on the thread that samples,
    since NumPyro's effect handlers are not thread-safe; building the InferenceData from the result is array
    work that may run on another thread.

    Parameters
    ----------
    result : bubblecal.inference.phase_results.PhaseResult
        Draws (DPD units) and, when it ran in this process, its sampler.
    loglik : array_like or None
        Log likelihood of every draw.
    info : bubblecal.inference.idata.ExportInfo or None
        Dimension names, units and constant data of the groups.
    pointwise : mapping of str to array_like or None
        (draw, ...) pointwise log likelihood (else the sampler's model gives it).

    Returns
    -------
    dict
        Keyword arguments of :func:`bubblecal.inference.idata.build_inference_data`.
    """
    ll = {k: np.asarray(v)[None] for k, v in pointwise.items()} if pointwise is not None else None
    if result.sampler is not None:
        return result.sampler.inference_parts(info, log_likelihood=True if ll is None else ll)
    stats = {"loglik": np.asarray(loglik)[None]} if loglik is not None else None
    return {"posterior": {k: np.asarray(v)[None] for k, v in result.samples.items()}, "sample_stats": stats,
            "log_likelihood": ll, "info": info}


def phase_inference_data(result, loglik, *, info=None, pointwise=None):
    """The ArviZ InferenceData of a phase file (without the run's attributes).

    Parameters
    ----------
    result, loglik, info, pointwise
        As :func:`phase_inference_parts` (and, like it, call it on the thread that samples).

    Returns
    -------
    arviz.InferenceData
    """
    from bubblecal.inference.idata import build_inference_data

    return build_inference_data(**phase_inference_parts(result, loglik, info=info, pointwise=pointwise))


def write_phase(path: Path, result, loglik, attrs: Mapping, *, info=None, pointwise=None, idata=None,
                parts: Mapping | None = None) -> Path:
    """Write a phase result atomically: ArviZ NetCDF (``.nc``) or plain ``.npz`` (samples + attrs JSON).

    The NetCDF file is written by :func:`bubblecal.inference.netcdf.write_netcdf` (ArviZ's layout and
    compression, in one open of the file).

    Parameters
    ----------
    path : Path
        Target file; its suffix picks the format.
    result : bubblecal.inference.phase_results.PhaseResult
        Draws (DPD units), log evidence and its standard error, status, seconds.
    loglik : array_like or None
        Log likelihood of every draw (stored for the MAP).
    attrs : Mapping
        Extra metadata (config hash, phase name, diagnostics).
    info : bubblecal.inference.idata.ExportInfo or None
        Dimension names, units and constant data of the NetCDF groups.
    pointwise : mapping of str to array_like or None
        (draw, ...) pointwise log likelihood (else the sampler's model gives it).
    idata : arviz.InferenceData or None
        Write this (the joint run's chains) instead of building one from ``result``.
    parts : mapping or None
        :func:`phase_inference_parts` computed before (then no model is traced here, and the write may run on
        another thread than the sampler's).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    TypeError, ValueError
        A variable or attribute that the NetCDF writer does not lay out
        (:func:`~bubblecal.inference.write_netcdf`; the message names the file); nothing is written.
    OSError
        The file stayed locked by another process.
    """
    path = Path(path)
    meta = {"log_evidence": result.log_evidence, "log_evidence_se": result.log_evidence_se, "status": result.status,
            "seconds": result.seconds, "name": result.name, **attrs}
    if path.suffix == ".nc":
        if idata is None and parts is None:
            idata = phase_inference_data(result, loglik, info=info, pointwise=pointwise)
        elif idata is None:
            from bubblecal.inference.idata import build_inference_data

            idata = build_inference_data(**parts)
        idata.posterior.attrs.update({k: (json.dumps(v) if isinstance(v, (dict, list)) else
                                          ("nan" if isinstance(v, float) and not math.isfinite(v) else v))
                                      for k, v in meta.items()})
        from bubblecal.inference.netcdf import write_netcdf

        _retry_locked(lambda: atomic_write(path, lambda p: write_netcdf(idata, p)), path)
    else:
        arrays = {f"sample__{k}": np.asarray(v) for k, v in result.samples.items()}
        if loglik is not None:
            arrays["loglik"] = np.asarray(loglik)
        arrays["meta"] = np.array(json.dumps(meta, default=str))

        def _w(p):
            with open(p, "wb") as fh:
                np.savez(fh, **arrays)

        atomic_write(path, _w)
    return path


#: Attempts of a NetCDF write that finds its own temporary file locked, and the first wait [s] (doubled each time).
LOCK_RETRIES, LOCK_WAIT_S = 8, 0.05


def _retry_locked(write: Callable[[], Path], path: Path) -> Path:
    """Run ``write`` again (into a new temporary file) while HDF5 finds the file locked.

    A child process started meanwhile (XLA's GPU compiler, for one) inherits the open HDF5 descriptor of a file
    being written, and with it HDF5's lock, until it exits: the writer's next open of that file then fails with
    EAGAIN. The child is short-lived, so a few waits clear it.
    """
    for attempt in range(LOCK_RETRIES - 1):
        try:
            return write()
        except BlockingIOError:
            time.sleep(LOCK_WAIT_S * 2**attempt)
    try:
        return write()
    except BlockingIOError as exc:
        raise OSError(f"{path}: the file stayed locked by another process over {LOCK_RETRIES} attempts ({exc}); "
                      "set HDF5_USE_FILE_LOCKING=FALSE if the folder is not shared") from exc


def read_phase(path: Path):
    """Read a file written by :func:`write_phase`.

    Parameters
    ----------
    path : Path
        A ``.nc`` or ``.npz`` phase file.

    Returns
    -------
    tuple
        (:class:`~bubblecal.inference.phase_results.PhaseResult`, log likelihood per draw or None).

    Raises
    ------
    PhaseFileError
        The file is missing, truncated, damaged or holds no phase (the message names it and the cause).
    """
    try:
        with import_turn():  # a first read imports xarray, h5netcdf and dask: not beside another thread's imports
            return _read_phase(Path(path))
    except Exception as exc:  # h5py, netCDF4, zipfile and JSON each raise their own kinds on damaged bytes
        raise PhaseFileError(f"{path}: damaged or unreadable phase file ({type(exc).__name__}: {exc})") from exc


def _read_phase(path: Path):
    """:func:`read_phase` without the error translation."""
    from bubblecal.inference.phase_results import PhaseResult

    if path.suffix == ".nc":
        import xarray as xr

        # the two groups a result needs, not every group of the file (az.from_netcdf opens them all)
        with xr.open_dataset(path, group="posterior", engine="h5netcdf") as post:
            meta = dict(post.attrs)
            # a TMCMC file's chains are replicas and the result is the first; the joint run's are NUTS chains
            pick = _all_chains if meta.get("phase_result_chains") == "all" else (lambda v: np.asarray(v.values[0]))
            samples = {k: pick(post[k]) for k in post.data_vars}
        loglik = _sample_stat(path, "loglik", pick)
    else:
        with np.load(path, allow_pickle=False) as npz:
            samples = {k[len("sample__"):]: npz[k] for k in npz.files if k.startswith("sample__")}
            loglik = npz["loglik"] if "loglik" in npz.files else None
            meta = json.loads(str(npz["meta"]))

    def _f(v):
        try:
            return float(v)
        except (TypeError, ValueError):
            return math.nan

    result = PhaseResult(name=str(meta.get("name", meta.get("phase", path.stem))), samples=samples,
                         log_evidence=_f(meta.get("log_evidence")), log_evidence_se=_f(meta.get("log_evidence_se")),
                         status=str(meta.get("status", "converged")), seconds=_f(meta.get("seconds")))
    return result, loglik


def _sample_stat(path: Path, name: str, pick) -> np.ndarray | None:
    """``pick`` of the sample statistic ``name`` of a NetCDF phase file (None without the group or the variable)."""
    import xarray as xr

    try:
        with xr.open_dataset(path, group="sample_stats", engine="h5netcdf") as stats:
            return pick(stats[name]) if name in stats.data_vars else None
    except OSError:  # no sample_stats group (the posterior, read first, names a damaged file)
        return None


def _all_chains(var) -> np.ndarray:
    """(chain, draw, ...) values with chains concatenated."""
    v = np.asarray(var.values)
    return v.reshape((-1,) + v.shape[2:])


def phase_format(path: Path) -> int:
    """The ``bubblecal_idata_format`` of a NetCDF phase file (0 when written before the ArviZ groups).

    Parameters
    ----------
    path : Path
        A ``.nc`` phase file.

    Returns
    -------
    int

    Raises
    ------
    PhaseFileError
        The file cannot be read.
    """
    try:
        with import_turn():
            import xarray as xr

            with xr.open_dataset(path, group="posterior", engine="h5netcdf") as ds:
                return int(ds.attrs.get("bubblecal_idata_format", 0))
    except Exception as exc:  # h5py and netCDF4 raise their own kinds on damaged bytes
        raise PhaseFileError(f"{path}: damaged or unreadable phase file ({type(exc).__name__}: {exc})") from exc


def read_pointwise(path: Path) -> dict[str, np.ndarray]:
    """The first chain's pointwise log likelihood of a phase file (empty for ``.npz`` or without the group).

    Parameters
    ----------
    path : Path
        A phase file.

    Returns
    -------
    dict of str to numpy.ndarray
        Observed site -> (draw, ...) log likelihood.

    Raises
    ------
    PhaseFileError
        The file cannot be read.
    """
    if Path(path).suffix != ".nc":
        return {}
    try:
        with import_turn():
            import xarray as xr

            with xr.open_dataset(path, group="log_likelihood", engine="h5netcdf") as ds:
                return {k: np.asarray(v.values[0]) for k, v in ds.data_vars.items()}
    except OSError:
        return {}
    except Exception as exc:  # h5py raises its own kinds on damaged bytes
        raise PhaseFileError(f"{path}: damaged or unreadable phase file ({type(exc).__name__}: {exc})") from exc
