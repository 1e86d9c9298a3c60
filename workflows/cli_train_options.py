"""Parsers of ``bubblecal surrogates train``'s text options: each returns the typed value or raises
``typer.BadParameter`` naming the option and the allowed values."""

from __future__ import annotations

import typer

from bubblecal.surrogates.features import LOG_INPUT_CHOICES, check_log_inputs

__all__ = ["int_list", "band_list", "log_input_names"]


def int_list(text: str, name: str) -> tuple[int, ...]:
    """Comma-separated positive integers.

    Parameters
    ----------
    text : str
        The option's value, e.g. ``"32,64"``.
    name : str
        The option's name for messages, e.g. ``"--widths"``.

    Returns
    -------
    tuple of int

    Raises
    ------
    typer.BadParameter
        For a value that is not an integer or not positive, or no value.
    """
    try:
        vals = tuple(int(v) for v in text.replace(" ", "").split(",") if v)
    except ValueError as exc:
        raise typer.BadParameter(f"{name} must be comma-separated integers, got {text!r}") from exc
    if not vals or any(v < 1 for v in vals):
        raise typer.BadParameter(f"{name} must be positive integers, got {text!r}")
    return vals


def band_list(text: str) -> tuple[tuple[float, float], ...]:
    """'lo-hi,lo-hi' diameter bands [um] of ``--ldo-bands``.

    Parameters
    ----------
    text : str
        The option's value ('' for none).

    Returns
    -------
    tuple of (float, float)
        Bands [um], 0 < lo <= hi.

    Raises
    ------
    typer.BadParameter
        For a band that does not parse or has lo <= 0 or lo > hi.
    """
    out = []
    for part in (p for p in text.replace(" ", "").split(",") if p):
        try:
            lo, hi = (float(v) for v in part.split("-"))
        except ValueError:
            raise typer.BadParameter(f"--ldo-bands must be 'lo-hi,lo-hi' in um, got {part!r}") from None
        if not (0 < lo <= hi):
            raise typer.BadParameter(f"--ldo-bands: band {part!r} must have 0 < lo <= hi [um]")
        out.append((lo, hi))
    return tuple(out)


def log_input_names(text: str) -> tuple[str, ...] | None:
    """The shell parameters of ``--log-inputs``: None for 'auto', () for 'none', else the names.

    Parameters
    ----------
    text : str
        'auto', 'none' or comma-separated names from :data:`~bubblecal.surrogates.LOG_INPUT_CHOICES`.

    Returns
    -------
    tuple of str or None
        None lets :class:`~bubblecal.surrogates.training.SweepConfig` choose its default.

    Raises
    ------
    typer.BadParameter
        For a name outside ``LOG_INPUT_CHOICES``.
    """
    text = text.replace(" ", "")
    if text == "auto":
        return None
    if text == "none":
        return ()
    try:
        return check_log_inputs(v for v in text.split(",") if v)
    except ValueError:
        raise typer.BadParameter(f"--log-inputs must be 'auto', 'none' or names from {list(LOG_INPUT_CHOICES)}, "
                                 f"got {text!r}") from None
