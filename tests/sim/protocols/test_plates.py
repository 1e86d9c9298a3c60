"""The compression plates' capped WCA law (bubblecal.sim.protocols.plates)."""

from __future__ import annotations

import numpy as np

from bubblecal.sim.protocols import PlateContact, plate_force_energy


def test_plate_potential_capped_and_consistent():
    c = PlateContact()
    h = np.linspace(-0.5, 1.2, 2001)
    f, e = plate_force_energy(h, c)
    assert np.all(f >= 0) and np.all(f <= c.force_cap + 1e-9)
    assert np.all(f[h >= c.cutoff] == 0) and np.all(e[h >= c.cutoff] == 0)
    assert f[0] == c.force_cap
    # force = -dE/dh (finite differences, away from the kink at the cap)
    hh = np.array([0.93, 0.96, 0.99, 0.5, 0.0])
    d = 1e-6
    fd = -(plate_force_energy(hh + d, c)[1] - plate_force_energy(hh - d, c)[1]) / (2 * d)
    assert np.allclose(fd, plate_force_energy(hh, c)[0], rtol=1e-5, atol=1e-6)
