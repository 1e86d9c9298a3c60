"""ArviZ InferenceData of a sampler run: named dimensions, units, pointwise log likelihood, library versions.

Physics-free: dimension names, coordinates, units and constant data come from the caller as plain metadata
(:class:`ExportInfo`); the pointwise log likelihood and the observed data are read off the NumPyro model's
observed sites (:func:`pointwise_log_likelihood`). Factor sites (``numpyro.factor``) are not observations
and are left out. The pointwise log likelihood is stored as float32 (draws x points: 50,000 draws of a
100-point curve take 20 MB). Every group carries :func:`library_versions` and
``bubblecal_idata_format`` = :data:`IDATA_FORMAT` in its attributes, so a reader can tell files written
before these groups existed.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["ExportInfo", "IDATA_FORMAT", "library_versions", "observed_sites", "pointwise_log_likelihood",
           "build_inference_data"]

#: Version of the group layout written by :func:`build_inference_data` (attribute ``bubblecal_idata_format``).
IDATA_FORMAT = 2


@dataclass(frozen=True)
class ExportInfo:
    """What an InferenceData holds beyond the draws (the caller's vocabulary; nothing here knows physics).

    Parameters
    ----------
    dims : mapping of str to tuple of str
        Variable -> names of its axes after (chain, draw) for posterior, log_likelihood and sample_stats,
        or of all its axes for observed_data and constant_data.
    coords : mapping of str to array_like
        Coordinate values of the dimensions named in ``dims``.
    units : mapping of str to str
        Variable -> its ``units`` attribute (in whichever group it appears).
    constant_data : mapping of str to array_like
        Inputs of the model that are not observed (e.g. the loading coordinate).
    keep : mapping of str to array_like
        Observed site -> boolean mask of the entries that are observations (padding is dropped from
        observed_data and log_likelihood).
    attrs : mapping of str to object
        Extra attributes of every group (numbers or strings).
    """

    dims: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    coords: Mapping[str, Any] = field(default_factory=dict)
    units: Mapping[str, str] = field(default_factory=dict)
    constant_data: Mapping[str, Any] = field(default_factory=dict)
    keep: Mapping[str, Any] = field(default_factory=dict)
    attrs: Mapping[str, Any] = field(default_factory=dict)


def library_versions() -> dict[str, str]:
    """Versions of the libraries that wrote a file (``<name>_version`` -> version string).

    Returns
    -------
    dict of str to str
        bubblecal, numpy, jax, numpyro, arviz, xarray ('unknown' where not installed).
    """
    return dict(_library_versions())


@functools.cache
def _library_versions() -> dict[str, str]:
    """:func:`library_versions`, read once per process (each lookup scans the installed distributions)."""
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for name in ("bubblecal", "numpy", "jax", "numpyro", "arviz", "xarray"):
        try:
            out[f"{name}_version"] = version(name)
        except PackageNotFoundError:
            out[f"{name}_version"] = "unknown"
    return out


def _first_draw(samples: Mapping[str, np.ndarray], batch_ndims: int) -> dict:
    """The first draw of every site."""
    return {k: np.asarray(v)[(0,) * batch_ndims] for k, v in samples.items()}


def observed_sites(model: Callable, samples: Mapping[str, np.ndarray], args: tuple = (),
                   kwargs: Mapping | None = None, batch_ndims: int = 1) -> dict[str, np.ndarray]:
    """Observed values of every observed, non-factor site of ``model`` (traced at the first draw).

    Parameters
    ----------
    model : callable
        NumPyro model.
    samples : mapping of str to array_like
        Draws of the latent sites with ``batch_ndims`` leading axes.
    args, kwargs
        Arguments of the model.
    batch_ndims : int
        Leading draw axes of ``samples``.

    Returns
    -------
    dict of str to numpy.ndarray
        Site name -> observed value (units of the data).
    """
    import jax
    from numpyro.distributions.distribution import Unit
    from numpyro.handlers import substitute, trace

    draw, kw = _first_draw(samples, batch_ndims), dict(kwargs or {})

    def observed():
        tr = trace(substitute(model, draw)).get_trace(*args, **kw)
        return {name: site["value"] for name, site in tr.items()
                if site["type"] == "sample" and site["is_observed"] and not isinstance(site["fn"], Unit)}

    # run eagerly, every operation of the model would be a program of its own (dozens per dataset shape): staged,
    # an observation passed in as data comes out as it went in, one computed from the data alone (a dtype cast) is
    # a constant of the staged program, and only one computed from the latent values takes a compiled program
    found: dict = {}
    closed, shapes = jax.make_jaxpr(lambda: found.update(observed()) or dict(found), return_shape=True)()
    if any(isinstance(v, jax.core.Tracer) for v in found.values()):
        consts = dict(zip(closed.jaxpr.constvars, closed.consts, strict=True))
        leaves = [v.val if hasattr(v, "val") else consts.get(v) for v in closed.jaxpr.outvars]
        staged = jax.tree_util.tree_unflatten(jax.tree_util.tree_structure(shapes), leaves)
        found = {k: staged[k] if isinstance(v, jax.core.Tracer) else v for k, v in found.items()}
        if any(v is None for v in found.values()):
            found = jax.jit(observed)()
    return {name: np.asarray(v) for name, v in found.items()}


def pointwise_log_likelihood(model: Callable, samples: Mapping[str, np.ndarray], args: tuple = (),
                             kwargs: Mapping | None = None, *, batch_ndims: int = 1, chunk_size: int = 1024,
                             keep: Mapping[str, Any] | None = None,
                             evaluate: Callable | None = None,
                             sites: list[str] | None = None) -> dict[str, np.ndarray]:
    """log p(y_j | θ_s) of every observed (non-factor) site, draw and observation, as float32.

    Parameters
    ----------
    model : callable
        NumPyro model.
    samples : mapping of str to array_like
        Draws with ``batch_ndims`` leading axes (deterministic sites may be included).
    args, kwargs
        Arguments of the model.
    batch_ndims : int
        1 for (draw, ...) or 2 for (chain, draw, ...).
    chunk_size : int
        Draws evaluated per vectorised call (memory).
    keep : mapping of str to array_like or None
        Site -> boolean mask over its observations; masked-out entries (padding) are dropped.
    evaluate : callable or None
        ``evaluate(chunk) -> {site: log likelihood}`` of ``chunk_size`` draws, e.g. a program compiled once
        per model structure with the model's arrays as arguments (a sampler's); None: one program per call
        with the arguments as constants.
    sites : list of str or None
        The observed sites (as :func:`observed_sites` names them); None traces the model for them.

    Returns
    -------
    dict of str to numpy.ndarray
        Site name -> (batch..., observations...) float32.

    Raises
    ------
    ValueError
        If ``samples`` is empty or its sites disagree on the draw axes.
    """
    import jax
    from numpyro.infer import log_likelihood

    if not samples:
        raise ValueError("pointwise_log_likelihood needs at least one sampled site")
    arrays = {k: np.asarray(v) for k, v in samples.items()}
    batch = next(iter(arrays.values())).shape[:batch_ndims]
    if any(v.shape[:batch_ndims] != batch for v in arrays.values()):
        raise ValueError(f"samples disagree on their leading {batch_ndims} draw axes: "
                         + ", ".join(f"{k} {v.shape}" for k, v in arrays.items()))
    names = list(sites) if sites is not None else list(observed_sites(model, arrays, args, kwargs, batch_ndims))
    total = math.prod(batch)
    flat = {k: v.reshape((total,) + v.shape[batch_ndims:]) for k, v in arrays.items()}
    size = min(chunk_size, total)
    kw = dict(kwargs or {})
    if evaluate is None:
        # one compiled program per call: the model's arguments are constants, the last chunk is padded to size
        evaluate = jax.jit(lambda chunk: log_likelihood(model, chunk, *args, parallel=True, **kw))
    parts: dict[str, list] = {n: [] for n in names}
    for a in range(0, total, size):
        chunk = {k: v[a:a + size] for k, v in flat.items()}
        n_real = next(iter(chunk.values())).shape[0]
        if n_real < size:
            chunk = {k: np.concatenate([v, np.repeat(v[-1:], size - n_real, axis=0)]) for k, v in chunk.items()}
        ll = evaluate(chunk)
        for n in names:
            parts[n].append(np.asarray(ll[n], dtype=np.float32)[:n_real])
    out = {}
    for n in names:
        v = np.concatenate(parts[n], axis=0)
        if keep and n in keep:
            v = v[:, np.asarray(keep[n], dtype=bool)]
        out[n] = v.reshape(batch + v.shape[1:])
    return out


def _likelihood_groups(model: Callable, samples: Mapping[str, np.ndarray], args: tuple, kwargs: Mapping | None,
                       log_likelihood, info: ExportInfo | None, chunk_size: int,
                       evaluate: Callable | None = None) -> tuple[dict | None, dict | None]:
    """The log_likelihood and observed_data groups of a sampler's export, (chain, draw, ...) draws.

    ``log_likelihood`` True with a model: the pointwise log likelihood and the observed values (padding dropped by
    ``info.keep``); a mapping: those arrays as given and no observed values; anything else: neither.
    """
    if log_likelihood is True and model is not None:
        keep = dict(info.keep) if info is not None else None
        observed = observed_sites(model, samples, args, kwargs, batch_ndims=2)  # one trace serves both groups
        pointwise = pointwise_log_likelihood(model, samples, args, kwargs, batch_ndims=2, chunk_size=chunk_size,
                                             keep=keep, evaluate=evaluate, sites=list(observed))
        return pointwise, {k: (v[np.asarray(keep[k], dtype=bool)] if keep and k in keep else v)
                           for k, v in observed.items()}
    return (dict(log_likelihood) if isinstance(log_likelihood, Mapping) else None), None


def _dims(name: str, value: np.ndarray, info: ExportInfo, lead: int) -> list[str] | None:
    """Dimension names of a variable after its ``lead`` axes (None: ArviZ's defaults)."""
    dims = info.dims.get(name)
    if dims is None and value.ndim == lead:
        return []
    return None if dims is None else list(dims)


def build_inference_data(posterior: Mapping[str, np.ndarray], *, sample_stats: Mapping[str, np.ndarray] | None = None,
                         log_likelihood: Mapping[str, np.ndarray] | None = None,
                         observed_data: Mapping[str, np.ndarray] | None = None,
                         info: ExportInfo | None = None, extra_stats: Mapping[str, tuple] | None = None,
                         attrs: Mapping[str, Any] | None = None,
                         stats_coords: Mapping[str, Any] | None = None):
    """ArviZ InferenceData from (chain, draw, ...) arrays, with named dims, units and versions.

    Parameters
    ----------
    posterior : mapping of str to array_like
        Site -> (chain, draw, ...) draws.
    sample_stats : mapping of str to array_like or None
        Per-draw statistics (chain, draw).
    log_likelihood : mapping of str to array_like or None
        Observed site -> (chain, draw, observations...) pointwise log likelihood.
    observed_data : mapping of str to array_like or None
        Observed site -> its observations.
    info : ExportInfo or None
        Dimension names, coordinates, units, constant data and extra attributes.
    extra_stats : mapping of str to (tuple of str, array_like) or None
        Statistics that are not per draw (e.g. per stage): name -> (dims, values), added to sample_stats.
    attrs : mapping of str to object or None
        Attributes of every group (after the library versions and ``info.attrs``).
    stats_coords : mapping of str to array_like or None
        Coordinates of the dimensions of ``extra_stats`` (e.g. the stage numbers).

    Returns
    -------
    arviz.InferenceData

    Notes
    -----
    Pure array work (no model is traced): it may run on another thread than the sampler's.
    """
    import arviz as az

    info = info or ExportInfo()
    post = {k: np.asarray(v) for k, v in posterior.items()}
    groups = {"posterior": post}
    if sample_stats:
        groups["sample_stats"] = {k: np.asarray(v) for k, v in sample_stats.items()}
    if log_likelihood:
        groups["log_likelihood"] = {k: np.asarray(v) for k, v in log_likelihood.items()}
    if observed_data:
        groups["observed_data"] = {k: np.asarray(v) for k, v in observed_data.items()}
    constant = {k: np.asarray(v) for k, v in info.constant_data.items()}
    scalars = {k: v for k, v in constant.items() if v.ndim == 0}  # ArviZ would give them a '<name>_dim_0'
    if len(scalars) < len(constant):
        groups["constant_data"] = {k: v for k, v in constant.items() if v.ndim > 0}
    dims = {}
    for group, values in groups.items():
        lead = 2 if group in ("posterior", "sample_stats", "log_likelihood") else 0
        for k, v in values.items():
            d = _dims(k, v, info, lead)
            if d is not None:
                dims[k] = d
    coords = {k: np.asarray(v) for k, v in info.coords.items()}
    idata = az.from_dict(**groups, dims=dims, coords=coords)
    if scalars:
        import xarray as xr

        if "constant_data" in idata.groups():
            idata.constant_data = idata.constant_data.assign({k: ((), v) for k, v in scalars.items()})
        else:
            idata.add_groups({"constant_data": xr.Dataset({k: ((), v) for k, v in scalars.items()})})
    if extra_stats:
        import xarray as xr

        extra = xr.Dataset({k: (d, np.asarray(v)) for k, (d, v) in extra_stats.items()},
                           coords={"chain": idata.sample_stats.chain} if "sample_stats" in idata.groups() else None)
        if "sample_stats" in idata.groups():
            idata.sample_stats = idata.sample_stats.merge(extra)
        else:
            idata.add_groups({"sample_stats": extra})
        for k, v in (stats_coords or {}).items():
            idata.sample_stats.coords[k] = np.asarray(v)
    meta = {**library_versions(), "bubblecal_idata_format": IDATA_FORMAT, **dict(info.attrs), **dict(attrs or {})}
    for group in idata.groups():
        ds = getattr(idata, group)
        ds.attrs.update({k: _attr(v) for k, v in meta.items()})
        for k in ds.data_vars:
            if k in info.units:
                ds[k].attrs["units"] = info.units[k]
    return idata


def _attr(v):
    """A NetCDF-safe attribute value (non-finite floats as text, sequences as lists of numbers or text)."""
    if isinstance(v, float) and not math.isfinite(v):
        return str(v)
    if isinstance(v, bool):
        return int(v)
    return v

