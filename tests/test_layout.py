"""The house's plan, held by counts: few modules beside the folders, none too long, and the 0.2
import paths still working (with a warning) for one release."""

from __future__ import annotations

import importlib
import importlib.util
import json
import subprocess
import sys
from pathlib import Path

from racecar_sim.old_paths import MCL_MOVED, RACECAR_SIM_MOVED

ROOT = Path(__file__).resolve().parents[1]
KERNELS = {"mcl/filter/step_kernels.py"}
"""Numba kernel modules: one job (the filter's per-update kernels), allowed to be long."""


def flat_modules(package: str) -> list[str]:
    return sorted(p.name for p in (ROOT / package).glob("*.py"))


def test_few_modules_beside_the_folders() -> None:
    assert len(flat_modules("racecar_sim")) <= 8, flat_modules("racecar_sim")
    assert len(flat_modules("mcl")) <= 6, flat_modules("mcl")


def test_no_module_over_400_lines() -> None:
    long = sorted(
        f"{p.relative_to(ROOT)}: {n}"
        for package in ("racecar_sim", "mcl")
        for p in (ROOT / package).rglob("*.py")
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > 400
        and str(p.relative_to(ROOT)) not in KERNELS
    )  # fmt: skip
    assert not long, "\n".join(long)


def test_every_old_path_warns_and_is_the_new_module() -> None:
    moved = RACECAR_SIM_MOVED | MCL_MOVED
    missing = [new for new in moved.values() if importlib.util.find_spec(new) is None]
    assert not missing, f"old paths point at modules that do not exist: {missing}"
    code = (
        "import importlib, json, warnings\n"
        "import mcl, racecar_sim\n"
        f"moved = {moved!r}\n"
        "seen = {}\n"
        "for old, new in sorted(moved.items()):\n"
        "    with warnings.catch_warnings(record=True) as caught:\n"
        "        warnings.simplefilter('always')\n"
        "        module = importlib.import_module(old)\n"
        "    said = [str(w.message) for w in caught if w.category is FutureWarning]\n"
        "    seen[old] = [module is importlib.import_module(new), said]\n"
        "print(json.dumps(seen))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    seen = json.loads(out.stdout)
    for old, new in moved.items():
        same, said = seen[old]
        assert same, f"{old} is not the module {new}"
        parent = old.rsplit(".", 1)[0]
        # a module of a moved package warns when its parent's old path is first imported
        assert any(f"{old} moved to {new}" in s for s in said) or parent in moved, (old, said)


def test_the_quick_start_names_come_from_two_modules() -> None:
    import mcl
    import racecar_sim

    for name in ("RacecarEnv", "RacecarVectorEnv", "RaceEnv", "OccupancyMap", "load_map", "WallFollower"):
        assert getattr(racecar_sim, name) is not None, name
    for name in ("LocalizationWrapper", "LocalizedVectorEnv", "LocalizedRaceEnv", "ParticleFilter",
                 "AdaptiveParticleFilter", "ParticleFilterParams", "LostParams", "DriveRecorder",
                 "read_bag", "replay"):  # fmt: skip
        assert getattr(mcl, name) is not None, name


def test_every_env_says_what_changed_since_v0() -> None:
    from racecar_sim.env import RacecarEnv
    from racecar_sim.race.env import RaceEnv
    from racecar_sim.race.single import RacecarRaceEnv
    from racecar_sim.vector_env import RacecarVectorEnv

    for env_class in (RacecarEnv, RacecarVectorEnv, RaceEnv, RacecarRaceEnv):
        doc = env_class.__doc__ or ""
        assert "## Version History" in doc and "* v0" in doc, env_class.__name__


def test_the_readme_quick_start_imports_from_the_two_packages() -> None:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    code = text.split("## Quick start", 1)[1].split("```python", 1)[1].split("```", 1)[0]
    imports = [line for line in code.splitlines() if line.startswith(("from ", "import "))]
    ours = [line for line in imports if "mcl" in line or "racecar_sim" in line]
    assert ours and all(line.split()[1] in ("mcl", "racecar_sim") for line in ours), ours
