"""Where the package's files are: the MJCF models, found the same way in a checkout and in a wheel.

The repository keeps its models in the top-level ``models/`` folder (the project's design); the
package installs that folder as ``usv_mj.models`` (``package-dir`` in ``pyproject.toml``), so every
caller asks :func:`model_path` instead of building a path from ``__file__``.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

HULL = "usv.xml"
SCENE = "scene.xml"
#: the package's own folder (usv_mj/), whichever layer asks; a checkout's top folder is its parent
PACKAGE_DIR = Path(__file__).resolve().parent.parent


def models_dir() -> Path:
    """The folder that holds ``usv.xml`` and ``scene.xml`` (a real folder: MuJoCo opens files by path)."""
    return Path(str(resources.files("usv_mj.models")))


def model_path(name: str = HULL) -> Path:
    """The path of model file ``name`` (``"usv.xml"``, ``"scene.xml"``); FileNotFoundError names the folder."""
    path = models_dir() / name
    if not path.is_file():
        raise FileNotFoundError(f"usv_mj model file {name!r} not found in {models_dir()} "
                                f"(is the package installed with its models?)")
    return path


def model_files() -> list[Path]:
    """Every model XML file the package ships (hashed into a run log's metadata)."""
    return sorted(models_dir().glob("*.xml"))
