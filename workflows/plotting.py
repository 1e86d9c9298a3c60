"""Matplotlib helpers of the workflows' figures.

Figures are built on :class:`matplotlib.figure.Figure` directly, not through pyplot: drawing one selects
no backend, registers no global figure and changes no global ``rcParams`` (a notebook or another library
in the same process keeps its settings). PNG files are rendered by Agg.
"""

from __future__ import annotations

import functools
from pathlib import Path

__all__ = ["STYLE", "styled", "new_figure", "save_figure"]

#: rcParams of the calibration figures (applied only while a :func:`styled` function runs).
STYLE = {"font.size": 9, "axes.spines.top": False, "axes.spines.right": False, "legend.frameon": False,
         "savefig.dpi": 150}


def styled(func):
    """Decorator: run ``func`` (which draws and saves a figure) under :data:`STYLE`."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        import matplotlib

        with matplotlib.rc_context(STYLE):
            return func(*args, **kwargs)

    return wrapper


def new_figure(nrows: int = 1, ncols: int = 1, *, figsize: tuple[float, float], squeeze: bool = True):
    """A new figure and its subplot grid (the arguments of :meth:`matplotlib.figure.Figure.subplots`).

    Parameters
    ----------
    nrows, ncols : int
        Grid of axes.
    figsize : tuple of float
        Width and height in inches.
    squeeze : bool
        As in :func:`matplotlib.pyplot.subplots`.

    Returns
    -------
    tuple
        (:class:`matplotlib.figure.Figure`, axes or array of axes).
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    return fig, fig.subplots(nrows, ncols, squeeze=squeeze)


def save_figure(fig, path: Path, **savefig_kwargs) -> Path:
    """Tight layout, then write ``path`` (format from the suffix; dpi from ``rcParams`` unless given).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : Path
    **savefig_kwargs
        Passed to :meth:`matplotlib.figure.Figure.savefig` (e.g. ``dpi``).

    Returns
    -------
    Path
        ``path``.
    """
    fig.tight_layout()
    fig.savefig(path, **savefig_kwargs)
    return path
