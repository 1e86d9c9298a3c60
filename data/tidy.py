"""The tidy input format for measured bubbles: its columns, its error type and the typed, immutable collections.

A tidy curve file holds one row per measured point of any number of bubbles and agents (columns
:data:`CURVE_COLUMNS`, optional :data:`CURVE_OPTIONAL`); a tidy resonance file one row per bubble resonance
(:data:`RESONANCE_COLUMNS`, optional :data:`RESONANCE_OPTIONAL`). Files carry physical units (um, nm, nN, MHz);
the collections hold DPD units converted through :mod:`bubblecal.data.units`. The readers are in
:mod:`bubblecal.data.tidy_read`; the format is described in docs/data-formats.md ("Tidy bubble files").
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bubblecal.data.curves import KINDS, LoadingCurve, SourceCurve
from bubblecal.data.errors import DataError
from bubblecal.data.units import DEFAULT_UNITS, UnitSystem

__all__ = ["CURVE_COLUMNS", "CURVE_OPTIONAL", "RESONANCE_COLUMNS", "RESONANCE_OPTIONAL", "TidyDataError",
           "BubbleCurve", "BubbleCurveSet", "ResonanceSet"]

#: Required columns of a tidy curve file (one row per measured point).
CURVE_COLUMNS: tuple[str, ...] = ("bubble", "agent", "protocol", "diameter_um", "displacement_nm", "force_nN")
#: Optional columns of a tidy curve file: ``retained`` (1: the point enters the likelihood, 0: it does not).
CURVE_OPTIONAL: tuple[str, ...] = ("retained",)
#: Required columns of a tidy resonance file (one row per bubble).
RESONANCE_COLUMNS: tuple[str, ...] = ("agent", "diameter_um", "frequency_MHz")
#: Optional columns of a tidy resonance file: ``source`` (a citation or a note).
RESONANCE_OPTIONAL: tuple[str, ...] = ("source",)


class TidyDataError(DataError):
    """A tidy curve or resonance file failed validation; every problem found is listed at once.

    Each problem names the row (1-based data row and file line), the column, the value and the allowed range
    or the unit that was probably meant. The message layout is :class:`~bubblecal.data.DataError`'s.

    Parameters
    ----------
    path : str or pathlib.Path
        The file, or a label such as ``"curves.csv + resonance.csv"``.
    problems : list of str
        One message per problem.
    """


def _frozen(values) -> np.ndarray:
    """A read-only float64 copy (bool arrays keep their type)."""
    arr = np.array(values)
    arr = arr.astype(bool) if arr.dtype == bool else arr.astype(float)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class BubbleCurve:
    """One bubble's measured loading curve, every point of the file in DPD units.

    Parameters
    ----------
    bubble : str
        The bubble's id (unique across agents).
    agent : str
        The population the bubble belongs to (any label).
    protocol : str
        'compression' (x = displacement, y = force) or 'indentation' (x = force, y = displacement).
    diameter_um : float
        Bubble diameter [um].
    x, y : numpy.ndarray
        Every point of the bubble in the experiment's axis order [DPD length or DPD force], read-only.
    retained : numpy.ndarray of bool
        True where the point enters the likelihood; same length as ``x``.
    lines : tuple of int
        The file line of each point.
    path : str
        The file the bubble was read from.
    units : UnitSystem
        The unit system that converted the file's nm / nN to DPD units.
    """

    bubble: str
    agent: str
    protocol: str
    diameter_um: float
    x: np.ndarray
    y: np.ndarray
    retained: np.ndarray
    lines: tuple[int, ...]
    path: str = ""
    units: UnitSystem = field(default=DEFAULT_UNITS, repr=False)

    def __post_init__(self):
        for name in ("x", "y", "retained"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))

    @property
    def n_points(self) -> int:
        """Number of points in the file."""
        return int(self.x.size)

    @property
    def n_retained(self) -> int:
        """Number of points that enter the likelihood."""
        return int(self.retained.sum())

    def loading_curve(self) -> LoadingCurve:
        """The retained points as a :class:`~bubblecal.data.LoadingCurve`, every point kept as its source curve.

        Returns
        -------
        LoadingCurve
            Named after the bubble; x, y in DPD units; ``source_curve`` in nm / nN with the retained flags.
        """
        to_physical = {"force": self.units.dpd_to_nN, "displacement": self.units.dpd_to_nm}
        x_q, y_q = KINDS[self.protocol]
        source = SourceCurve(kind=self.protocol, x=np.asarray(to_physical[x_q](self.x)),
                             y=np.asarray(to_physical[y_q](self.y)), retained=np.array(self.retained),
                             path=self.path)
        return LoadingCurve(name=self.bubble, kind=self.protocol, x=np.array(self.x[self.retained]),
                            y=np.array(self.y[self.retained]), agent=self.agent, diameter_um=self.diameter_um,
                            source=self.path, path=self.path, source_curve=source, units=self.units,
                            bubble_diameter_um=self.diameter_um)


@dataclass(frozen=True)
class BubbleCurveSet:
    """Every bubble of a tidy curve file, in the order of their first row.

    Parameters
    ----------
    bubbles : tuple of BubbleCurve
        The bubbles.
    path : str
        The file.
    """

    bubbles: tuple[BubbleCurve, ...]
    path: str = ""

    def __len__(self) -> int:
        return len(self.bubbles)

    def __iter__(self):
        return iter(self.bubbles)

    @property
    def agents(self) -> tuple[str, ...]:
        """Agent labels in the order of their first bubble."""
        return tuple(dict.fromkeys(b.agent for b in self.bubbles))

    def by_agent(self) -> dict[str, tuple[BubbleCurve, ...]]:
        """The bubbles grouped by agent.

        Returns
        -------
        dict of str to tuple of BubbleCurve
            Agent label -> its bubbles, in file order.
        """
        return {a: tuple(b for b in self.bubbles if b.agent == a) for a in self.agents}

    def by_agent_protocol(self) -> dict[tuple[str, str], tuple[BubbleCurve, ...]]:
        """The bubbles grouped by (agent, protocol).

        Returns
        -------
        dict of (str, str) to tuple of BubbleCurve
            (agent, protocol) -> its bubbles, in file order.
        """
        keys = dict.fromkeys((b.agent, b.protocol) for b in self.bubbles)
        return {k: tuple(b for b in self.bubbles if (b.agent, b.protocol) == k) for k in keys}

    def counts(self) -> dict[str, dict[str, int]]:
        """Per agent: bubbles, points and retained points.

        Returns
        -------
        dict of str to dict
            Agent label -> ``{"bubbles": n, "points": n, "retained": n}``.
        """
        return {a: {"bubbles": len(bs), "points": sum(b.n_points for b in bs),
                    "retained": sum(b.n_retained for b in bs)} for a, bs in self.by_agent().items()}


@dataclass(frozen=True)
class ResonanceSet:
    """The rows of a tidy resonance file: one measured resonance per bubble.

    Parameters
    ----------
    agent : tuple of str
        Agent label of each row.
    diameter_um : numpy.ndarray
        Bubble diameters [um], read-only.
    frequency_MHz : numpy.ndarray
        Resonance frequencies [MHz], read-only.
    frequency_dpd : numpy.ndarray
        The same frequencies [1 / DPD time], read-only.
    source : tuple of str
        Citation or note of each row ('' where the file has none).
    lines : tuple of int
        The file line of each row.
    path : str
        The file.
    """

    agent: tuple[str, ...]
    diameter_um: np.ndarray
    frequency_MHz: np.ndarray
    frequency_dpd: np.ndarray
    source: tuple[str, ...]
    lines: tuple[int, ...]
    path: str = ""

    def __post_init__(self):
        for name in ("diameter_um", "frequency_MHz", "frequency_dpd"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))

    def __len__(self) -> int:
        return len(self.agent)

    @property
    def agents(self) -> tuple[str, ...]:
        """Agent labels in the order of their first row."""
        return tuple(dict.fromkeys(self.agent))

    def for_agent(self, agent: str) -> tuple[np.ndarray, np.ndarray]:
        """One agent's diameters [um] and frequencies [MHz].

        Parameters
        ----------
        agent : str
            An agent label of the file.

        Returns
        -------
        tuple of numpy.ndarray
            (diameter_um, frequency_MHz), empty where the agent has no row.
        """
        mask = np.array([a == agent for a in self.agent], dtype=bool)
        return np.array(self.diameter_um[mask]), np.array(self.frequency_MHz[mask])
