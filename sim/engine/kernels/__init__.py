"""bubblecal.sim.engine.kernels."""
