"""Shell (membrane) verification checks of physics.md section 6 (checks 3-5).

Each check is ``check_xxx(quick: bool = True, device: str = "cpu") -> CheckResult``; ``ALL_SHELL_CHECKS``
lists them for ``bubblecal sim verify``.  Placeholder until the implementations land (see below).
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["CheckResult", "ALL_SHELL_CHECKS"]


@dataclass
class CheckResult:
    """One verification row: what was expected, what was measured, the tolerance and the verdict."""

    name: str
    expected: str
    measured: float | str
    tolerance: str
    passed: bool
    details: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return {"name": self.name, "expected": self.expected, "measured": self.measured,
                "tolerance": self.tolerance, "passed": bool(self.passed), "details": self.details}


ALL_SHELL_CHECKS: list = []
