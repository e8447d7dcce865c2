"""The one build step pyproject.toml cannot declare: the wheel's start-up file.

``packaging/usv_mj-gymnasium.pth`` must sit at the top of site-packages (Python reads ``.pth``
files only there), outside the package, so ``build_py`` copies it into the build's root; the wheel
lists it in its RECORD, so ``pip uninstall`` removes it. What it does and why: usv_mj/envs/gymnasium_hook.py.
Editable installs skip it. Everything else about the build is in pyproject.toml.
"""

from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

START_UP = Path(__file__).resolve().parent / "packaging" / "usv_mj-gymnasium.pth"


class BuildPyWithStartUpFile(build_py):
    def run(self):
        super().run()
        if not getattr(self, "editable_mode", False):
            self.copy_file(str(START_UP), str(Path(self.build_lib) / START_UP.name), preserve_mode=False)

    def get_outputs(self, include_bytecode=True):
        outputs = super().get_outputs(include_bytecode)
        if getattr(self, "editable_mode", False):
            return outputs
        return [*outputs, str(Path(self.build_lib) / START_UP.name)]


setup(cmdclass={"build_py": BuildPyWithStartUpFile})
