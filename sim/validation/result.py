"""The row type of every physics check: :class:`CheckResult`."""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["CheckResult"]


@dataclass
class CheckResult:
    """One verification row: what was expected, what was measured, the tolerance and the verdict.

    Parameters
    ----------
    name : str
        Check name (a table row).
    expected : str
        The expected value, in words.
    measured : float or str
        The measured value.
    tolerance : str
        The tolerance, in words.
    passed : bool
        The verdict.
    details : dict, optional
        Everything else worth keeping (set-up, timings in s, intermediate numbers).
    """

    name: str
    expected: str
    measured: float | str
    tolerance: str
    passed: bool
    details: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """The row as a JSON-friendly dict."""
        return {"name": self.name, "expected": self.expected, "measured": self.measured,
                "tolerance": self.tolerance, "passed": bool(self.passed), "details": self.details}
