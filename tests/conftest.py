"""Shared test fixtures: the location of ``../shared/reference`` (skipped cleanly when absent)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]


def shared_reference_dir() -> Path | None:
    """Return ``../shared/reference`` beside the checkout (or $BUBBLECAL_SHARED/reference), or None."""
    env = os.environ.get("BUBBLECAL_SHARED")
    candidates = [Path(env) / "reference"] if env else []
    candidates.append(REPO_ROOT.parent / "shared" / "reference")
    for path in candidates:
        if path.is_dir():
            return path
    return None


@pytest.fixture
def shared_reference() -> Path:
    """Path of the shared reference data; the test is skipped when it is not present."""
    path = shared_reference_dir()
    if path is None:
        pytest.skip("../shared/reference not present")
    return path
