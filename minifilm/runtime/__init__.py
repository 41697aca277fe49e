"""minifilm.runtime.controller."""
