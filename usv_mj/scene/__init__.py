"""Scene: the MJCF of the hulls and the obstacles, and the hull's scaling: a model, never a live plant."""
