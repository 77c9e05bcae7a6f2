"""An editable install (``pip install -e .``, what the README's commands do) reads the bundled maps
from the checkout's top-level ``maps/`` folder, live: a map drawn there is found by name at once.

The project goes into a fresh venv from a copy of the sources (``--no-deps``); its dependencies
come from the running interpreter's site-packages, appended to the fresh venv's path by a ``.pth``
line (a folder added that way runs none of its own ``.pth`` files, so the dev venv's editable
install of the project cannot answer the import).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

PROBE = textwrap.dedent(
    """
    import json
    import gymnasium as gym
    import racecar_sim
    from racecar_sim.maps import bundled_names
    from racecar_sim.maps.bundled import maps_dir

    env = gym.make("RacecarSim-v0", map="office")
    obs, info = env.reset(seed=0)
    print(json.dumps({"module": racecar_sim.__file__, "maps_dir": str(maps_dir()),
                      "maps": bundled_names(), "scan": int(obs["scan"].shape[0])}))
    """
)


@pytest.mark.slow
def test_editable_install_reads_the_checkouts_maps_folder(tmp_path: Path) -> None:
    src = tmp_path / "src"
    ignore = shutil.ignore_patterns("__pycache__", "*.egg-info", "build", "*.pyc", "*.nbi", "*.nbc")
    for name in ("racecar_sim", "mcl", "maps"):
        shutil.copytree(REPO / name, src / name, ignore=ignore)
    for name in ("pyproject.toml", "setup.py", "MANIFEST.in", "README.md"):
        shutil.copy2(REPO / name, src / name)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    venv = tmp_path / "venv"
    run = lambda cmd, **kw: subprocess.run(  # noqa: E731
        cmd, capture_output=True, text=True, timeout=600, env=kw.pop("env", env), **kw
    )
    done = run([sys.executable, "-m", "venv", str(venv)])
    assert done.returncode == 0, done.stderr
    python = venv / ("Scripts" if os.name == "nt" else "bin") / "python"
    done = run([str(python), "-m", "pip", "install", "-q", "--no-deps", "-e", str(src)], cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert not (src / "racecar_sim" / "maps" / "data").exists()  # nothing copied into the package

    probe_env = env
    site = run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"])
    deps = Path(site.stdout.strip()) / "zz_dev_dependencies.pth"
    deps.write_text(sysconfig.get_paths()["purelib"] + "\n", encoding="utf-8")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    done = run([str(python), "-c", PROBE], cwd=elsewhere, env=probe_env)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert Path(result["module"]).is_relative_to(src)
    assert Path(result["maps_dir"]) == src / "maps"
    assert result["maps"] == sorted(p.stem for p in (REPO / "maps").glob("*.yaml"))
    assert result["scan"] > 0

    shutil.copy2(src / "maps" / "office.yaml", src / "maps" / "office_copy.yaml")  # a new map
    done = run([str(python), "-c", PROBE], cwd=elsewhere, env=probe_env)
    assert done.returncode == 0, done.stderr
    assert "office_copy" in json.loads(done.stdout.strip().splitlines()[-1])["maps"]
