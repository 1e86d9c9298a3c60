"""A surrogate file that is not an archive, or whose bytes are damaged, is a SurrogateFormatError naming it."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from bubblecal.surrogates import SurrogateFormatError, load

BUNDLE = Path(__file__).resolve().parents[2] / "surrogates" / "bundle"


def shipped() -> Path:
    return sorted(BUNDLE.glob("*.npz"))[0]


def test_a_file_that_is_not_an_archive(tmp_path):
    path = tmp_path / "x.npz"
    path.write_text("not an archive")
    with pytest.raises(SurrogateFormatError, match=r"x\.npz: not a \.npz archive") as err:
        load(path)
    assert "allow_pickle" not in str(err.value)


def test_a_bit_flip_inside_an_array(tmp_path):
    path = tmp_path / "flip.npz"
    shutil.copy(shipped(), path)
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))
    with pytest.raises(SurrogateFormatError, match=r"flip\.npz: damaged \.npz \(BadZipFile"):
        load(path)
    assert load(shipped()).setup in ("compression", "indentation")  # the intact file still loads
