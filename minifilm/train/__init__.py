"""minifilm.train.trainer."""
