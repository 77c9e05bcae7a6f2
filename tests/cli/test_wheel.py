"""A regular install works: the wheel carries the bundled maps, the version and the console command.

Builds the wheel from a copy of the sources (``pip wheel --no-deps``), installs it into a fresh
venv (its dependencies from the configured package index), and from another folder makes
``RacecarSim-v0`` on the default bundled map, drives it, and runs ``racecar-sim``. A fresh venv
and not ``--system-site-packages``: nothing of the project or of the dev venv can be borrowed, so
a missing dependency, package-data entry or entry point fails here.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
BUNDLED = sorted(p.stem for p in (REPO / "maps").glob("*.yaml"))

DRIVE = textwrap.dedent(
    """
    import json, sys
    from importlib.metadata import version
    from pathlib import Path

    import gymnasium as gym
    import numpy as np

    import racecar_sim
    from racecar_sim.drivers import WallFollower
    from racecar_sim.maps import bundled_names

    env = gym.make("RacecarSim-v0")
    obs, info = env.reset(seed=0)
    start = np.array(info["pose"], dtype=float)
    driver = WallFollower()
    for _ in range(40):
        obs, reward, terminated, truncated, info = env.step(driver(obs))
        assert not terminated, "the wall follower hit a wall in 1 s"
    print(json.dumps({
        "module": racecar_sim.__file__,
        "version": racecar_sim.__version__,
        "dist_version": version("racecar-sim"),
        "maps": bundled_names(),
        "moved": float(np.hypot(*(np.array(info["pose"][:2]) - start[:2]))),
        "scan": int(obs["scan"].shape[0]),
    }))
    """
)


def _run(cmd: list[str], cwd: Path, env: dict[str, str], timeout: float = 300):
    done = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    return done


@pytest.mark.slow
def test_wheel_installs_into_a_fresh_venv_and_drives(tmp_path: Path) -> None:
    import json

    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"

    src = tmp_path / "src"  # build from a copy: the checkout gets no build/ or egg-info
    ignore = shutil.ignore_patterns("__pycache__", "*.egg-info", "build", "*.pyc", "*.nbi", "*.nbc")
    for name in ("racecar_sim", "mcl", "maps"):
        shutil.copytree(REPO / name, src / name, ignore=ignore)
    for name in ("pyproject.toml", "setup.py", "MANIFEST.in", "README.md"):
        shutil.copy2(REPO / name, src / name)
    dist = tmp_path / "dist"
    done = _run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(dist), str(src)],
        tmp_path,
        env,
    )
    assert done.returncode == 0, done.stderr
    (wheel,) = dist.glob("racecar_sim-*.whl")

    venv = tmp_path / "venv"
    done = _run([sys.executable, "-m", "venv", str(venv)], tmp_path, env)
    assert done.returncode == 0, done.stderr
    bin_dir = venv / ("Scripts" if os.name == "nt" else "bin")
    done = _run(
        [str(bin_dir / "python"), "-m", "pip", "install", "-q", "--no-compile", str(wheel)],
        tmp_path,
        env,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr

    elsewhere = tmp_path / "elsewhere"  # neither the checkout nor the copy is importable from here
    elsewhere.mkdir()
    done = _run([str(bin_dir / "python"), "-c", DRIVE], elsewhere, env)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert Path(result["module"]).is_relative_to(venv)
    assert result["version"] == result["dist_version"]
    assert result["maps"] == BUNDLED
    assert result["moved"] > 0.5  # 1 s of driving at the wall follower's speed
    assert result["scan"] > 0

    command = bin_dir / "racecar-sim"
    done = _run([str(command), "--help"], elsewhere, env)
    assert done.returncode == 0, done.stderr
    assert "drive" in done.stdout and "experiment" in done.stdout
    done = _run([str(command), "--version"], elsewhere, env)
    assert done.stdout.strip() == f"racecar-sim {result['version']}"
    out = elsewhere / "out"
    done = _run([str(command), "drive", "--map", "nowhere", "--out", str(out)], elsewhere, env)
    assert done.returncode == 2
    assert len(done.stderr.splitlines()) == 1 and "--map" in done.stderr
    assert not out.exists()

    # installed defaults: make-maps draws into ./maps (never into the venv) and says so; a benchmark
    # whose default map (../shared beside the working directory) is absent names --map in one line
    done = _run([str(command), "make-maps"], elsewhere, env)
    assert done.returncode == 0, done.stderr
    assert "installed, not run from a source checkout" in done.stdout
    assert (elsewhere / "maps" / "basement_loop.yaml").is_file()
    done = _run([str(command), "bench", "mcl", "--updates", "1"], elsewhere, env)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert f"--map: {tmp_path / 'shared' / 'maps' / 'stata_basement.yaml'} not found" in done.stderr
