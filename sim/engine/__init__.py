"""bubblecal.sim.engine: the Warp DPD engine (mesh, particles, neighbours, system, kernels, minimisers)."""
