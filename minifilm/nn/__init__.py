"""The deep-learning kit, written from scratch. Knows nothing about motion."""
