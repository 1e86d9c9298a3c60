"""The closed sets of values of the command line's options, as ``str`` enums built from the package's names.

Typer prints an enum's values in ``--help`` (``[definity|sonovue|all]``) and rejects any other value as a usage
error (exit status 2) before a command runs. The values are not written here: each enum is built from the tuple
that defines them once (:mod:`bubblecal.data.names`, the calibration config, the tier registry, the law forms),
so an added agent, tier or form reaches the command line by itself. Members are ``str``: ``Agent.definity ==
'definity'``, and :func:`value` turns an option back into the plain string the pipelines take.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable

from bubblecal.data import AGENTS, LOADING_PROTOCOLS, UNITS
from bubblecal.sim.protocols.ringdown.batch import RINGDOWN_TIERS
from bubblecal.sim.tiers.base import TIER_NAMES
from bubblecal.surrogates.resonance_law import LAW_FORMS
from bubblecal.workflows.calibrate.config import (
    DEVICES,
    NETWORKS,
    PHASE3_STARTS,
    PHASE3_TARGETS,
    SAMPLERS,
    SURROGATE_CHOICES,
    WORKFLOWS,
)

__all__ = ["ALL_AGENTS", "Agent", "AgentOrAll", "Workflow", "Sampler", "JaxDevice", "Phase3", "Phase3Start", "Networks",
           "Surrogates", "Tier", "RingdownTier", "LoadingProtocol", "Units", "LawFormName", "choice_value"]

#: ``--agent`` value selecting every agent.
ALL_AGENTS = "all"


def _choices(name: str, values: Iterable[str]) -> type[enum.StrEnum]:
    """A ``StrEnum`` whose members' names and values are ``values`` (in order)."""
    return enum.StrEnum(name, {v: v for v in values})


#: A contrast agent (:data:`bubblecal.data.AGENTS`).
Agent = _choices("Agent", AGENTS)
#: A contrast agent or every agent.
AgentOrAll = _choices("AgentOrAll", (*AGENTS, ALL_AGENTS))
#: A calibration workflow (priors set and data).
Workflow = _choices("Workflow", WORKFLOWS)
#: The calibration sampler: staged TMCMC or joint NUTS.
Sampler = _choices("Sampler", SAMPLERS)
#: The JAX device of a calibration.
JaxDevice = _choices("JaxDevice", DEVICES)
#: The phase-3 target of the staged calibration.
Phase3 = _choices("Phase3", PHASE3_TARGETS)
Phase3Start = _choices("Phase3Start", PHASE3_STARTS)
#: Networks over the diameter (``calibrate --networks``).
Networks = _choices("Networks", NETWORKS)
#: Which surrogates serve the published study (``calibrate --surrogates``).
Surrogates = _choices("Surrogates", SURROGATE_CHOICES)
#: A DPD fidelity tier (:data:`bubblecal.sim.TIER_NAMES`).
Tier = _choices("Tier", TIER_NAMES)
#: A tier that runs the ringdown protocol.
RingdownTier = _choices("RingdownTier", RINGDOWN_TIERS)
#: A mechanical loading protocol (:data:`bubblecal.data.LOADING_PROTOCOLS`).
LoadingProtocol = _choices("LoadingProtocol", LOADING_PROTOCOLS)
#: Units of a curve file.
Units = _choices("Units", UNITS)
#: A form of the acoustic law continuous in the diameter.
LawFormName = _choices("LawFormName", LAW_FORMS)


def choice_value(option: str | enum.Enum | None) -> str | None:
    """The plain string of an option (an enum member's value), or None.

    Parameters
    ----------
    option : str, enum member or None
        A parsed option.

    Returns
    -------
    str or None
    """
    if option is None:
        return None
    return str(option.value) if isinstance(option, enum.Enum) else str(option)
