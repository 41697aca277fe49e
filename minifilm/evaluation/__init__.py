"""minifilm.evaluation."""
