"""minifilm.phases."""
