"""Optional dependencies: each belongs to one extra of the distribution, and a missing one names that extra.

The lean install (``pip install bubblecal``) calibrates; simulation, training, Sobol sensitivity, clusters and the
benchmarks' samplers come with extras (pyproject ``[project.optional-dependencies]``).  Every import of an optional
library goes through :func:`require`, so that a user without the extra gets one message saying what to install
instead of a bare ``ModuleNotFoundError`` from deep inside a module::

    wp = require("warp", "sim")            # in place of ``import warp as wp``
    sobol = require("SALib.sample.sobol", "sensitivity")
"""

from __future__ import annotations

import importlib
from types import ModuleType

__all__ = ["EXTRAS", "DISTRIBUTIONS", "MissingExtraError", "require"]

#: Extra -> the top-level import names of the optional libraries it installs (pyproject lists their ranges).
EXTRAS: dict[str, tuple[str, ...]] = {
    "sim": ("warp", "trimesh", "dask", "distributed"),
    "train": ("torch", "onnx", "onnxruntime", "onnxscript"),
    "sensitivity": ("SALib",),
    "cluster": ("dask_jobqueue",),
    "bench": ("blackjax",),
}
#: Import name -> distribution name, where the two differ.
DISTRIBUTIONS: dict[str, str] = {"warp": "warp-lang", "dask_jobqueue": "dask-jobqueue"}


class MissingExtraError(ModuleNotFoundError):
    """An optional library is not installed; the message names it, its extra and the command that installs it.

    A ``ModuleNotFoundError`` (so an ``ImportError``): code that treats a missing library as "not available"
    keeps working.

    Parameters
    ----------
    module : str
        The import name that failed (e.g. ``'warp'`` or ``'SALib.sample.sobol'``).
    extra : str
        The extra that installs it (a key of :data:`EXTRAS`).

    Attributes
    ----------
    extra : str
        The extra to install.
    install : str
        The command that installs it.
    """

    def __init__(self, module: str, extra: str):
        top = module.split(".")[0]
        self.extra = extra
        self.install = f"pip install 'bubblecal[{extra}]'"
        dist = DISTRIBUTIONS.get(top, top)
        super().__init__(f"{top}{f' ({dist})' if dist != top else ''} is not installed: it comes with bubblecal's "
                         f"[{extra}] extra; install it with {self.install} (in a checkout: pip install -c "
                         f"requirements.lock -e '.[{extra}]')", name=top)


def require(module_name: str, extra: str) -> ModuleType:
    """Import an optional library, or raise :class:`MissingExtraError` naming the extra that installs it.

    Parameters
    ----------
    module_name : str
        Absolute import name (``'warp'``, ``'torch'``, ``'SALib.sample.sobol'``); its top-level package must be
        one of ``EXTRAS[extra]``.
    extra : str
        The extra that installs it (a key of :data:`EXTRAS`).

    Returns
    -------
    types.ModuleType
        The imported module (the submodule itself for a dotted name).

    Raises
    ------
    MissingExtraError
        The library (its top-level package) is not installed.
    ValueError
        ``extra`` is not an extra, or it does not install ``module_name`` (a mistake in the calling code).
    """
    top = module_name.split(".")[0]
    if extra not in EXTRAS:
        raise ValueError(f"unknown extra {extra!r}; the extras are {', '.join(EXTRAS)}")
    if top not in EXTRAS[extra]:
        raise ValueError(f"the [{extra}] extra does not install {top!r} (it installs {', '.join(EXTRAS[extra])})")
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        # only the library itself being absent is a missing extra; a part or a requirement of an installed
        # library that is missing is a broken installation, which keeps its own error
        if exc.name != top:
            raise
        raise MissingExtraError(module_name, extra) from exc
