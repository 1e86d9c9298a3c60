"""The campaign layer's errors: a campaign that cannot run, an invalid setting, an invalid campaign file."""

from __future__ import annotations

from pathlib import Path

__all__ = ["CampaignError", "CampaignConfigError", "CampaignFileError"]


class CampaignError(RuntimeError):
    """A campaign cannot run (store of another design, missing ringdown module, repeated task errors)."""


class CampaignConfigError(ValueError):
    """A campaign setting is invalid.

    Parameters
    ----------
    field_name : str
        The :class:`~bubblecal.campaigns.CampaignConfig` field (``ranges.<param>`` for one parameter's range);
        kept as ``field``.
    message : str
        What is wrong and the allowed values; kept as ``detail``.
    """

    def __init__(self, field_name: str, message: str):
        self.field = field_name
        self.detail = message
        super().__init__(f"{field_name}: {message}")


class CampaignFileError(ValueError):
    """A campaign TOML file is invalid; the message names the file, the field and the allowed values.

    Parameters
    ----------
    path : str or Path
        The campaign file (or the name that was not found); kept as ``path``.
    key : str
        The offending TOML key, e.g. ``[campaign].n_samples``, ``[tier].ftol``, ``path``, ``syntax``; kept as
        ``key``.
    message : str
        What is wrong and the allowed values.
    """

    def __init__(self, path: str | Path, key: str, message: str):
        self.path = str(path)
        self.key = key
        super().__init__(f"campaign file {self.path}: {key}: {message}")
