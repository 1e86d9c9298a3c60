"""ArviZ InferenceData written as NetCDF4/HDF5 in one open of the file, laid out as ArviZ's ``to_netcdf`` lays it out.

ArviZ writes every group through xarray and h5netcdf, which reopen the file per group and spend most of a small
file's time on per-variable bookkeeping. :func:`write_netcdf` writes the same layout with h5py directly: the groups
in ArviZ's order, every dimension an HDF5 dimension scale carrying netCDF-4's ``_Netcdf4Dimid`` and
``_Netcdf4Coordinates``, the variables in the dataset's order with xarray's encoding (NaN ``_FillValue`` of floats,
booleans as int8 with ``dtype='bool'``, text as variable-length strings) and ArviZ's zlib compression. Readers
(``arviz.from_netcdf``, ``xarray.open_dataset``, h5netcdf) see the same datasets as in ArviZ's file.
"""

from __future__ import annotations

import functools
import numbers
from pathlib import Path

import numpy as np

__all__ = ["write_netcdf"]

#: Attributes h5netcdf keeps for the netCDF-4 and dimension-scale bookkeeping (hidden from readers).
HIDDEN_ATTRS = frozenset({"REFERENCE_LIST", "CLASS", "DIMENSION_LIST", "NAME", "_Netcdf4Dimid", "_Netcdf4Coordinates",
                          "_nc3_strict", "_NCProperties"})
#: Variable attributes that xarray's encoding writes itself (a variable's own would clash with them).
ENCODING_ATTRS = frozenset({"_FillValue", "missing_value", "scale_factor", "add_offset", "_Unsigned", "_Encoding",
                            "coordinates", "dtype"})
#: HDF5 name of a dimension without a coordinate variable (netCDF-C's), followed by its length in 10 columns.
NOT_A_VARIABLE = b"This is a netCDF dimension but not a netCDF variable."
#: zlib level of ArviZ's ``compress=True`` (xarray passes gzip without a level: h5py's default).
ZLIB_LEVEL = 4
#: h5py's variable-length UTF-8 text dtype.
_TEXT = np.dtype("O", metadata={"vlen": str})


def write_netcdf(idata, path) -> Path:
    """Write an InferenceData to a NetCDF4/HDF5 file that readers cannot tell from ArviZ's ``to_netcdf`` one.

    Parameters
    ----------
    idata : arviz.InferenceData
        Groups of float32/float64, (unsigned) integer, bool or text (``<U``) variables, scalars included, with
        dimension coordinates only; attributes (of the groups, their variables and ``idata.attrs``) are text, real
        numbers, lists of text, or lists/1-D arrays of real numbers.
    path : str or pathlib.Path
        File to create (replaced if it exists).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    TypeError
        A variable's dtype or an attribute value (bool, None, bytes, a mapping, a nested or mixed sequence, a text
        array, a 0-d array) is not supported; the message names the file, the group and the variable or
        attribute, and nothing is written.
    ValueError
        A layout ArviZ would write otherwise: a non-dimension or multi-dimensional coordinate, a data variable
        named as a dimension, a name with '/', a zero-length dimension, an attribute name that netCDF-4 or
        xarray's encoding reserve; nothing is written.

    Notes
    -----
    Encoded as ArviZ 0.23's ``to_netcdf(compress=True)`` through xarray and h5netcdf: numeric and bool variables,
    coordinates included, gzip level 4 without shuffle in h5py's default chunks; scalars and text uncompressed;
    floats with a NaN ``_FillValue``. With the same data bytes, chunks and filters, the file is a few percent
    smaller than ArviZ's, which keeps the unused space of the placeholder datasets it replaces by coordinates and
    of its reopening the file per group. A variable's
    own ``encoding`` (of a dataset read from a file) is not applied, as ArviZ applies none to a freshly built
    InferenceData. The root ``_NCProperties`` names this package, HDF5 and h5py as the writers.
    """
    import h5py

    path = Path(path)
    try:  # every check before the file opens
        root = _attrs(getattr(idata, "attrs", None) or {}, "the root group", HIDDEN_ATTRS)
        plans = [_plan(group, getattr(idata, group)) for group in idata.groups()]
    except (TypeError, ValueError) as exc:
        raise type(exc)(f"{path}: {exc}") from None
    with h5py.File(path, "w", track_order=True) as f:
        for key, value in root:
            _put(f.id, key, value)
        dimid = 0
        for plan in plans:
            dimid = _write_group(f.create_group(plan["group"], track_order=True), plan, dimid)
        _put(f.id, "_NCProperties", np.array(_nc_properties().encode("ascii")))
    return path


@functools.cache
def _nc_properties() -> str:
    """The root ``_NCProperties`` (netCDF-4 provenance: format version 2, then the writing libraries)."""
    from importlib.metadata import PackageNotFoundError, version

    import h5py

    try:
        own = version("bubblecal")
    except PackageNotFoundError:
        own = "unknown"
    return f"version=2,bubblecal={own},hdf5={h5py.version.hdf5_version},h5py={h5py.__version__}"


def _plan(group: str, ds) -> dict:
    """What :func:`_write_group` writes of one group: checked arrays, dimensions and attributes, in file order."""
    dims: dict[str, int] = {}
    for var in ds.variables.values():  # in order of first use, as xarray creates them
        dims.update(zip(var.dims, var.shape, strict=True))
    for d, n in dims.items():
        if n == 0 or "/" in str(d):
            raise ValueError(f"group {group!r}: dimension {d!r} (length {n}) is not supported by write_netcdf")
    variables = []
    for name, var in ds.variables.items():
        where = f"group {group!r}, variable {name!r}"
        if not isinstance(name, str) or not name or "/" in name:
            raise ValueError(f"{where}: names must be non-empty text without '/'")
        is_coord = name in ds.coords
        if is_coord and var.dims != (name,):
            raise ValueError(f"{where}: only dimension coordinates (1-D, named as their dimension) are supported")
        if not is_coord and name in dims:
            raise ValueError(f"{where}: a data variable named as a dimension is not supported")
        values = _encode(var, where)
        attrs = _attrs(var.attrs, where, HIDDEN_ATTRS | ENCODING_ATTRS)
        if var.dtype.kind == "b":  # xarray's bool encoding, after the variable's own attributes
            attrs.append(("dtype", np.array("bool", dtype=_TEXT)))
        variables.append((name, var.dims, values, attrs, is_coord))
    return {"group": group, "attrs": _attrs(ds.attrs, f"group {group!r}", HIDDEN_ATTRS), "dims": dims,
            "variables": variables}


def _encode(var, where: str) -> np.ndarray:
    """The stored array of a variable (xarray's encoding of its dtype); TypeError for a dtype not supported."""
    dtype = var.dtype
    if dtype.isnative and ((dtype.kind == "f" and dtype.itemsize in (4, 8)) or dtype.kind in "iu"):
        return np.asarray(var.values)
    if dtype.kind == "b":
        return np.asarray(var.values).astype(np.int8)
    if dtype.kind == "U":
        return np.asarray(var.values).astype(object)
    raise TypeError(f"{where}: dtype {dtype} is not supported by write_netcdf (float32, float64, native-order "
                    "integers, bool and <U text are)")


def _attrs(attrs, where: str, reserved: frozenset) -> list[tuple[str, np.ndarray]]:
    """(name, stored array) of every attribute, in order; ValueError for a reserved name, TypeError for a value."""
    out = []
    for key, value in attrs.items():
        if not isinstance(key, str) or not key or key in reserved:
            raise ValueError(f"{where}: attribute name {key!r} is reserved or not text")
        stored = _attr_array(value)
        if stored is None:
            raise TypeError(f"{where}: attribute {key!r} = {value!r} ({type(value).__name__}) is not supported by "
                            "write_netcdf (text, real numbers, lists of text, lists or 1-D arrays of numbers are)")
        out.append((key, stored))
    return out


def _attr_array(value) -> np.ndarray | None:
    """The array h5netcdf stores for an attribute (text as is, a number as a 1-element array), None where ArviZ's
    writer refuses the value (bool, None, mappings, nested or mixed sequences, text arrays) or it has no netCDF
    type."""
    if isinstance(value, str):
        return np.array(value, dtype=_TEXT)
    if isinstance(value, (list, tuple)) and value and all(isinstance(x, str) for x in value):
        return np.array(value, dtype=_TEXT)
    if isinstance(value, (list, tuple)):
        if not all(isinstance(x, numbers.Real) and not isinstance(x, (bool, np.bool_)) for x in value):
            return None
    elif isinstance(value, np.ndarray):
        if value.ndim != 1:  # refused rather than stored in a shape that reads back otherwise than ArviZ's
            return None
    elif isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        return None
    arr = np.asarray(value)
    arr = arr.reshape(1) if arr.ndim == 0 else arr
    if arr.dtype.kind in "iu" or (arr.dtype.kind == "f" and arr.dtype.itemsize in (4, 8)):
        return arr
    return None


def _put(oid, key: str, data: np.ndarray) -> None:
    """Create the attribute ``key`` of the HDF5 object ``oid`` holding ``data`` (its shape and dtype).

    h5py's low-level calls, as its ``attrs[key] = data`` makes them, without the existence check, conversions and
    dtype lookups it repeats per attribute.
    """
    from h5py import h5a, h5s

    logical, memory = _h5types(data.dtype.str)
    h5a.create(oid, key.encode(), logical, h5s.create_simple(data.shape)).write(data, mtype=memory)


@functools.cache
def _h5types(dtype: str):
    """HDF5 file and memory types of an attribute's NumPy dtype (``|O``: variable-length UTF-8 text, as h5py's)."""
    from h5py import h5t

    dt = _TEXT if dtype == "|O" else np.dtype(dtype)
    return h5t.py_create(dt, logical=True), h5t.py_create(dt)


def _write_group(grp, plan: dict, dimid: int) -> int:
    """Write one planned group into the open h5py group ``grp``; returns the next free netCDF dimension id."""
    import h5py

    for key, value in plan["attrs"]:
        _put(grp.id, key, value)
    ids = {d: dimid + i for i, d in enumerate(plan["dims"])}  # unique in the file, as netCDF-C numbers them
    coords = {name for name, *_, is_coord in plan["variables"] if is_coord}
    scales = {}
    # dimensions without a coordinate variable come first: h5netcdf creates every dimension before the variables
    for d, n in plan["dims"].items():
        if d not in coords:
            scales[d] = grp.create_dataset(d, (n,), dtype=">f4", track_order=True)
            _put(scales[d].id, "_Netcdf4Dimid", np.array(ids[d], dtype=np.int32))
            scales[d].make_scale(NOT_A_VARIABLE + b"%10d" % n)
    created = []
    for name, dims, values, attrs, is_coord in plan["variables"]:
        kw = {"fillvalue": np.nan} if values.dtype.kind == "f" else {}
        if values.dtype.kind == "O":
            kw["dtype"] = h5py.string_dtype()
        elif values.ndim:  # ArviZ compresses numbers; xarray drops the filters of scalars
            kw.update(compression="gzip", compression_opts=ZLIB_LEVEL)
        ds = grp.create_dataset(name, data=values, track_order=True, **kw)
        created.append((ds, dims, attrs, is_coord))
        if is_coord:
            _put(ds.id, "_Netcdf4Dimid", np.array(ids[name], dtype=np.int32))
            ds.make_scale(name)
            scales[name] = ds
    # attached once every scale exists: a coordinate may come after the variables that use its dimension
    for ds, dims, attrs, is_coord in created:
        if not is_coord:
            for axis, d in enumerate(dims):
                ds.dims[axis].attach_scale(scales[d])
        if dims:
            _put(ds.id, "_Netcdf4Coordinates", np.array([ids[d] for d in dims], dtype=np.int32))
            if not is_coord:  # netCDF-C gives a variable the id of its first dimension
                _put(ds.id, "_Netcdf4Dimid", np.array(ids[dims[0]], dtype=np.int32))
        if ds.dtype.kind == "f":
            _put(ds.id, "_FillValue", np.full(1, np.nan, dtype=ds.dtype))
        for key, value in attrs:
            _put(ds.id, key, value)
    return dimid + len(ids)
