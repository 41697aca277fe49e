"""minifilm.dataset."""
