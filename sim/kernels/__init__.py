"""bubblecal.sim.kernels."""
