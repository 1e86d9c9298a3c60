"""bubblecal.models."""
