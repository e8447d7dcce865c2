"""The scenario presets: one TOML file each (``paper.toml``, ...), read by :mod:`usv_mj.scenario.spec`."""

from importlib import resources


def names() -> list[str]:
    """The presets' names, sorted (the files of this package; standard library only)."""
    return sorted(p.name[:-5] for p in resources.files(__name__).iterdir() if p.name.endswith(".toml"))
