"""The six shipped reference curves (package data in ``data/reference/``, provenance in its PROVENANCE.md).

Each curve ships twice: ``<name>_dpd.csv`` holds the retained points in DPD units (what the likelihood
sees) and ``<name>_source_physical.csv`` the whole digitised source curve in nm / nN with its retained flags
(docs/inference.md section 1).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from bubblecal.data.curves import LoadingCurve
from bubblecal.data.errors import DataError
from bubblecal.data.names import AGENTS
from bubblecal.data.readers import load_curve
from bubblecal.data.units import DEFAULT_UNITS, UnitSystem

__all__ = ["REFERENCE_CURVES", "load_reference", "reference_curves", "reference_names", "resolve_reference_name"]

_BUCHNER_SANTOS = "Buchner Santos et al., Langmuir 28:5753 (2012)"
_MORRIS = "J. K. Morris, PhD thesis, Edinburgh (2014)"

#: The six shipped curves: name -> (agent, kind, nominal diameter [um], measured diameter [um], citation).
#: The nominal diameter names the curve; the measured one (3.19, 3.40, 5.76 um for SonoVue) sets the
#: DPD geometry, as in the published training sets (radius_dpd 6.38, 6.8, 11.52).
REFERENCE_CURVES: dict[str, tuple[str, str, float, float, str]] = {
    "definity_compression_2.1um": ("definity", "compression", 2.1, 2.1, _BUCHNER_SANTOS),
    "definity_compression_2.9um": ("definity", "compression", 2.9, 2.9, _BUCHNER_SANTOS),
    "definity_compression_3.0um": ("definity", "compression", 3.0, 3.0, _BUCHNER_SANTOS),
    "sonovue_indentation_3.2um": ("sonovue", "indentation", 3.2, 3.19, _MORRIS),
    "sonovue_indentation_3.4um": ("sonovue", "indentation", 3.4, 3.40, _MORRIS),
    "sonovue_indentation_5.8um": ("sonovue", "indentation", 5.8, 5.76, _MORRIS),
}


def _reference_path(filename: str) -> Path:
    """Path of a file in the package's ``data/reference`` folder."""
    return Path(str(resources.files("bubblecal.data") / "reference" / filename))


def reference_names() -> list[str]:
    """Names of the six shipped curves.

    Returns
    -------
    list of str
        E.g. ``"definity_compression_2.1um"``, in :data:`REFERENCE_CURVES` order.
    """
    return list(REFERENCE_CURVES)


def resolve_reference_name(name: str) -> str:
    """The canonical name of a shipped curve given in a short form.

    Parameters
    ----------
    name : str
        A full name, or ``agent-D``, ``agent_Dum``, ``agent D`` or ``agent_kind_D`` with the nominal diameter D
        [um] (e.g. 'definity-2.1', 'definity_2.1um', 'sonovue 5.8'); case-insensitive.

    Returns
    -------
    str
        A key of :data:`REFERENCE_CURVES`.

    Raises
    ------
    DataError
        If no shipped curve has that name.
    """
    key = name.strip().lower().replace("-", "_").replace(" ", "_")
    if key in REFERENCE_CURVES:
        return key
    for canonical, (agent, kind, diameter, _measured, _) in REFERENCE_CURVES.items():
        for alias in (f"{agent}_{diameter}", f"{agent}_{diameter}um", f"{agent}_{kind}_{diameter}"):
            if key == alias:
                return canonical
    raise DataError("reference data", [f"unknown curve {name!r}; available: {', '.join(REFERENCE_CURVES)}"])


def _load_named_reference(name: str, unit_system: UnitSystem) -> LoadingCurve:
    """Load shipped curve ``name`` in DPD units, with its physical source curve."""
    agent, kind, diameter, measured, citation = REFERENCE_CURVES[name]
    curve = load_curve(_reference_path(f"{name}_dpd.csv"), kind, "dpd", name=name, agent=agent,
                       diameter_um=diameter, source=citation, unit_system=unit_system)
    src = load_curve(_reference_path(f"{name}_source_physical.csv"), kind, "physical", unit_system=unit_system)
    return LoadingCurve(name=name, kind=kind, x=curve.x, y=curve.y, agent=agent, diameter_um=diameter,
                        source=citation, path=curve.path, source_curve=src.source_curve, units=unit_system,
                        bubble_diameter_um=measured)


def load_reference(agent: str, diameter_um: float, unit_system: UnitSystem = DEFAULT_UNITS) -> LoadingCurve:
    """The shipped curve of one agent at one nominal diameter.

    Parameters
    ----------
    agent : str
        'definity' or 'sonovue' (case-insensitive).
    diameter_um : float
        Nominal bubble diameter [um], matched to within 1e-6 um (2.1, 2.9, 3.0 Definity; 3.2, 3.4, 5.8 SonoVue).
    unit_system : UnitSystem
        Unit system of the curve's physical views.

    Returns
    -------
    LoadingCurve
        The retained points in DPD units, with the whole physical source curve and the measured diameter.

    Raises
    ------
    DataError
        If the agent is unknown or has no curve at that diameter (the message lists the available ones).
    """
    agent_key = agent.strip().lower()
    agents = sorted({a for a, *_ in REFERENCE_CURVES.values()})
    if agent_key not in agents:
        raise DataError("reference data", [f"unknown agent {agent!r}; allowed: {', '.join(agents)}"])
    for name, (a, _kind, diameter, _measured, _) in REFERENCE_CURVES.items():
        if a == agent_key and abs(diameter - float(diameter_um)) < 1e-6:
            return _load_named_reference(name, unit_system)
    available = ", ".join(f"{d:g}" for a, _k, d, *_ in REFERENCE_CURVES.values() if a == agent_key)
    raise DataError("reference data", [f"no {agent_key} curve at diameter {diameter_um} um; available: {available} um"])


def reference_curves(agent: str | None = None, unit_system: UnitSystem = DEFAULT_UNITS) -> list[LoadingCurve]:
    """All six shipped curves, or one agent's.

    Parameters
    ----------
    agent : str, optional
        'definity' or 'sonovue' (case-insensitive); None for all.
    unit_system : UnitSystem
        Unit system of the curves' physical views.

    Returns
    -------
    list of LoadingCurve
        In :data:`REFERENCE_CURVES` order: by agent, then by diameter.

    Raises
    ------
    DataError
        If ``agent`` is not one of the agents.
    """
    names = [n for n, (a, *_) in REFERENCE_CURVES.items() if agent is None or a == agent.lower()]
    if not names:
        raise DataError("reference data", [f"unknown agent {agent!r}; allowed: {', '.join(AGENTS)}"])
    return [_load_named_reference(n, unit_system) for n in names]
