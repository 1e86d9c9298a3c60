"""Published loading grids (bubblecal.sim.protocols.loading)."""

from __future__ import annotations

import numpy as np
import pytest

from bubblecal.sim.protocols import published_compression_protocol, published_indentation_protocol


def test_published_grids():
    c = published_compression_protocol()
    assert c.n_points == 15 and c.displacements_dpd[0] == 0.0
    assert np.allclose(np.diff(c.as_array()), 0.12) and np.isclose(c.displacements_dpd[-1], 1.68)
    for d, fmax in ((3.2, 6000.0), (3.4, 6000.0), (5.8, 8000.0)):
        p = published_indentation_protocol(d)
        assert p.n_points == 15 and p.forces_dpd[0] == 0.0 and p.forces_dpd[-1] == fmax
        assert np.allclose(np.diff(p.as_array()), fmax / 14)
    with pytest.raises(ValueError, match="diameter_um"):
        published_indentation_protocol(2.0)
