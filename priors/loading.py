"""Finding, loading and checking priors files: the shipped workflow files of this folder or a user's file.

One file per workflow (``definity_full.toml``, ``sonovue_reduced_acoustic.toml``, ...); the format is documented
at the top of every shipped file. :func:`load_priors` validates the whole file and raises :class:`PriorError`
listing every problem at once (file and key named); nothing is clipped.
"""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path

from bubblecal.priors.spec import PriorSpec
from bubblecal.priors.validation import _validate

__all__ = ["PriorError", "available_priors", "workflow_file_name", "prior_path", "load_priors", "check_priors"]


class PriorError(ValueError):
    """A priors file failed validation; every offending key is named at once.

    The message reads ``"priors file <path>: <n> problem(s):"`` followed by one ``"  - <problem>"`` line per
    problem.

    Parameters
    ----------
    path : str or pathlib.Path
        The priors file, or the name that could not be resolved.
    problems : list of str
        One message per problem, each naming the key (e.g. ``parameters.kb.prior``).

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
        noun = "problem" if len(problems) == 1 else "problems"
        lines = "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(f"priors file {self.path}: {len(self.problems)} {noun}:\n{lines}")


def available_priors() -> list[str]:
    """Names of the shipped workflow files.

    Returns
    -------
    list of str
        File stems without ``.toml`` (e.g. ``"definity_full"``), sorted.
    """
    folder = resources.files("bubblecal.priors")
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def workflow_file_name(agent: str, workflow: str) -> str:
    """Name of the shipped priors file of an agent and a command-line workflow.

    Parameters
    ----------
    agent : str
        'definity' or 'sonovue' (case-insensitive).
    workflow : str
        'full', 'reduced' or 'reduced-acoustic' (case-insensitive).

    Returns
    -------
    str
        E.g. ``"sonovue_reduced_acoustic"`` (not checked against the shipped files).
    """
    return f"{agent.lower()}_{workflow.lower().replace('-', '_')}"


def prior_path(name_or_path: str | Path) -> Path:
    """Resolve a shipped workflow name or a file path to a priors file.

    Parameters
    ----------
    name_or_path : str or pathlib.Path
        A path ending in ``.toml`` or an existing path (returned as given), or a shipped workflow name such as
        'definity_full' (case-insensitive, '-' read as '_').

    Returns
    -------
    pathlib.Path

    Raises
    ------
    PriorError
        If it is neither a path nor a shipped workflow (the message lists the shipped ones).
    """
    candidate = Path(name_or_path)
    if candidate.suffix == ".toml" or candidate.exists():
        return candidate
    key = str(name_or_path).lower().replace("-", "_")
    if key in available_priors():
        return Path(str(resources.files("bubblecal.priors") / f"{key}.toml"))
    raise PriorError(str(name_or_path),
                     [f"no such priors file or shipped workflow; shipped: {', '.join(available_priors())}"])


def load_priors(name_or_path: str | Path) -> PriorSpec:
    """Load and validate a workflow's priors.

    Parameters
    ----------
    name_or_path : str or pathlib.Path
        A shipped workflow name ('definity_reduced_acoustic') or a priors file (see :func:`prior_path`).

    Returns
    -------
    PriorSpec
        Named after the file's stem; the values in DPD units.

    Raises
    ------
    PriorError
        Listing every problem (file and key named): no such file or workflow, a folder, an unreadable or
        non-UTF-8 file, invalid TOML, unknown sections or
        keys, bad bounds, missing or doubly listed parameters, noise amplitudes that do not fit the workflow.
    """
    path = prior_path(name_or_path)
    try:
        with open(path, "rb") as handle:
            raw = tomllib.load(handle)
    except FileNotFoundError as exc:
        raise PriorError(path, ["file not found"]) from exc
    except IsADirectoryError as exc:
        raise PriorError(path, ["is a folder, not a priors TOML file"]) from exc
    except UnicodeDecodeError as exc:
        raise PriorError(path, [f"not UTF-8 text (byte {exc.start}); TOML files are UTF-8"]) from exc
    except tomllib.TOMLDecodeError as exc:
        raise PriorError(path, [f"not valid TOML: {exc}"]) from exc
    except OSError as exc:
        raise PriorError(path, [f"cannot read file: {exc.strerror or exc}"]) from exc
    problems: list[str] = []
    agent, setup, shell, acoustic, description, params, fixed, noise = _validate(raw, problems)
    if problems:
        raise PriorError(path, problems)
    return PriorSpec(name=path.stem, path=str(path), agent=agent, setup=setup, shell=shell, acoustic=acoustic,
                     parameters=params, fixed=fixed, noise=noise, description=description)


def check_priors(name_or_path: str | Path) -> list[str]:
    """Problems found in a priors file.

    Parameters
    ----------
    name_or_path : str or pathlib.Path
        A shipped workflow name or a priors file.

    Returns
    -------
    list of str
        Every problem (see :func:`load_priors`); empty when the file is valid.
    """
    try:
        load_priors(name_or_path)
    except PriorError as exc:
        return exc.problems
    return []
