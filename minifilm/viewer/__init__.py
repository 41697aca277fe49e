"""Pictures of motion: the paper's Figure 4 phase plot, side-view strips, animations.

Everything here needs matplotlib (the ``viz`` extra), imported inside the drawing functions, so the
core never depends on it.
"""
