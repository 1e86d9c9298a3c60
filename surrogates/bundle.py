"""Surrogate bundles: a directory of surrogate files with a ``manifest.json``; the shipped default bundle.

Format ``bubblecal-surrogate-bundle``, version 1 (docs/data-formats.md): a directory holding the mechanical
``.npz`` files (:mod:`bubblecal.surrogates.surrogate_file`), acoustic JSON files (per-diameter quadratics,
:mod:`bubblecal.surrogates.acoustic`, or laws continuous in the diameter, :mod:`bubblecal.surrogates.acoustic_law`;
each file's ``format_version`` says which) and ``manifest.json``::

    {"format": "bubblecal-surrogate-bundle", "format_version": 1, "created_utc": "...",
     "surrogates": [{"file": "compression_2.1um.npz", "setup": "compression",
                     "diameter_um": 2.1, "data_hash": "...", "holdout_score": 0.004},
                    {"file": "compression_1.5-8um.npz", "setup": "compression",
                     "diameter_range_um": [1.5, 8.0], "data_hash": "...", ...},
                    {"file": "compression_1.5-8um_fast.npz", "setup": "compression", "network": "fast",
                     "diameter_range_um": [1.5, 8.0], "data_hash": "...", ...}, ...],
     "acoustic": [{"file": "acoustic_definity.json", "name": "definity"},
                  {"file": "acoustic_definity_1.5-11.2um.json", "name": "definity",
                   "diameter_range_um": [1.5, 11.2]}, ...],
     "notes": "free text"}

A name has at most one file of each kind. Mechanical and acoustic lookups prefer the per-diameter files
(:meth:`Bundle.get`, :meth:`Bundle.acoustic_for`): the networks and laws over the diameter answer the other
diameters of their range. A protocol has at most one network over the diameter per role (``network``:
``'accurate'``, the default when the field is missing, or ``'fast'``; :mod:`bubblecal.surrogates.bundle_networks`).
The package ships a default bundle (package data ``bubblecal/surrogates/bundle/``, :func:`default_bundle_path`);
:func:`~bubblecal.surrogates.write_bundle` (:mod:`bubblecal.surrogates.bundle_write`) writes one. Nothing here
imports torch or onnx.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bubblecal.surrogates.acoustic import AcousticFormatError, AcousticRangeError, AcousticSurrogate
from bubblecal.surrogates.acoustic_law import AcousticLawSurrogate
from bubblecal.surrogates.bundle_networks import DEFAULT_NETWORK, NETWORK_ROLES, entry_network, lookup_order
from bubblecal.surrogates.fileio import read_versioned_json
from bubblecal.surrogates.surrogate import Surrogate
from bubblecal.surrogates.surrogate_file import SurrogateFormatError, load

__all__ = ["BUNDLE_FORMAT", "BUNDLE_FORMAT_VERSION", "DIAMETER_ATOL_UM", "Bundle", "load_bundle",
           "default_bundle_path", "NoDefaultBundleError"]

#: ``format`` of a bundle manifest.
BUNDLE_FORMAT = "bubblecal-surrogate-bundle"
#: ``format_version`` written and read.
BUNDLE_FORMAT_VERSION = 1
#: Largest gap [um] between a requested diameter and a per-diameter surrogate's data or nominal diameter (the
#: "3.2 um" SonoVue data have radius 6.38 DPD, 3.19 um).
DIAMETER_ATOL_UM = 0.025


@dataclass
class Bundle:
    """A loaded bundle: mechanical surrogates by (setup, diameter_um) or over the diameter; acoustic ones by name.

    Parameters
    ----------
    path : Path
        The bundle directory.
    manifest : dict
        Its ``manifest.json``.
    surrogates : dict of (str, float) to Surrogate
        Per-diameter mechanical surrogates keyed by (loading protocol, data diameter [um]).
    acoustic : dict of str to AcousticSurrogate
        Per-diameter acoustic quadratics (file version 1) keyed by name (e.g. ``'definity'``).
    over_diameter : dict of str to Surrogate
        The accurate mechanical networks over the diameter keyed by loading protocol (at most one each).
    acoustic_law : dict of str to AcousticLawSurrogate
        Acoustic laws continuous in the diameter (file version 2) keyed by name (at most one each).
    fast : dict of str to Surrogate
        The fast mechanical networks over the diameter (manifest ``network = 'fast'``) keyed by loading protocol
        (at most one each).
    """

    path: Path
    manifest: dict
    surrogates: dict[tuple[str, float], Surrogate] = field(default_factory=dict)
    acoustic: dict[str, object] = field(default_factory=dict)
    over_diameter: dict[str, Surrogate] = field(default_factory=dict)
    acoustic_law: dict[str, AcousticLawSurrogate] = field(default_factory=dict)
    fast: dict[str, Surrogate] = field(default_factory=dict)

    def _wide(self, role: str) -> dict[str, Surrogate]:
        """The networks over the diameter of ``role``, keyed by loading protocol."""
        return self.fast if role == "fast" else self.over_diameter

    def networks(self, setup: str) -> tuple[str, ...]:
        """Roles of the networks over the diameter the bundle has for ``setup``.

        Parameters
        ----------
        setup : {'compression', 'indentation'}
            Loading protocol.

        Returns
        -------
        tuple of str
            The roles present, in the order of :data:`~bubblecal.surrogates.NETWORK_ROLES` (empty when none).
        """
        return tuple(r for r in NETWORK_ROLES if setup in self._wide(r))

    def get(self, setup: str, diameter_um: float, atol: float = DIAMETER_ATOL_UM,
            prefer: str = "per-diameter", network: str = DEFAULT_NETWORK) -> Surrogate:
        """The surrogate for ``setup`` at ``diameter_um``: a per-diameter one, or the network over the diameter.

        A per-diameter surrogate matches within ``atol`` of its data or nominal diameter (nominal diameters name
        the data sets: the "3.2 um" SonoVue set has data diameter 3.19 um); a network over the diameter matches
        every diameter of its range and is returned bound to ``diameter_um``
        (:meth:`~bubblecal.surrogates.Surrogate.at_diameter`). ``network`` picks which network over the diameter
        answers: ``'fast'`` falls back to the accurate one, with no error, where the bundle has no fast network
        covering the diameter (:meth:`networks` tells); per-diameter files have no role and answer by ``prefer``.

        Parameters
        ----------
        setup : {'compression', 'indentation'}
            Loading protocol.
        diameter_um : float
            Bubble diameter [um].
        atol : float
            Largest accepted gap to a per-diameter surrogate [um].
        prefer : {'per-diameter', 'over-diameter'}
            Which kind answers when both match.
        network : {'accurate', 'fast'}
            Role of the network over the diameter (:mod:`bubblecal.surrogates.bundle_networks`).

        Returns
        -------
        Surrogate
            The matching surrogate.

        Raises
        ------
        KeyError
            When none matches (the message lists what the bundle has).
        ValueError
            For an unknown ``prefer`` or ``network`` (the message names the allowed values).
        """
        if prefer not in ("per-diameter", "over-diameter"):
            raise ValueError(f"prefer must be 'per-diameter' or 'over-diameter', got {prefer!r}")
        roles = lookup_order(network)
        best, best_gap = None, math.inf
        for (s, d), sur in self.surrogates.items():
            if s != setup:
                continue
            nominal = float(sur.metadata.get("nominal_diameter_um", d))
            gap = min(abs(d - float(diameter_um)), abs(nominal - float(diameter_um)))
            if gap < best_gap:
                best, best_gap = sur, gap
        per = best if best is not None and best_gap <= atol else None
        covering = [w for w in (self._wide(r).get(setup) for r in roles)
                    if w is not None and w.diameter_range_um[0] <= float(diameter_um) <= w.diameter_range_um[1]]
        if covering and (per is None or prefer == "over-diameter"):
            return covering[0].at_diameter(float(diameter_um))
        if per is not None:
            return per
        have = [f"{s} {d:g} um" for s, d in sorted(self.surrogates)]
        have += [f"{s} {w.diameter_range_um[0]:g}-{w.diameter_range_um[1]:g} um (over the diameter"
                 + (", fast)" if r == "fast" else ")")
                 for r in NETWORK_ROLES for s, w in sorted(self._wide(r).items())]
        raise KeyError(f"bundle {self.path} has no {setup} surrogate at {diameter_um:g} um "
                       f"(has: {', '.join(have) or 'none'})")

    def keys(self):
        """Sorted (setup, diameter_um) keys of the mechanical surrogates."""
        return sorted(self.surrogates)

    def acoustic_for(self, name: str, diameter_um, prefer: str = "per-diameter") -> AcousticSurrogate:
        """The acoustic surrogate of ``name`` for a set of diameters: the per-diameter quadratics, or the law.

        The per-diameter quadratics answer when they were fitted at every requested diameter; otherwise (or
        with ``prefer='over-diameter'``) the law continuous in the diameter answers when its range holds every
        requested diameter. One surrogate serves all the diameters (a dataset is never split between the two).

        Parameters
        ----------
        name : str
            Agent or label (e.g. ``'definity'``).
        diameter_um : float or array_like
            Bubble diameter(s) [um].
        prefer : {'per-diameter', 'over-diameter'}
            Which kind answers when both cover the diameters.

        Returns
        -------
        AcousticSurrogate
            The per-diameter quadratics or an :class:`~bubblecal.surrogates.AcousticLawSurrogate`.

        Raises
        ------
        AcousticRangeError
            When neither covers every diameter, or the bundle has no acoustic surrogate ``name`` (the message
            names the diameters outside and what the bundle has).
        ValueError
            For an unknown ``prefer``.
        """
        if prefer not in ("per-diameter", "over-diameter"):
            raise ValueError(f"prefer must be 'per-diameter' or 'over-diameter', got {prefer!r}")
        d = np.atleast_1d(np.asarray(diameter_um, dtype=float)).ravel()
        per, law = self.acoustic.get(name), self.acoustic_law.get(name)
        per_ok = per is not None and all(np.any(np.abs(np.asarray(per.diameters) - v) <= 1e-6) for v in d)
        lo, hi = law.diameter_range if law is not None else (math.nan, math.nan)
        law_ok = law is not None and bool(np.all((d >= lo - 1e-9) & (d <= hi + 1e-9)))
        if per_ok and not (law_ok and prefer == "over-diameter"):
            return per
        if law_ok:
            return law
        have = ([f"quadratics at {', '.join(f'{x:g}' for x in per.diameters)} um"] if per is not None else [])
        have += [f"a law over {lo:g}-{hi:g} um"] if law is not None else []
        outside = [f"{v:g}" for v in np.unique(d) if not (lo - 1e-9 <= v <= hi + 1e-9)] if law is not None else []
        raise AcousticRangeError(
            f"bundle {self.path}: no acoustic surrogate {name!r} covers the diameter(s) "
            f"{', '.join(outside or [f'{v:g}' for v in np.unique(d)])} um (has: {'; '.join(have) or 'none'}; "
            f"acoustic names: {', '.join(sorted(set(self.acoustic) | set(self.acoustic_law))) or 'none'})")


def load_bundle(path: str | Path) -> Bundle:
    """Load a bundle directory (``manifest.json`` + files), checking each file against its manifest entry.

    Parameters
    ----------
    path : str or Path
        The bundle directory.

    Returns
    -------
    Bundle
        Every mechanical and acoustic surrogate of the manifest.

    Raises
    ------
    FileNotFoundError
        When the manifest or a listed file is missing.
    SurrogateFormatError
        As :func:`_load_bundle`, and for a manifest or acoustic file whose fields have the wrong types (a
        number where a name belongs, a list where a table belongs), naming the manifest.
    AcousticFormatError
        For a malformed acoustic file.
    """
    try:
        return _load_bundle(path)  # acoustic files check their own fields' types on load
    except (SurrogateFormatError, AcousticFormatError, FileNotFoundError):
        raise
    except (TypeError, AttributeError, KeyError, IndexError, ValueError) as exc:  # a field of the wrong type
        raise SurrogateFormatError(f"{Path(path) / 'manifest.json'}: malformed bundle (a field or a listed file "
                                   f"has the wrong type: {type(exc).__name__}: {exc})") from None


def _load_bundle(path: str | Path) -> Bundle:
    """:func:`load_bundle` without the translation of wrongly typed fields (same arguments and errors)."""
    path = Path(path)
    mpath = path / "manifest.json"
    manifest = read_versioned_json(mpath, BUNDLE_FORMAT, BUNDLE_FORMAT_VERSION, SurrogateFormatError,
                                   "bundle manifest")
    bundle = Bundle(path=path, manifest=manifest)
    for i, entry in enumerate(manifest.get("surrogates", [])):
        wide = "diameter_range_um" in entry
        for key in ("file", "setup", "diameter_range_um" if wide else "diameter_um", "data_hash"):
            if key not in entry:
                raise SurrogateFormatError(f"{mpath}: surrogates[{i}] lacks field '{key}'")
        sur = load(path / entry["file"])
        if sur.data_hash != entry["data_hash"]:
            raise SurrogateFormatError(f"{mpath}: surrogates[{i}] field 'data_hash' {entry['data_hash'][:12]}... "
                                       f"does not match {entry['file']} ({sur.data_hash[:12]}...)")
        role = entry_network(entry, i, mpath, wide)
        if wide:
            if sur.setup != entry["setup"] or not sur.over_diameter or not all(
                    math.isclose(a, float(b), abs_tol=1e-9)
                    for a, b in zip(sur.diameter_range_um, entry["diameter_range_um"], strict=True)):
                raise SurrogateFormatError(f"{mpath}: surrogates[{i}] setup/diameter_range_um disagree with "
                                           f"{entry['file']}")
            if sur.setup in bundle._wide(role):
                raise SurrogateFormatError(f"{mpath}: surrogates[{i}] ({entry['file']}): a second {role!r} "
                                           f"{sur.setup} network over the diameter")
            bundle._wide(role)[sur.setup] = sur
            continue
        if sur.over_diameter or sur.setup != entry["setup"] or not math.isclose(
                sur.diameter_um, float(entry["diameter_um"]), abs_tol=1e-9):
            raise SurrogateFormatError(f"{mpath}: surrogates[{i}] setup/diameter_um disagree with {entry['file']}")
        key = (sur.setup, sur.diameter_um)
        if key in bundle.surrogates:
            raise SurrogateFormatError(f"{mpath}: two surrogates for {sur.setup} {sur.diameter_um:g} um")
        bundle.surrogates[key] = sur
    for i, entry in enumerate(manifest.get("acoustic", [])):
        for key in ("file", "name"):
            if key not in entry:
                raise SurrogateFormatError(f"{mpath}: acoustic[{i}] lacks field '{key}'")
        ac = AcousticSurrogate.load(path / entry["file"])  # the file's format_version picks the class
        kind = bundle.acoustic_law if isinstance(ac, AcousticLawSurrogate) else bundle.acoustic
        if entry["name"] in kind:
            raise SurrogateFormatError(f"{mpath}: acoustic[{i}]: a second "
                                       f"{'law' if kind is bundle.acoustic_law else 'per-diameter file'} "
                                       f"named {entry['name']!r}")
        if "diameter_range_um" in entry and not (kind is bundle.acoustic_law and all(
                math.isclose(a, float(b), abs_tol=1e-9)
                for a, b in zip(ac.diameter_range, entry["diameter_range_um"], strict=True))):
            raise SurrogateFormatError(f"{mpath}: acoustic[{i}] field 'diameter_range_um' "
                                       f"{entry['diameter_range_um']!r} disagrees with {entry['file']}")
        kind[entry["name"]] = ac
    return bundle


class NoDefaultBundleError(FileNotFoundError):
    """The shipped surrogate bundle (package data ``bubblecal/surrogates/bundle/``) is not installed."""


def default_bundle_path(must_exist: bool = False) -> Path:
    """Directory of the shipped surrogate bundle (package data ``bubblecal/surrogates/bundle/``).

    Parameters
    ----------
    must_exist : bool
        Check that the directory holds a ``manifest.json``.

    Returns
    -------
    Path
        The directory.

    Raises
    ------
    NoDefaultBundleError
        With ``must_exist=True`` when there is no manifest (the message points at ``--bundle DIR`` and
        ``bubblecal surrogates synthetic-bundle DIR``).
    """
    path = Path(__file__).resolve().parent / "bundle"
    if must_exist and not (path / "manifest.json").is_file():
        raise NoDefaultBundleError(
            f"no shipped surrogate bundle found at {path}; pass --bundle DIR (e.g. a development bundle written "
            "by `bubblecal surrogates synthetic-bundle DIR`, SYNTHETIC closed-form laws, not DPD)")
    return path
