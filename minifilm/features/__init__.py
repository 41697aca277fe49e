"""minifilm.features."""
