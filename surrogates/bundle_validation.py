"""Measured validation figures of a bundle's networks over the diameter (``validation.json`` beside the manifest).

The file records what the benchmarks measured for each network over the diameter, so that ``bubblecal surrogates
info`` shows it next to the training scores: the fidelity gate of its training curves (quasi-static against the
explicit tier at diameters the paper never simulated) and its error against the published Mirheo rows beside the
per-diameter network's.  Layout (``format_version`` 1)::

    {"format": "bubblecal-bundle-validation", "format_version": 1,
     "networks": {"compression_1.5-8um.npz": {
         "explicit_tier": {"gate": 0.03, "source": "...", "rows": [{"diameter_um": 1.8, "median": 0.0163, "n": 7}]},
         "published_rows": {"gate": 0.05, "source": "...",
                            "rows": [{"diameter_um": 2.1, "median": 0.0325, "per_diameter": 0.0327}]}}}}

Medians are relative L2 (fractions); ``source`` names the command, machine and date of the measurement.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

from bubblecal.surrogates.surrogate_file import SurrogateFormatError

__all__ = ["VALIDATION_FILE", "VALIDATION_KINDS", "load_validation", "validation_lines"]

#: File name of the validation figures inside a bundle directory.
VALIDATION_FILE = "validation.json"
#: The kinds of figures a network may have, with their meaning in ``surrogates info``.
VALIDATION_KINDS = {"explicit_tier": "training curves vs the explicit tier at new diameters",
                    "published_rows": "against the published Mirheo rows (per-diameter network in brackets)"}


def load_validation(bundle_dir: str | Path) -> dict:
    """The validation figures of a bundle, checked.

    Parameters
    ----------
    bundle_dir : str or Path
        A bundle directory.

    Returns
    -------
    dict
        Network file name -> kind -> {"gate", "source", "rows"}; empty when the bundle has no validation file.

    Raises
    ------
    SurrogateFormatError
        If the file is not valid JSON of the layout above (the message names the file and the field).
    """
    path = Path(bundle_dir) / VALIDATION_FILE
    if not path.is_file():
        return {}
    try:
        doc = json.loads(path.read_text())
    except ValueError as exc:
        raise SurrogateFormatError(f"{path}: not JSON ({exc})") from None
    if not isinstance(doc, Mapping) or doc.get("format") != "bubblecal-bundle-validation" \
            or doc.get("format_version") != 1:
        raise SurrogateFormatError(f"{path}: field 'format' / 'format_version' must be 'bubblecal-bundle-validation' "
                                   "/ 1")
    networks = doc.get("networks")
    if not isinstance(networks, Mapping):
        raise SurrogateFormatError(f"{path}: field 'networks' must map network file names to their figures")
    for name, kinds in networks.items():
        for kind, block in (kinds or {}).items():
            where = f"{path}: networks.{name}.{kind}"
            if kind not in VALIDATION_KINDS:
                raise SurrogateFormatError(f"{where}: unknown kind; allowed: {', '.join(VALIDATION_KINDS)}")
            rows = block.get("rows") if isinstance(block, Mapping) else None
            if not isinstance(rows, list) or not rows:
                raise SurrogateFormatError(f"{where}: field 'rows' must be a non-empty list")
            for k, row in enumerate(rows):
                if not isinstance(row, Mapping) or not all(isinstance(row.get(f), (int, float))
                                                           for f in ("diameter_um", "median")):
                    raise SurrogateFormatError(f"{where}.rows[{k}]: needs numbers 'diameter_um' and 'median'")
    return {name: dict(kinds or {}) for name, kinds in networks.items()}


def validation_lines(figures: Mapping, file_name: str) -> list[str]:
    """Lines of ``surrogates info`` for one network: one per kind of figure, each row 'D um: median %'.

    Parameters
    ----------
    figures : Mapping
        :func:`load_validation`'s result.
    file_name : str
        The network's file name in the bundle.

    Returns
    -------
    list of str
        Empty when the network has no figures.
    """
    lines = []
    for kind, block in figures.get(file_name, {}).items():
        parts = []
        for row in block["rows"]:
            text = f"{row['diameter_um']:g} um {100 * row['median']:.2f} %"
            if row.get("per_diameter") is not None:
                text += f" [{100 * row['per_diameter']:.2f} %]"
            if row.get("n") is not None:
                text += f" ({row['n']} sets)"
            parts.append(text)
        gate = f"; gate {100 * block['gate']:g} %" if block.get("gate") is not None else ""
        lines.append(f"  {VALIDATION_KINDS[kind]}: " + ", ".join(parts) + gate
                     + (f" ({block['source']})" if block.get("source") else ""))
    return lines
