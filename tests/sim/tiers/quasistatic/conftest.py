"""Fixtures of the tier tests: the NumPy reference of the quasi-static tier (``qs_reference.py``, loaded by path)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def qs_reference(load_script):
    """The module ``tests/sim/tiers/quasistatic/qs_reference.py`` (``reference_compression``,
    ``reference_indentation``)."""
    pytest.importorskip("warp")
    return load_script("tests/sim/tiers/quasistatic/qs_reference.py")
