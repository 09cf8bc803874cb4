"""The wheel carries the bundled data: ``configs/``, ``envs/``, ``episodes/`` and ``policies/`` (the top-level
directories of the checkout) are copied into the built package as ``navbench/_data/``, where
:mod:`navbench.paths` finds them. An editable install reads them from the checkout instead."""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

DATA_DIRS = ("configs", "envs", "episodes", "policies")  # navbench.paths.DATA_DIRS


class BuildWithData(build_py):
    def run(self):
        super().run()
        if self.editable_mode:
            return
        here = Path(__file__).resolve().parent
        target = Path(self.build_lib) / "navbench" / "_data"
        for name in DATA_DIRS:
            if not (here / name).is_dir():
                raise SystemExit(f"setup.py: {here / name} is missing: the wheel must carry the bundled data")
            shutil.rmtree(target / name, ignore_errors=True)
            shutil.copytree(here / name, target / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))


setup(cmdclass={"build_py": BuildWithData})
