"""Build step: the bundled maps live in the repository's top-level ``maps/`` folder; a wheel
carries them as package data in ``racecar_sim/maps/data`` (``racecar_sim.maps.bundled.maps_dir``
finds either). Everything else is configured in pyproject.toml."""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

MAPS = Path(__file__).resolve().parent / "maps"


class BuildPyWithMaps(build_py):
    """build_py, then ``maps/*.yaml``, ``*.png`` and ``*.csv`` (the loop maps' tracks) copied into the built package."""

    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):
            return  # an editable install reads the checkout's maps/ directly
        target = Path(self.build_lib) / "racecar_sim" / "maps" / "data"
        target.mkdir(parents=True, exist_ok=True)
        files = sorted(p for p in MAPS.glob("*") if p.suffix in (".yaml", ".png", ".csv"))
        if not files:
            raise RuntimeError(f"no bundled maps in {MAPS}: run racecar-sim make-maps")
        for path in files:
            shutil.copy2(path, target / path.name)


setup(cmdclass={"build_py": BuildPyWithMaps})
