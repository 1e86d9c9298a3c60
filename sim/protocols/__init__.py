"""bubblecal.sim.protocols: loading grids, MD compression / indentation, ringdown and its PCA."""
