"""Physics: every formula of the hull, the MMG, the disturbances, the actuators and the sea, written once (knows no integrator, no MuJoCo, no scenario file)."""
