"""Files written through atomic_write get the permissions of an ordinary new file: 0o666 minus the umask."""

from __future__ import annotations

import os
import stat

import pytest

from bubblecal.data import atomic_write, current_umask


@pytest.mark.parametrize("umask", [0o022, 0o002, 0o077])
def test_atomic_write_honours_the_umask(tmp_path, umask):
    old = os.umask(umask)
    try:
        assert current_umask() == umask
        path = atomic_write(tmp_path / "f.json", lambda p: p.write_text("{}"))
    finally:
        os.umask(old)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask
