"""Which surrogate served a dataset, in words: for the report, the console and ``evidence.csv``.

A mechanical surrogate is a per-diameter file or a network over the diameter of one role (``'accurate'`` or
``'fast'``, :mod:`bubblecal.surrogates.bundle_networks`); an acoustic one is the per-diameter quadratics or the law
continuous in the diameter. The role is the bundle's: a network is ``'fast'`` when it is the file the bundle lists
as the fast network of its protocol.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["surrogate_label", "acoustic_label", "served_lines"]


def _file(obj) -> str:
    """The file name an object was loaded from ('in memory' when none)."""
    path = getattr(obj, "path", None)
    return Path(path).name if path is not None else "in memory"


def surrogate_label(sur, bundle=None) -> str:
    """One phrase naming the mechanical surrogate ``sur``: its kind, file and (over the diameter) role.

    Parameters
    ----------
    sur : bubblecal.surrogates.Surrogate
        A per-diameter surrogate or a network over the diameter bound to a diameter.
    bundle : bubblecal.surrogates.Bundle or None
        The bundle it came from (tells the role of a network over the diameter; None: 'accurate' unless it is
        not known, then no role).

    Returns
    -------
    str
        E.g. ``'network over the diameter compression_1.5-8um_fast.npz (fast)'`` or
        ``'per-diameter file compression_2.1um.npz'``.
    """
    if not getattr(sur, "over_diameter", False):
        return f"per-diameter file {_file(sur)}"
    role = ""
    if bundle is not None:
        fast = getattr(bundle, "fast", {}).get(sur.setup)
        same = fast is not None and fast.path is not None and sur.path is not None and fast.path == sur.path
        role = " (fast)" if same else " (accurate)"
    return f"network over the diameter {_file(sur)}{role}"


def acoustic_label(f_res) -> str:
    """One phrase naming the acoustic surrogate ``f_res``: the per-diameter quadratics or the law, and its file.

    Parameters
    ----------
    f_res : bubblecal.surrogates.AcousticSurrogate
        The per-diameter quadratics or an :class:`~bubblecal.surrogates.AcousticLawSurrogate`.

    Returns
    -------
    str
        E.g. ``'acoustic law over 1.5-11.2 um acoustic_definity_1.5-11.2um.json'``.
    """
    from bubblecal.surrogates import AcousticLawSurrogate

    if isinstance(f_res, AcousticLawSurrogate):
        lo, hi = f_res.diameter_range
        return f"acoustic law over {lo:g}-{hi:g} um {_file(f_res)}"
    return f"per-diameter acoustic quadratics {_file(f_res)}"


def served_lines(ap, bundle=None) -> list[str]:
    """``'<dataset>: <surrogate>'`` for every loading curve and acoustic dataset of one agent's plan.

    Datasets served by the same surrogate kind and file share one line (``'a, b, c: ...'``), so a run of many
    bubbles on one network reads as one line.

    Parameters
    ----------
    ap : bubblecal.workflows.calibrate.AgentPlan
        The agent's curves, surrogates and acoustic datasets.
    bundle : bubblecal.surrogates.Bundle or None
        The bundle (for the role of a network over the diameter).

    Returns
    -------
    list of str
        One line per distinct surrogate, in the order of the datasets.
    """
    groups: dict[str, list[str]] = {}
    for curve, sur in zip(ap.curves, ap.surrogates, strict=True):
        groups.setdefault(surrogate_label(sur, bundle), []).append(curve.name)
    if ap.acoustic and ap.f_res is not None:
        groups.setdefault(acoustic_label(ap.f_res), []).extend(ds.name for ds in ap.acoustic)
    return [f"{_names(names)}: {label}" for label, names in groups.items()]


def _names(names: list[str], most: int = 6) -> str:
    """The dataset names, or past ``most`` the first few and the count."""
    if len(names) <= most:
        return ", ".join(names)
    return f"{', '.join(names[:3])} ... ({len(names)} datasets)"
