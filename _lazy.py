"""Lazy exports (PEP 562): names a package exports but imports only on first access.

A package whose public objects pull in a heavy library (Warp kernels, torch, JAX) keeps ``import`` cheap by
naming them in a mapping and installing the two module hooks this helper returns::

    __getattr__, __dir__ = lazy_exports(__name__, {"ShellForceField": "bubblecal.sim.engine.kernels.shell.field"},
                                        globals())
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterable, Mapping

__all__ = ["by_module", "lazy_exports"]


def lazy_exports(package: str, names: Mapping[str, str],
                 namespace: dict) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """The module hooks ``__getattr__`` and ``__dir__`` of a package with lazily imported exports.

    Parameters
    ----------
    package : str
        The package's ``__name__`` (named in the error of an unknown attribute).
    names : mapping of str to str
        Exported name -> absolute name of the module that defines it.
    namespace : dict
        The package's ``globals()``; a name is cached there on first access, so the module is imported once.

    Returns
    -------
    tuple of callable
        ``(__getattr__, __dir__)`` to assign at the package's top level.

    Raises
    ------
    AttributeError
        From the returned ``__getattr__``, for a name that is neither defined nor lazily exported.
    """

    def __getattr__(name: str) -> object:
        module = names.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(names))

    return __getattr__, __dir__


def by_module(groups: Mapping[str, Iterable[str]]) -> dict[str, str]:
    """The ``names`` mapping of :func:`lazy_exports` from the exports of each module.

    Parameters
    ----------
    groups : mapping of str to iterable of str
        Absolute module name -> the names the package exports from it.

    Returns
    -------
    dict of str to str
        Exported name -> its module.

    Raises
    ------
    ValueError
        A name listed under two modules.
    """
    out: dict[str, str] = {}
    for module, names in groups.items():
        for name in names:
            if name in out:
                raise ValueError(f"{name} is exported from both {out[name]} and {module}")
            out[name] = module
    return out
