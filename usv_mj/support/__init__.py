"""Support: the numba cache, worker spawning, the package's files, TOML reading."""
