"""bubblecal.priors."""
