"""Campaign records: one finished simulation sample, its schema, validation and checksummed line.

A record is what :class:`~bubblecal.data.CampaignStore` holds, one JSON object per line
(docs/data-formats.md).  Record schema version 1; the ``'invalid'`` status and the ``'ringdown'`` setup
extend it backwards-compatibly (every store written without them still reads).

Record (all keys required unless marked optional)
-------------------------------------------------
=================  ===========================================================================
``v``              record schema version (1)
``sample_id``      str, the design point's id, unique within the campaign (resume key)
``curve_id``       str, globally unique id of this curve (e.g. ``"camp3/lhs-000123/r0"``)
``setup``          ``"compression"`` | ``"indentation"`` | ``"ringdown"``
``params``         {"ka","kb","b1","b2","a3","a4": float} (DPD units, see bubblecal.data.units)
``radius_dpd``     float, bubble radius [DPD length] (diameter_um = radius_dpd * 0.5)
``x``              [float] loading coordinate: compression imposed total displacement [DPD
                   length]; indentation applied force [DPD force]; ringdown time t [DPD time]
``y``              [float] response: compression force [DPD force]; indentation displacement
                   (reduction of the pole-to-pole distance) [DPD length]; ringdown volume radius
                   R(t) = (3V/4 pi)^(1/3) [DPD length]; same length as x
``status``         ``"ok"`` | ``"ruptured"`` | ``"failed"`` | ``"unstable"`` | ``"timeout"`` |
                   ``"invalid"`` (the simulation reported ok but the curve holds non-finite numbers)
``seed``           int, the random seed of the run
``tier``           str, fidelity tier (``"explicit"``, ``"implicit"``, ``"quasistatic"``, ...)
``code_version``   str, bubblecal version (and git commit when known)
``provenance``     object, free-form (host, device, config hash, wall time, start/end, ...)
``written_utc``    str, ISO-8601 time of writing
``message``        optional str (e.g. the failure reason)
``crc32``          int, zlib.crc32 of the canonical JSON (sorted keys, no spaces) of the record
                   without ``crc32``: detects torn or edited lines
=================  ===========================================================================

NaN/Infinity are written as the JSON extensions ``NaN``/``Infinity`` (Python's json reads them).
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import zlib
from collections.abc import Iterable, Mapping

from bubblecal.data.errors import StoreError
from bubblecal.data.names import PROTOCOLS, RECORD_STATUSES, SHELL_PARAMETERS
from bubblecal.data.names import code_version as running_code_version

__all__ = ["RECORD_VERSION", "REQUIRED_FIELDS", "make_record", "validate_record"]

#: Record schema version written and read by this code.
RECORD_VERSION = 1
#: Fields every record holds (``message`` is optional; ``crc32`` is added when the record is stored).
REQUIRED_FIELDS = ("v", "sample_id", "curve_id", "setup", "params", "radius_dpd", "x", "y", "status", "seed",
                   "tier", "code_version", "provenance", "written_utc")


def _utc_now() -> str:
    """The current UTC time as ISO-8601 with microseconds and a ``Z``."""
    return _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _canonical(obj: Mapping) -> str:
    """Canonical JSON (sorted keys, no spaces, NaN/Infinity allowed): what the checksum covers."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=True)


def _checksummed_line(rec: Mapping) -> str:
    """One store line: the canonical JSON of ``rec`` (without any old checksum) plus its crc32, newline-ended."""
    rec = {k: v for k, v in rec.items() if k != "crc32"}
    rec["crc32"] = zlib.crc32(_canonical(rec).encode())
    return _canonical(rec) + "\n"


def make_record(*, sample_id: str, setup: str, params: Mapping[str, float], radius_dpd: float,
                x: Iterable[float], y: Iterable[float], status: str, seed: int, tier: str,
                curve_id: str | None = None, provenance: Mapping | None = None, message: str | None = None,
                code_version: str | None = None) -> dict:
    """Build and validate one record (the fields are described in the module docstring).

    Parameters
    ----------
    sample_id : str
        The design point's id, unique within the campaign.
    setup : str
        'compression', 'indentation' or 'ringdown'.
    params : mapping of str to float
        Shell constants ka [DPD 2-D modulus], kb [DPD energy], b1, b2, a3, a4 [-]; when all six are present
        exactly these are kept, as floats, in that order.
    radius_dpd : float
        Bubble radius [DPD length].
    x, y : iterable of float
        The curve, in DPD units (see the module docstring for each setup's axes).
    status : str
        One of :data:`~bubblecal.data.RECORD_STATUSES`.
    seed : int
        Random seed of the run.
    tier : str
        Fidelity tier that produced the curve.
    curve_id : str, optional
        Globally unique curve id (default: ``sample_id``).
    provenance : mapping, optional
        Free-form provenance (host, device, config hash, ...).
    message : str, optional
        E.g. the failure reason.
    code_version : str, optional
        Default: the running code's :func:`~bubblecal.data.code_version`.

    Returns
    -------
    dict
        The record, stamped with the current UTC time in ``written_utc``; no ``crc32`` yet.

    Raises
    ------
    StoreError
        If the record does not follow the schema (:func:`validate_record`).
    """
    rec = {
        "v": RECORD_VERSION, "sample_id": str(sample_id),
        "curve_id": str(curve_id if curve_id is not None else sample_id), "setup": setup,
        "params": ({k: float(params[k]) for k in SHELL_PARAMETERS} if all(k in params for k in SHELL_PARAMETERS)
                   else dict(params)),
        "radius_dpd": float(radius_dpd), "x": [float(v) for v in x], "y": [float(v) for v in y],
        "status": status, "seed": int(seed), "tier": str(tier),
        "code_version": code_version or running_code_version(), "provenance": dict(provenance or {}),
        "written_utc": _utc_now(),
    }
    if message is not None:
        rec["message"] = str(message)
    validate_record(rec)
    return rec


def validate_record(rec: Mapping, where: str = "record") -> None:
    """Check that ``rec`` follows the record schema.

    Parameters
    ----------
    rec : mapping
        The record (without ``crc32``).
    where : str
        Label of the record in error messages (e.g. ``"<file>:<line>"``).

    Raises
    ------
    StoreError
        Naming the field: a missing field, another record version, an unknown setup or status, params that are
        not an object or lack a shell constant, x and y of different lengths, or a status 'ok' record with
        non-finite numbers in params/radius_dpd/x/y or an empty x.
    """
    for key in REQUIRED_FIELDS:
        if key not in rec:
            raise StoreError(f"{where}: missing field '{key}'")
    if rec["v"] != RECORD_VERSION:
        raise StoreError(f"{where}: field 'v' is {rec['v']!r}, this code reads record version {RECORD_VERSION}")
    if rec["setup"] not in PROTOCOLS:
        raise StoreError(f"{where}: field 'setup' must be one of {PROTOCOLS}, got {rec['setup']!r}")
    if rec["status"] not in RECORD_STATUSES:
        raise StoreError(f"{where}: field 'status' must be one of {RECORD_STATUSES}, got {rec['status']!r}")
    params = rec["params"]
    if not isinstance(params, Mapping):
        raise StoreError(f"{where}: field 'params' must be an object")
    for k in SHELL_PARAMETERS:
        if k not in params:
            raise StoreError(f"{where}: field 'params' lacks '{k}'")
    if len(rec["x"]) != len(rec["y"]):
        raise StoreError(f"{where}: fields 'x' and 'y' differ in length ({len(rec['x'])} vs {len(rec['y'])})")
    if rec["status"] == "ok":
        vals = list(rec["x"]) + list(rec["y"]) + [params[k] for k in SHELL_PARAMETERS] + [rec["radius_dpd"]]
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in vals):
            raise StoreError(f"{where}: status 'ok' but non-finite numbers in params/radius_dpd/x/y")
        if len(rec["x"]) == 0:
            raise StoreError(f"{where}: status 'ok' but field 'x' is empty")
