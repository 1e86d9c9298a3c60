"""Roles of a bundle's mechanical networks over the diameter: the accurate network and the fast one.

A bundle may hold, per loading protocol, two networks over the diameter (:mod:`bubblecal.surrogates.features`):
the ``'accurate'`` one (the selection of the architecture sweep) and a smaller ``'fast'`` one, cheaper to evaluate,
whose held-out error is still far below the measurement noise (docs/decisions.md). The manifest names the role
of each entry over the diameter in its ``network`` field; an entry without one is ``'accurate'`` (bundles written
before the roles existed read unchanged). Per-diameter entries have no role but ``'accurate'``: each is the one
network trained at its diameter.

:meth:`Bundle.get <bubblecal.surrogates.Bundle.get>` with ``network='fast'`` answers with the fast network where
the bundle has one covering the diameter and falls back to the accurate network otherwise (never an error: the
accurate network is a valid, slower answer); :meth:`Bundle.networks <bubblecal.surrogates.Bundle.networks>`
says which roles a protocol has.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from bubblecal.surrogates.surrogate_file import SurrogateFormatError

__all__ = ["NETWORK_ROLES", "DEFAULT_NETWORK", "check_network", "entry_network", "lookup_order"]

#: Roles of a network over the diameter, in the order the bundle lists them.
NETWORK_ROLES = ("accurate", "fast")
#: The role :meth:`Bundle.get <bubblecal.surrogates.Bundle.get>` uses by default, and the role of a manifest entry
#: without a ``network`` field.
DEFAULT_NETWORK = "accurate"


def check_network(network: str) -> str:
    """Return ``network`` when it names a role.

    Parameters
    ----------
    network : str
        A role asked for by a caller.

    Returns
    -------
    str
        ``network``.

    Raises
    ------
    ValueError
        For a value outside :data:`NETWORK_ROLES` (the message names the value and the allowed ones).
    """
    if network not in NETWORK_ROLES:
        raise ValueError(f"network must be one of {', '.join(repr(r) for r in NETWORK_ROLES)}, got {network!r}")
    return network


def entry_network(entry: Mapping, index: int, manifest_path: str | Path, over_diameter: bool) -> str:
    """The role of a manifest's ``surrogates[index]`` entry, validated.

    Parameters
    ----------
    entry : Mapping
        The manifest entry.
    index : int
        Its position in the manifest's ``surrogates`` list (named in messages).
    manifest_path : str or Path
        The manifest (named in messages).
    over_diameter : bool
        Whether the entry is a network over the diameter (only those may be ``'fast'``).

    Returns
    -------
    str
        The entry's ``network`` field, or :data:`DEFAULT_NETWORK` when it has none.

    Raises
    ------
    SurrogateFormatError
        For a value outside :data:`NETWORK_ROLES`, or a role other than ``'accurate'`` on a per-diameter entry.
    """
    role = entry.get("network", DEFAULT_NETWORK)
    if not isinstance(role, str) or role not in NETWORK_ROLES:
        raise SurrogateFormatError(f"{manifest_path}: surrogates[{index}] ({entry.get('file', '?')}) field "
                                   f"'network' is {role!r}; allowed: {', '.join(repr(r) for r in NETWORK_ROLES)}")
    if role != DEFAULT_NETWORK and not over_diameter:
        raise SurrogateFormatError(f"{manifest_path}: surrogates[{index}] ({entry.get('file', '?')}) field "
                                   f"'network' is {role!r}, but only networks over the diameter (entries with "
                                   f"'diameter_range_um') have a role other than {DEFAULT_NETWORK!r}")
    return role


def lookup_order(network: str) -> tuple[str, ...]:
    """Roles tried, in order, for a request of ``network``: the fast one falls back to the accurate one.

    Parameters
    ----------
    network : str
        The requested role.

    Returns
    -------
    tuple of str
        ``('fast', 'accurate')`` for ``'fast'``, ``('accurate',)`` for ``'accurate'``.

    Raises
    ------
    ValueError
        For a value outside :data:`NETWORK_ROLES`.
    """
    check_network(network)
    return ("fast", DEFAULT_NETWORK) if network == "fast" else (DEFAULT_NETWORK,)
