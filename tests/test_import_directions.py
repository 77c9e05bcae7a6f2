"""Imports point down only: the simulator knows nothing of the filter, the filter nothing of the
wrappers or the lab around it, and only the command line and the benchmarks import themselves.

Every import counts (top level, inside a function, under ``TYPE_CHECKING``), as in
``tests/test_import_cycles.py``, whose graph this reads.
"""

from __future__ import annotations

import pytest

from tests.test_import_cycles import import_graph

FILTER = "mcl.filter"
"""The particle filter and its parts."""
WRAPPERS = ("mcl.wrappers",)
LAB = (
    "mcl.io", "mcl.experiments", "mcl.calibration", "mcl.mapping", "mcl.agents", "mcl.bench", "mcl.cli",
)


def within(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return import_graph()


def test_the_graph_sees_the_packages(graph) -> None:
    assert "racecar_sim.env" in graph and "mcl.filter.particle_filter" in graph
    assert "racecar_sim.env" in graph["racecar_sim.vector_env"]  # it does import the env


def test_racecar_sim_never_imports_mcl(graph) -> None:
    bad = sorted(
        f"{m} -> {d}" for m, deps in graph.items() if within(m, "racecar_sim")
        for d in deps if within(d, "mcl")
    )  # fmt: skip
    assert not bad, "\n".join(bad)


def test_the_filter_imports_neither_wrappers_nor_the_lab(graph) -> None:
    filter_modules = [m for m in graph if within(m, FILTER)]
    assert "mcl.filter.particle_filter" in filter_modules and len(filter_modules) >= 15
    bad = sorted(
        f"{m} -> {d}" for m in filter_modules for d in graph[m]
        if any(within(d, p) for p in WRAPPERS + LAB)
    )  # fmt: skip
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("lab", ["mcl.cli", "mcl.bench"])
def test_only_the_command_line_and_the_benchmarks_import_themselves(graph, lab: str) -> None:
    bad = sorted(
        f"{m} -> {d}" for m, deps in graph.items() if not within(m, lab)
        for d in deps if within(d, lab)
    )  # fmt: skip
    assert not bad, "\n".join(bad)


SIM_LAYERS = {
    "racecar_sim.raycast": ("car", "sensors", "world", "drivers", "env", "vector_env", "fleet", "race"),
    "racecar_sim.car": ("sensors", "world", "drivers", "env", "vector_env", "fleet", "race"),
    "racecar_sim.sensors": ("world", "drivers", "env", "vector_env", "fleet", "race"),
    "racecar_sim.world": ("car", "sensors", "drivers", "env", "vector_env", "fleet", "race"),
    "racecar_sim.drivers": ("env", "vector_env", "fleet", "race"),
    "racecar_sim.fleet": ("drivers", "env", "vector_env", "race"),
    "racecar_sim.env": ("vector_env", "race"),
}
"""Inside the simulator: the car, its sensors and the world below the core that steps N cars (the
fleet), the core below the envs (the single env is the core with one car), the drivers below the
envs, the single env below the N-car ones and the race (docs/ARCHITECTURE.md, Layout)."""


@pytest.mark.parametrize("package", sorted(SIM_LAYERS))
def test_the_simulator_s_folders_import_downwards(graph, package: str) -> None:
    above = tuple(f"racecar_sim.{name}" for name in SIM_LAYERS[package])
    bad = sorted(
        f"{m} -> {d}" for m, deps in graph.items() if within(m, package)
        for d in deps if any(within(d, p) for p in above)
    )  # fmt: skip
    assert not bad, "\n".join(bad)


def test_the_wrappers_import_no_lab_module(graph) -> None:
    """The wrappers take step hooks; the bag recorder and the live view (``mcl.io``) attach to them
    from above (the command line, the experiments), never the other way round."""
    wrapper_modules = [m for m in graph if within(m, WRAPPERS[0])]
    assert {"mcl.wrappers.single", "mcl.wrappers.hooks"} <= set(wrapper_modules)
    bad = sorted(
        f"{m} -> {d}" for m in wrapper_modules for d in graph[m]
        if any(within(d, p) for p in LAB)
    )  # fmt: skip
    assert not bad, "\n".join(bad)


def test_the_wrappers_import_nothing_by_name_at_run_time() -> None:
    """No ``importlib.import_module(...)`` or ``__import__(...)`` behind the graph's back."""
    import ast

    from tests.test_import_cycles import ROOT

    found = []
    for path in sorted((ROOT / "mcl" / "wrappers").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call):
                name = getattr(node.func, "attr", None) or getattr(node.func, "id", None)
                if name in ("import_module", "__import__"):
                    found.append(f"{path.name}:{node.lineno}")
    assert not found, found
