"""Matplotlib helpers of the workflows' figures.

Figures are built on :class:`matplotlib.figure.Figure` directly, not through pyplot: drawing one selects
no backend, registers no global figure and changes no global ``rcParams`` (a notebook or another library
in the same process keeps its settings). PNG files are rendered by Agg.
"""

from __future__ import annotations

import functools
from pathlib import Path

__all__ = ["STYLE", "COLOURS", "styled", "new_figure", "save_figure", "figure_title", "agent_title", "short_label"]

#: How the published agents are written in titles; a user's agent label is shown as given.
AGENT_TITLES = {"definity": "Definity", "sonovue": "SonoVue"}

#: rcParams of the calibration figures (applied only while a :func:`styled` function runs).
STYLE = {"font.size": 9, "axes.spines.top": False, "axes.spines.right": False, "legend.frameon": False,
         "savefig.dpi": 150}


#: Colour cycle of the calibration figures.
COLOURS = ("#1b6ca8", "#d1495b", "#2e8b57", "#edae49", "#6a4c93", "#00798c")


def figure_title(result, plan, what: str) -> str:
    """Figure title: agent, what, workflow, and a warning line for a synthetic bundle.

    Parameters
    ----------
    result : bubblecal.workflows.calibrate.AgentResult
    plan : bubblecal.workflows.calibrate.Plan
    what : str
        What the figure shows.

    Returns
    -------
    str
    """
    t = f"{agent_title(result.plan.agent)} — {what} ({result.plan.workflow})"
    return t + ("\nSYNTHETIC surrogate bundle: not a physical result" if plan.synthetic_bundle else "")


def agent_title(agent: str) -> str:
    """An agent as written in a title: the published agents' names (``AGENT_TITLES``), a user's label as given.

    Parameters
    ----------
    agent : str
        The agent label.

    Returns
    -------
    str
    """
    return AGENT_TITLES.get(agent, agent)


def short_label(text: str, width: int = 24) -> str:
    """``text`` cut to ``width`` characters (an ellipsis marks the cut), so a long bubble id keeps a panel readable.

    Parameters
    ----------
    text : str
    width : int
        Most characters kept.

    Returns
    -------
    str
    """
    return text if len(text) <= width else text[: width - 1] + "…"


def styled(func):
    """Decorator: run ``func`` (which draws and saves a figure) under :data:`STYLE`."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        import matplotlib

        with matplotlib.rc_context(STYLE):
            return func(*args, **kwargs)

    return wrapper


def new_figure(nrows: int = 1, ncols: int = 1, *, figsize: tuple[float, float], squeeze: bool = True,
               layout: str | None = None, **subplots_kwargs):
    """A new figure and its subplot grid (the arguments of :meth:`matplotlib.figure.Figure.subplots`).

    Parameters
    ----------
    nrows, ncols : int
        Grid of axes.
    figsize : tuple of float
        Width and height in inches.
    squeeze : bool
        As in :func:`matplotlib.pyplot.subplots`.
    layout : str or None
        None: :func:`save_figure` applies a tight layout; 'constrained': the figure keeps matplotlib's
        constrained layout (needed for figure-level labels and legends placed "outside").
    **subplots_kwargs
        Passed to :meth:`matplotlib.figure.Figure.subplots` (e.g. ``sharey``, ``gridspec_kw``).

    Returns
    -------
    tuple
        (:class:`matplotlib.figure.Figure`, axes or array of axes).
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, layout=layout)
    return fig, fig.subplots(nrows, ncols, squeeze=squeeze, **subplots_kwargs)


def save_figure(fig, path: Path, **savefig_kwargs) -> Path:
    """Tight layout (unless the figure has a layout engine of its own), then write ``path``.

    The format follows the suffix; the dpi comes from ``rcParams`` unless given.

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
    if fig.get_layout_engine() is None:
        fig.tight_layout()
    fig.savefig(path, **savefig_kwargs)
    return path
