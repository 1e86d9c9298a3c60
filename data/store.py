"""Campaign store: the append-only record of finished simulation samples (writer + reader).

Simulation campaigns (:mod:`bubblecal.campaigns`) write it; the surrogate training sets
(:mod:`bubblecal.surrogates.training`) read it.  It lives in the data layer so that both ``sim`` and ``surrogates`` may import
it.  Format version 1 (``'invalid'`` status and ``'ringdown'`` setup added backwards-compatibly: every
older store still reads):

Layout
------
A directory ``STORE/`` holding

* ``store.json`` - header written once, atomically: ``{"format": "bubblecal-campaign-store",
  "format_version": 1, "created_utc": ..., "description": ..., "meta": {...}}``;
* ``records.jsonl`` - **append-only JSON lines**, one record per finished sample (UTF-8, ``\\n``
  terminated). A path ending in ``.jsonl`` is accepted as a bare records file (no header).
* A path ending in ``.jsonl.gz`` is a gzip-compressed bare records file: read-only (how finished training
  sets ship with the package, :func:`export_compressed`).

Record (one JSON object per line; all keys required unless marked optional)
--------------------------------------------------------------------------
=================  ===========================================================================
``v``              record schema version (1)
``sample_id``      str, the design point's id, unique within the campaign (resume key)
``curve_id``       str, globally unique id of this curve (e.g. ``"camp3/lhs-000123/r0"``)
``setup``          ``"compression"`` | ``"indentation"`` | ``"ringdown"``
``params``         {"ka","kb","b1","b2","a3","a4": float} (DPD units, see data/units.py)
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

Robustness
----------
Each record is written with a single ``write`` on a file opened in append mode, then flushed
(and fsync'ed unless ``fsync=False``). A crash mid-write leaves at most one torn last line; the
next writer terminates it with a newline before appending (nothing is ever rewritten), and the
reader skips lines that fail to parse or whose checksum disagrees, reporting them in
:attr:`CampaignStore.problems` and with a warning. When a ``sample_id`` appears more than once
the **last** record wins (a retried 'failed' sample is superseded by its later result).
:meth:`CampaignStore.finished_ids` gives the samples a resumed campaign can skip.
One writing process per store is assumed (Dask: gather results and write from the client).
"""

from __future__ import annotations

import datetime as _dt
import gzip
import json
import math
import os
import warnings
import zlib
from collections.abc import Iterable, Mapping
from pathlib import Path

from bubblecal.data.files import atomic_write
from bubblecal.data.names import PROTOCOLS, RECORD_STATUSES, SHELL_PARAMETERS
from bubblecal.data.names import code_version as running_code_version

__all__ = ["STORE_FORMAT", "STORE_FORMAT_VERSION", "RECORD_VERSION", "StoreError", "CampaignStore", "make_record",
           "validate_record", "export_compressed"]

STORE_FORMAT = "bubblecal-campaign-store"
STORE_FORMAT_VERSION = 1
RECORD_VERSION = 1
REQUIRED = ("v", "sample_id", "curve_id", "setup", "params", "radius_dpd", "x", "y", "status", "seed",
            "tier", "code_version", "provenance", "written_utc")


class StoreError(ValueError):
    """A record or store file is invalid; the message names the file/record and the field."""


def _utc_now() -> str:
    return _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _canonical(obj: Mapping) -> str:
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
    """Build and validate a record (see the module docstring for the fields)."""
    rec = {
        "v": RECORD_VERSION, "sample_id": str(sample_id),
        "curve_id": str(curve_id if curve_id is not None else sample_id), "setup": setup,
        "params": {k: float(params[k]) for k in SHELL_PARAMETERS} if all(k in params for k in SHELL_PARAMETERS) else dict(params),
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
    """Raise :class:`StoreError` naming the field when ``rec`` does not follow the schema."""
    for key in REQUIRED:
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


class CampaignStore:
    """Append-only campaign store at ``path`` (a directory, or a bare ``.jsonl`` file)."""

    def __init__(self, path: str | Path, fsync: bool = True):
        self.path = Path(path)
        self.fsync = fsync
        self.compressed = self.path.name.endswith(".jsonl.gz")
        if self.path.suffix == ".jsonl" or self.compressed:
            self.records_path = self.path
            self.header_path = None
        else:
            self.records_path = self.path / "records.jsonl"
            self.header_path = self.path / "store.json"
        self.problems: list[str] = []
        self._repaired = False

    # -- creation ---------------------------------------------------------------------------------
    @classmethod
    def create(cls, path: str | Path, description: str = "", meta: Mapping | None = None,
               exist_ok: bool = True, fsync: bool = True) -> CampaignStore:
        """Create (or open, with ``exist_ok``) a store directory with its header."""
        store = cls(path, fsync=fsync)
        if store.header_path is None:
            store.records_path.parent.mkdir(parents=True, exist_ok=True)
            store.records_path.touch()
            return store
        if store.header_path.exists():
            if not exist_ok:
                raise FileExistsError(f"campaign store already exists: {store.path}")
            store.header()
            return store
        store.path.mkdir(parents=True, exist_ok=True)
        header = {"format": STORE_FORMAT, "format_version": STORE_FORMAT_VERSION, "created_utc": _utc_now(),
                  "description": description, "meta": dict(meta or {}), "code_version": running_code_version()}
        atomic_write(store.header_path, lambda tmp: tmp.write_text(json.dumps(header, indent=2)))
        store.records_path.touch()
        return store

    def header(self) -> dict:
        """The header of a directory store (validated); ``{}`` for a bare .jsonl file."""
        if self.header_path is None:
            return {}
        if not self.header_path.is_file():
            raise StoreError(f"{self.header_path}: missing store header (not a campaign store directory)")
        try:
            header = json.loads(self.header_path.read_text())
        except json.JSONDecodeError as exc:
            raise StoreError(f"{self.header_path}: not valid JSON ({exc})") from exc
        if header.get("format") != STORE_FORMAT:
            raise StoreError(f"{self.header_path}: field 'format' is {header.get('format')!r}, expected {STORE_FORMAT!r}")
        if header.get("format_version") != STORE_FORMAT_VERSION:
            raise StoreError(f"{self.header_path}: field 'format_version' is {header.get('format_version')!r}, "
                             f"this code reads version {STORE_FORMAT_VERSION}")
        return header

    # -- writing ----------------------------------------------------------------------------------
    def _repair_tail(self) -> None:
        """Terminate a torn last line (crash mid-write) so the next record starts on a fresh line."""
        if self._repaired:
            return
        self._repaired = True
        p = self.records_path
        if p.exists() and p.stat().st_size > 0:
            with open(p, "rb") as fh:
                fh.seek(-1, os.SEEK_END)
                last = fh.read(1)
            if last != b"\n":
                with open(p, "ab") as fh:
                    fh.write(b"\n")

    def append(self, record: Mapping) -> None:
        """Validate and append one record (one write call, flushed and fsync'ed)."""
        self.append_many([record])

    def append_many(self, records: Iterable[Mapping]) -> int:
        """Append several records; each line is complete and checksummed. Returns the count."""
        if self.compressed:
            raise StoreError(f"{self.path}: a compressed (.jsonl.gz) store is read-only; campaigns append to a "
                             f"store directory")
        if self.header_path is not None and not self.header_path.exists():
            raise StoreError(f"{self.path}: not a campaign store (use CampaignStore.create first)")
        lines = []
        for i, rec in enumerate(records):
            rec = {k: v for k, v in dict(rec).items() if k != "crc32"}
            validate_record(rec, where=f"{self.records_path} (record {i} to append)")
            lines.append(_checksummed_line(rec))
        if not lines:
            return 0
        self._repair_tail()
        data = "".join(lines).encode()
        fd = os.open(self.records_path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            view = memoryview(data)
            while view:
                n = os.write(fd, view)
                view = view[n:]
            if self.fsync:
                os.fsync(fd)
        finally:
            os.close(fd)
        return len(lines)

    # -- reading ----------------------------------------------------------------------------------
    def iter_records(self):
        """Yield every valid record in file order (duplicates included); problems collected."""
        self.problems = []
        if self.header_path is not None:
            self.header()
        if not self.records_path.exists():
            raise FileNotFoundError(f"campaign store records not found: {self.records_path}")
        with (gzip.open if self.compressed else open)(self.records_path, "rb") as fh:
            for lineno, raw in enumerate(fh, start=1):
                if not raw.strip():
                    continue
                where = f"{self.records_path}:{lineno}"
                try:
                    rec = json.loads(raw.decode())
                except (UnicodeDecodeError, json.JSONDecodeError):
                    self.problems.append(f"{where}: unreadable line (torn write?) skipped")
                    continue
                if not isinstance(rec, dict) or "crc32" not in rec:
                    self.problems.append(f"{where}: no checksum, skipped")
                    continue
                crc = rec.pop("crc32")
                if zlib.crc32(_canonical(rec).encode()) != crc:
                    self.problems.append(f"{where}: checksum mismatch, skipped")
                    continue
                try:
                    validate_record(rec, where=where)
                except StoreError as exc:
                    self.problems.append(f"{exc}; skipped")
                    continue
                yield rec

    def read(self, statuses: Iterable[str] | None = None, warn: bool = True) -> list[dict]:
        """All records, the last one per ``sample_id`` winning; optionally only some statuses."""
        latest: dict[str, dict] = {}
        for rec in self.iter_records():
            latest.pop(rec["sample_id"], None)
            latest[rec["sample_id"]] = rec
        if self.problems and warn:
            warnings.warn(f"{self.records_path}: {len(self.problems)} line(s) skipped: "
                          + "; ".join(self.problems[:5]), stacklevel=2)
        records = list(latest.values())
        if statuses is not None:
            keep = set(statuses)
            records = [r for r in records if r["status"] in keep]
        return records

    def finished_ids(self, statuses: Iterable[str] = ("ok", "ruptured")) -> set[str]:
        """sample_ids whose latest record has one of ``statuses`` (a resumed campaign skips them)."""
        return {r["sample_id"] for r in self.read(statuses=statuses, warn=False)}

    def counts(self) -> dict[str, int]:
        """Number of samples per status (latest record per sample)."""
        out = dict.fromkeys(RECORD_STATUSES, 0)
        for r in self.read(warn=False):
            out[r["status"]] = out.get(r["status"], 0) + 1
        return out


def export_compressed(store: CampaignStore | str | Path, out: str | Path) -> Path:
    """Write the latest record of every sample of ``store`` (all statuses, checksums kept) to the gzip
    file ``out`` (must end in ``.jsonl.gz``), atomically; a read-only store for shipping finished sets.
    Gzip's header time is fixed so the same records give the same bytes.  Returns ``out``."""
    out = Path(out)
    if not out.name.endswith(".jsonl.gz"):
        raise StoreError(f"{out}: a compressed store's name must end in .jsonl.gz")
    src = store if isinstance(store, CampaignStore) else CampaignStore(store)
    records = src.read()
    if not records:
        raise StoreError(f"{src.path}: no records to export")
    data = "".join(_checksummed_line(rec) for rec in records).encode()

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as raw, gzip.GzipFile(fileobj=raw, mode="wb", compresslevel=9, mtime=0,
                                                   filename="") as gz:
            gz.write(data)

    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(out, write)
    return out
