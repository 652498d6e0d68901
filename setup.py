"""Build hook: the wheel carries the shipped reference set.

``references/default.json`` at the top of the repository stays the one source (it is
rebuilt by the command in ``references/README.md``); building the package copies it to
``dgli_vision/core/data/references/default.json`` inside the wheel, so that an installed
``dgli-classify`` finds it without ``--references``. Everything else is in pyproject.toml.
"""

from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

REFERENCES = Path(__file__).resolve().parent / "references" / "default.json"


class BuildWithReferences(build_py):
    """``build_py`` that also copies the shipped reference set into the package."""

    def run(self) -> None:
        super().run()
        package = Path(self.build_lib) / "dgli_vision" / "core"
        target = package / "data" / "references" / "default.json"
        target.parent.mkdir(parents=True, exist_ok=True)
        self.copy_file(str(REFERENCES), str(target))


setup(cmdclass={"build_py": BuildWithReferences})
