"""References: trajectories by kind, and guidance planned around obstacles."""
