"""minifilm.synthetic."""
