"""The published study as one instance of the tidy format: ``published_curves.csv`` and ``published_resonance.csv``.

Both files in ``data/reference/`` are written by :func:`write_published_tidy` from the shipped per-curve source
files and the acoustic table (never by hand); the test suite checks that reading them gives the DPD arrays of
:func:`~bubblecal.data.load_reference` and the frequencies of :func:`~bubblecal.data.acoustic_observations`.
Bubble ids are ``<agent>-<nominal diameter>um``; the ``diameter_um`` column holds the measured diameter that
sets the DPD geometry.
"""

from __future__ import annotations

import csv
from importlib import resources
from pathlib import Path

from bubblecal.data.acoustic import acoustic_observations
from bubblecal.data.curves import KINDS
from bubblecal.data.files import atomic_write
from bubblecal.data.reference import REFERENCE_CURVES, reference_curves
from bubblecal.data.tidy import CURVE_COLUMNS, CURVE_OPTIONAL, RESONANCE_COLUMNS, RESONANCE_OPTIONAL

__all__ = ["PUBLISHED_CURVES_FILE", "PUBLISHED_RESONANCE_FILE", "published_tidy_paths", "write_published_tidy"]

#: File name of the published curves in the tidy format (package data in ``data/reference/``).
PUBLISHED_CURVES_FILE = "published_curves.csv"
#: File name of the published resonance rows in the tidy format (package data in ``data/reference/``).
PUBLISHED_RESONANCE_FILE = "published_resonance.csv"


def published_tidy_paths() -> tuple[Path, Path]:
    """Paths of the shipped tidy files.

    Returns
    -------
    tuple of pathlib.Path
        (curves, resonance) in the package's ``data/reference`` folder.
    """
    folder = Path(str(resources.files("bubblecal.data") / "reference"))
    return folder / PUBLISHED_CURVES_FILE, folder / PUBLISHED_RESONANCE_FILE


def _curve_rows() -> list[list[str]]:
    """One row per source point of the six shipped curves, in physical units as shipped."""
    rows = []
    for curve in reference_curves():
        agent, kind, nominal, measured, _ = REFERENCE_CURVES[curve.name]
        src = curve.source_curve
        axes = dict(zip(KINDS[kind], (src.x, src.y), strict=True))
        for d, f, keep in zip(axes["displacement"], axes["force"], src.retained, strict=True):
            rows.append([f"{agent}-{nominal:g}um", agent, kind, repr(float(measured)), repr(float(d)),
                         repr(float(f)), "1" if keep else "0"])
    return rows


def _write_csv(path: Path, header: tuple[str, ...], rows: list[list[str]]) -> Path:
    """Write a headed CSV atomically."""
    def writer(tmp: Path) -> None:
        with open(tmp, "w", newline="", encoding="utf-8") as handle:
            out = csv.writer(handle, lineterminator="\n")
            out.writerow(header)
            out.writerows(rows)
    return atomic_write(path, writer)


def write_published_tidy(folder: str | Path | None = None) -> tuple[Path, Path]:
    """Write the published curves and resonance rows in the tidy format.

    Parameters
    ----------
    folder : str or pathlib.Path, optional
        Target folder (default: the package's ``data/reference``, where the shipped copies live).

    Returns
    -------
    tuple of pathlib.Path
        The curves file and the resonance file written.
    """
    curves_path, resonance_path = published_tidy_paths()
    if folder is not None:
        curves_path, resonance_path = Path(folder) / curves_path.name, Path(folder) / resonance_path.name
    _write_csv(curves_path, CURVE_COLUMNS + CURVE_OPTIONAL, _curve_rows())
    resonance = [[o.agent, repr(float(o.diameter_um)), repr(float(o.frequency_MHz)),
                  f"{o.source}, {o.source_figure}"] for o in acoustic_observations()]
    _write_csv(resonance_path, RESONANCE_COLUMNS + RESONANCE_OPTIONAL, resonance)
    return curves_path, resonance_path
