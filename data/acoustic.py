"""Acoustic resonance observations: the shipped table, its reader and its grouping into datasets.

In the hierarchy each acoustic dataset has its own latent shell parameters: Definity's 14
bubbles (Goertz et al. 2006) form one dataset, SonoVue's 3 bubbles (van der Meer et al. 2004)
three datasets (docs/inference.md section 3).  Diameters are in um, frequencies in MHz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from bubblecal.data.errors import DataError
from bubblecal.data.names import AGENTS
from bubblecal.data.plausibility import plausibility_problems
from bubblecal.data.readers import read_csv_rows, separator_hint

__all__ = ["AcousticObservation", "AcousticDataset", "acoustic_observations", "acoustic_datasets",
           "load_acoustic_table"]

_COLUMNS = ("agent", "source", "source_figure", "diameter_um", "resonance_frequency_MHz")


@dataclass(frozen=True)
class AcousticObservation:
    """One bubble's measured resonance.

    Parameters
    ----------
    agent : str
        'definity' or 'sonovue'.
    diameter_um : float
        Bubble diameter [um].
    frequency_MHz : float
        Measured resonance frequency [MHz].
    source : str
        Citation of the measurement.
    source_figure : str
        Figure of the source the value was read from.
    """

    agent: str
    diameter_um: float
    frequency_MHz: float
    source: str
    source_figure: str


@dataclass(frozen=True)
class AcousticDataset:
    """A group of observations sharing one latent parameter set in the hierarchy.

    Parameters
    ----------
    name : str
        Dataset name, e.g. ``"definity_acoustic"`` or ``"sonovue_acoustic_2.6um"``.
    agent : str
        'definity' or 'sonovue'.
    diameter_um : numpy.ndarray
        Bubble diameters [um].
    frequency_MHz : numpy.ndarray
        Measured resonance frequencies [MHz], same length as ``diameter_um``.
    source : str
        Citation of the measurements.
    """

    name: str
    agent: str
    diameter_um: np.ndarray
    frequency_MHz: np.ndarray
    source: str

    @property
    def n_points(self) -> int:
        """Number of bubbles in the dataset."""
        return int(self.diameter_um.size)


def load_acoustic_table(path: str | Path) -> list[AcousticObservation]:
    """Read and validate an acoustic observations table.

    Parameters
    ----------
    path : str or pathlib.Path
        A headed CSV file with the columns agent, source, source_figure, diameter_um [um] and
        resonance_frequency_MHz [MHz] (more columns are ignored); agent is case-insensitive.

    Returns
    -------
    list of AcousticObservation
        One per row, in file order.

    Raises
    ------
    DataError
        If the file is missing, unreadable, not UTF-8 or lacks a column (a semicolon-separated header is named),
        or listing every bad cell with row and column: a ragged row, an unknown agent, a diameter or frequency
        that is not a finite number > 0 or lies outside its plausible range
        (:data:`~bubblecal.data.PLAUSIBLE_RANGES`). A UTF-8 byte-order mark is accepted.
    """
    path = Path(path)
    problems: list[str] = []
    rows = [r for r in read_csv_rows(path) if any(cell.strip() for cell in r)]
    header = [h.strip() for h in rows[0]] if rows else []
    hint = separator_hint(header)
    missing = [c for c in _COLUMNS if c not in header]
    if missing:
        raise DataError(path, [f"header: missing column(s) {', '.join(missing)} (found: {', '.join(header) or 'none'})"
                               + hint])
    out = []
    checked: dict[str, list[tuple[str, float]]] = {"diameter_um": [], "resonance_frequency_MHz": []}
    for k, cells in enumerate(rows[1:], start=1):
        if len(cells) != len(header):
            problems.append(f"row {k}: {len(cells)} cells, expected {len(header)}")
            continue
        row = dict(zip(header, (c.strip() for c in cells), strict=True))
        agent = row["agent"].lower()
        if agent not in AGENTS:
            problems.append(f"row {k}, column 'agent': {row['agent']!r} not one of {', '.join(AGENTS)}")
        values = {}
        for col in ("diameter_um", "resonance_frequency_MHz"):
            try:
                value = float(row[col])
            except ValueError:
                problems.append(f"row {k}, column {col!r}: {row[col]!r} is not a number")
                continue
            if not math.isfinite(value) or value <= 0:
                problems.append(f"row {k}, column {col!r}: {value} must be finite and > 0")
                continue
            values[col] = value
            checked[col].append((f"row {k}, column {col!r}", value))
        if len(values) == 2 and agent in AGENTS:
            out.append(AcousticObservation(agent, values["diameter_um"], values["resonance_frequency_MHz"],
                                           row["source"], row["source_figure"]))
    for col, quantity in (("diameter_um", "diameter"), ("resonance_frequency_MHz", "resonance_frequency")):
        labels = [label for label, _ in checked[col]]
        problems += plausibility_problems(quantity, [v for _, v in checked[col]], labels)
    if problems:
        raise DataError(path, problems)
    return out


def acoustic_observations(agent: str | None = None) -> list[AcousticObservation]:
    """The 17 shipped observations, or one agent's.

    Parameters
    ----------
    agent : str, optional
        'definity' or 'sonovue' (case-insensitive); None for all.

    Returns
    -------
    list of AcousticObservation
        In file order (3 SonoVue, then 14 Definity bubbles).

    Raises
    ------
    DataError
        If ``agent`` is not one of the agents.
    """
    path = Path(str(resources.files("bubblecal.data") / "reference" / "acoustic_observations_published.csv"))
    rows = load_acoustic_table(path)
    if agent is None:
        return rows
    if agent.lower() not in AGENTS:
        raise DataError(path, [f"unknown agent {agent!r}; allowed: {', '.join(AGENTS)}"])
    return [r for r in rows if r.agent == agent.lower()]


def acoustic_datasets(agent: str, observations: list[AcousticObservation] | None = None) -> list[AcousticDataset]:
    """Group one agent's observations into hierarchy datasets: Definity one dataset, SonoVue one per bubble.

    Parameters
    ----------
    agent : str
        'definity' or 'sonovue' (case-insensitive).
    observations : list of AcousticObservation, optional
        The observations to group (those of other agents are ignored); default: the shipped ones.

    Returns
    -------
    list of AcousticDataset
        Empty if the agent has no observations.

    Raises
    ------
    DataError
        If ``observations`` is None and ``agent`` is not one of the agents.
    """
    rows = acoustic_observations(agent) if observations is None else [o for o in observations
                                                                       if o.agent == agent.lower()]
    if not rows:
        return []
    if agent.lower() == "definity":
        return [AcousticDataset(
            name="definity_acoustic", agent="definity",
            diameter_um=np.array([r.diameter_um for r in rows]),
            frequency_MHz=np.array([r.frequency_MHz for r in rows]), source=rows[0].source)]
    return [AcousticDataset(name=f"sonovue_acoustic_{r.diameter_um:g}um", agent="sonovue",
                            diameter_um=np.array([r.diameter_um]), frequency_MHz=np.array([r.frequency_MHz]),
                            source=r.source) for r in rows]
