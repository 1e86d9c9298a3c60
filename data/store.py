"""Campaign store: the append-only record of finished simulation samples (writer + reader).

Simulation campaigns write it; the surrogate training sets read it.  It lives in the data layer so that both
``sim`` and ``surrogates`` may import it.  Store format version 1 (docs/data-formats.md); the records are
described in :mod:`bubblecal.data.records`.

Layout
------
A directory ``STORE/`` holding

* ``store.json`` - header written once, atomically: ``{"format": "bubblecal-campaign-store",
  "format_version": 1, "created_utc": ..., "description": ..., "meta": {...}, "code_version": ...}``;
* ``records.jsonl`` - **append-only JSON lines**, one checksummed record per finished sample (UTF-8,
  ``\\n`` terminated).

A path ending in ``.jsonl`` is accepted as a bare records file (no header).  A path ending in ``.jsonl.gz``
is a gzip-compressed bare records file: read-only (how finished training sets ship with the package,
:func:`export_compressed`).

Robustness
----------
Each append is a single ``write`` on a file opened in append mode, then flushed (and fsync'ed unless
``fsync=False``). A crash mid-write leaves at most one torn last line; the next writer terminates it with a
newline before appending (nothing is ever rewritten), and the reader skips lines that fail to parse or whose
checksum disagrees, reporting them in :attr:`CampaignStore.problems` and with a warning. When a ``sample_id``
appears more than once the **last** record wins (a retried 'failed' sample is superseded by its later result).
:meth:`CampaignStore.finished_ids` gives the samples a resumed campaign can skip.
One writing process per store is assumed (with Dask: gather the results and write from the client).
"""

from __future__ import annotations

import gzip
import json
import os
import warnings
import zlib
from collections.abc import Iterable, Mapping
from pathlib import Path

from bubblecal.data.errors import StoreError
from bubblecal.data.files import atomic_write
from bubblecal.data.names import RECORD_STATUSES
from bubblecal.data.names import code_version as running_code_version
from bubblecal.data.records import _canonical, _checksummed_line, _utc_now, validate_record

__all__ = ["STORE_FORMAT", "STORE_FORMAT_VERSION", "CampaignStore", "export_compressed"]

#: Value of the header's ``format`` field.
STORE_FORMAT = "bubblecal-campaign-store"
#: Store format version written and read by this code.
STORE_FORMAT_VERSION = 1


class CampaignStore:
    """Append-only campaign store at ``path``.

    Opening a store reads nothing; :meth:`create` makes a new one.

    Parameters
    ----------
    path : str or pathlib.Path
        A store directory, a bare ``.jsonl`` records file, or a read-only ``.jsonl.gz`` export.
    fsync : bool
        Fsync the records file after every append (durable against power loss; slower).

    Attributes
    ----------
    path : pathlib.Path
        ``path``.
    compressed : bool
        True for a ``.jsonl.gz`` export (read-only).
    records_path : pathlib.Path
        The records file.
    header_path : pathlib.Path or None
        The header file of a directory store; None for a bare records file.
    problems : list of str
        Lines skipped by the last read (file:line and why).
    """

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
        """Create a store (or open an existing one) with its header and an empty records file.

        Parameters
        ----------
        path : str or pathlib.Path
            A store directory, or a bare ``.jsonl`` records file (created empty, no header).
        description : str
            Free text stored in the header.
        meta : mapping, optional
            Free-form metadata stored in the header (e.g. the campaign configuration).
        exist_ok : bool
            Open an existing store directory instead of failing.
        fsync : bool
            As in :class:`CampaignStore`.

        Returns
        -------
        CampaignStore

        Raises
        ------
        FileExistsError
            If the store directory exists and ``exist_ok`` is False.
        StoreError
            If an existing store's header is invalid.
        """
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
        """The header of a directory store, validated.

        Returns
        -------
        dict
            The parsed ``store.json``; ``{}`` for a bare records file.

        Raises
        ------
        StoreError
            If the header is missing, not JSON, or of another format or format version.
        """
        if self.header_path is None:
            return {}
        if not self.header_path.is_file():
            raise StoreError(f"{self.header_path}: missing store header (not a campaign store directory)")
        try:
            header = json.loads(self.header_path.read_text())
        except json.JSONDecodeError as exc:
            raise StoreError(f"{self.header_path}: not valid JSON ({exc})") from exc
        if header.get("format") != STORE_FORMAT:
            raise StoreError(
                f"{self.header_path}: field 'format' is {header.get('format')!r}, expected {STORE_FORMAT!r}"
            )
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
        """Validate and append one record (one write call, flushed and fsync'ed).

        Parameters
        ----------
        record : mapping
            A record as built by :func:`~bubblecal.data.make_record`.

        Raises
        ------
        StoreError
            As :meth:`append_many`.
        """
        self.append_many([record])

    def append_many(self, records: Iterable[Mapping]) -> int:
        """Validate and append several records in one write; each line is complete and checksummed.

        Parameters
        ----------
        records : iterable of mapping
            Records as built by :func:`~bubblecal.data.make_record`; an old ``crc32`` is replaced.

        Returns
        -------
        int
            Number of records appended.

        Raises
        ------
        StoreError
            If the store is a read-only ``.jsonl.gz`` export, a directory without a header, or a record is
            invalid (nothing is written then).
        """
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
        """Yield every valid record in file order, duplicates included.

        Lines that do not parse, lack or fail their checksum, or break the schema are skipped and listed in
        :attr:`problems`.

        Yields
        ------
        dict
            A record without its ``crc32``.

        Raises
        ------
        StoreError
            If a directory store's header is invalid.
        FileNotFoundError
            If the records file does not exist.
        """
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
        """The latest record of every sample.

        Parameters
        ----------
        statuses : iterable of str, optional
            Keep only samples whose latest record has one of these statuses (default: all).
        warn : bool
            Warn (``UserWarning``) when lines were skipped.

        Returns
        -------
        list of dict
            One record per ``sample_id`` (the last one written wins), ordered by when each sample's latest
            record was written.

        Raises
        ------
        StoreError
            If a directory store's header is invalid.
        FileNotFoundError
            If the records file does not exist.
        """
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
        """The samples a resumed campaign skips.

        Parameters
        ----------
        statuses : iterable of str
            Statuses that count as finished.

        Returns
        -------
        set of str
            The ``sample_id`` of every sample whose latest record has one of ``statuses``.
        """
        return {r["sample_id"] for r in self.read(statuses=statuses, warn=False)}

    def counts(self) -> dict[str, int]:
        """Number of samples per status, counting each sample's latest record.

        Returns
        -------
        dict of str to int
            Every status of :data:`~bubblecal.data.RECORD_STATUSES` (zero included).
        """
        out = dict.fromkeys(RECORD_STATUSES, 0)
        for r in self.read(warn=False):
            out[r["status"]] = out.get(r["status"], 0) + 1
        return out


def export_compressed(store: CampaignStore | str | Path, out: str | Path) -> Path:
    """Write the latest record of every sample of a store to a read-only gzip store, atomically.

    All statuses are kept, with their checksums. Gzip's header time and file name are fixed, so the same
    records give the same bytes. This is how finished training sets ship with the package.

    Parameters
    ----------
    store : CampaignStore or str or pathlib.Path
        The store to export.
    out : str or pathlib.Path
        The output file; its name must end in ``.jsonl.gz``.

    Returns
    -------
    pathlib.Path
        ``out``.

    Raises
    ------
    StoreError
        If ``out`` does not end in ``.jsonl.gz``, the store's header is invalid, or the store holds no records.
    """
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
