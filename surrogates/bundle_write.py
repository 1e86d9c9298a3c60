"""Write a surrogate bundle: copy the files into a directory and write its ``manifest.json``.

The format is :mod:`bubblecal.surrogates.bundle`'s; the roles of the networks over the diameter are
:mod:`bubblecal.surrogates.bundle_networks`'. Nothing here imports torch or onnx.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Iterable, Mapping
from pathlib import Path

from bubblecal.data import code_version
from bubblecal.surrogates.acoustic import AcousticSurrogate
from bubblecal.surrogates.acoustic_law import AcousticLawSurrogate
from bubblecal.surrogates.bundle import BUNDLE_FORMAT, BUNDLE_FORMAT_VERSION
from bubblecal.surrogates.bundle_networks import DEFAULT_NETWORK
from bubblecal.surrogates.fileio import atomic_write_bytes, utc_now
from bubblecal.surrogates.surrogate_file import SurrogateFormatError, load

__all__ = ["write_bundle"]


def write_bundle(path: str | Path, surrogate_files: Iterable[str | Path] = (),
                 acoustic_files: Mapping[str, str | Path] | None = None, notes: str = "",
                 fast_files: Iterable[str | Path] = ()) -> Path:
    """Copy surrogate ``.npz`` files and acoustic JSON files into ``path`` and write ``manifest.json``.

    Every file is loaded (validated) first; files already inside ``path`` are not copied. Entries over the
    diameter record their role in ``network``: ``'accurate'`` for ``surrogate_files``, ``'fast'`` for
    ``fast_files``. Two networks over the diameter of one role for one protocol, or two files of one name, are
    refused before anything is copied.

    Parameters
    ----------
    path : str or Path
        The bundle directory (created when missing).
    surrogate_files : iterable of str or Path
        Mechanical surrogate files.
    acoustic_files : Mapping of str to (str or Path or sequence of them), optional
        Acoustic surrogate files keyed by name (e.g. ``'definity'``): per-diameter quadratics, a law over the
        diameter, or one of each.
    notes : str
        Free text stored in the manifest.
    fast_files : iterable of str or Path
        Fast mechanical networks over the diameter (:mod:`bubblecal.surrogates.bundle_networks`).

    Returns
    -------
    Path
        The manifest path.

    Raises
    ------
    FileNotFoundError, SurrogateFormatError, AcousticFormatError
        When a file is missing or malformed, a fast file is not a network over the diameter, a role of a
        protocol is given twice, or two surrogate files share a name.
    """
    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    entries = []
    roles: dict[tuple[str, str], Path] = {}
    loaded = []
    mechanical = [(Path(f), DEFAULT_NETWORK) for f in surrogate_files] + [(Path(f), "fast") for f in fast_files]
    names = [f.name for f, _ in mechanical]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:  # one would overwrite the other's copy
        raise SurrogateFormatError(f"{path}: two surrogate files named {', '.join(twice)}")
    for f, role in mechanical:
        sur = load(f)
        if role != DEFAULT_NETWORK and not sur.over_diameter:
            raise SurrogateFormatError(f"{f}: a {role} network must be a network over the diameter (this one is "
                                       f"per diameter, {sur.diameter_um:g} um)")
        if sur.over_diameter:
            if (sur.setup, role) in roles:
                raise SurrogateFormatError(f"{f}: a second {role!r} {sur.setup} network over the diameter (the "
                                           f"first: {roles[sur.setup, role]})")
            roles[sur.setup, role] = f
        loaded.append((f, role, sur))
    for f, role, sur in loaded:
        dest = path / f.name
        if f.resolve() != dest.resolve():
            shutil.copyfile(f, dest)
        size = ({"diameter_range_um": list(sur.diameter_range_um), "ldo_score": sur.metadata.get("ldo_score"),
                 "network": role} if sur.over_diameter else {"diameter_um": sur.diameter_um})
        entries.append({"file": f.name, "setup": sur.setup, **size, "data_hash": sur.data_hash,
                        "holdout_score": sur.holdout_score, "architecture": sur.architecture})
    acoustic_entries = []
    for name, files in (acoustic_files or {}).items():
        for f in [files] if isinstance(files, (str, Path)) else files:
            f = Path(f)
            ac = AcousticSurrogate.load(f)  # validate
            dest = path / f.name
            if f.resolve() != dest.resolve():
                shutil.copyfile(f, dest)
            wide = {"diameter_range_um": list(ac.diameter_range)} if isinstance(ac, AcousticLawSurrogate) else {}
            acoustic_entries.append({"file": f.name, "name": name, **wide})
    manifest = {"format": BUNDLE_FORMAT, "format_version": BUNDLE_FORMAT_VERSION, "created_utc": utc_now(),
                "code_version": code_version(), "surrogates": entries, "acoustic": acoustic_entries,
                "notes": notes}
    mpath = path / "manifest.json"
    atomic_write_bytes(mpath, lambda fh: fh.write(json.dumps(manifest, indent=2).encode()))
    return mpath
