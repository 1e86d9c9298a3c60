"""bubblecal.surrogates."""
