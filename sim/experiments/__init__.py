"""bubblecal.sim.experiments."""
