"""The data layer's error types: a data file, or a campaign record or store, that failed validation."""

from __future__ import annotations

from pathlib import Path

__all__ = ["DataError", "StoreError"]


class DataError(ValueError):
    """A data file failed validation; every problem found is listed at once.

    The message reads ``"<path>: <n> problem(s):"`` followed by one ``"  - <problem>"`` line per problem.

    Parameters
    ----------
    path : str or pathlib.Path
        The file the problems belong to, or a label such as ``"reference data"``.
    problems : list of str
        One message per problem, naming row and column where they apply.

    Attributes
    ----------
    path : str
        ``path`` as a string.
    problems : list of str
        A copy of ``problems``.
    """

    def __init__(self, path: str | Path, problems: list[str]):
        self.path = str(path)
        self.problems = list(problems)
        lines = "\n".join(f"  - {p}" for p in self.problems)
        noun = "problem" if len(self.problems) == 1 else "problems"
        super().__init__(f"{self.path}: {len(self.problems)} {noun}:\n{lines}")


class StoreError(ValueError):
    """A campaign record or store file is invalid; the message names the file or record and the field."""
