"""Core: the error family, the registries, the kernel contract and the shared array layouts (imports nothing of usv_mj above it)."""
