"""Loop: the one control step and the loops that drive it (the Python loop and the compiled one)."""
