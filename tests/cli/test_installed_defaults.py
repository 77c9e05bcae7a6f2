"""Defaults that make sense from an installed package, not only from a checkout: ``make-maps`` never
draws into site-packages, and the benchmarks look for ``../shared`` beside the checkout or, when
installed, beside the working directory, and name the flag when its map is not there.

"Installed" is simulated by :func:`racecar_sim.maps.bundled.checkout_maps_dir` returning None (what
it returns in a wheel); ``tests/cli/test_wheel.py`` runs the real installed command."""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest

from mcl.bench import shared_dir, stata_map
from mcl.cli.main import main
from mcl.cli.make_maps import default_out

REPO = Path(__file__).resolve().parents[2]
bundled = importlib.import_module("racecar_sim.maps.bundled")


@pytest.fixture
def installed(monkeypatch, tmp_path):
    """Run as an installed package from ``tmp_path/work``; returns that folder."""
    monkeypatch.setattr(bundled, "checkout_maps_dir", lambda: None)
    monkeypatch.delenv("RACECAR_SIM_MAPS", raising=False)
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    return work


def _package_data() -> dict[str, float]:
    folder = Path(bundled.__file__).resolve().parent / "data"
    return {p.name: p.stat().st_mtime_ns for p in folder.glob("*")} if folder.is_dir() else {}


def test_in_a_checkout_the_defaults_are_the_checkouts(monkeypatch) -> None:
    monkeypatch.delenv("RACECAR_SIM_MAPS", raising=False)
    assert default_out() == (REPO / "maps", None)
    assert shared_dir() == REPO.parent / "shared"
    assert stata_map() == REPO.parent / "shared" / "maps" / "stata_basement.yaml"


def test_installed_make_maps_draws_into_the_working_directory_and_says_so(
    installed, capsys
) -> None:
    before = _package_data()
    assert main(["make-maps"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].startswith("racecar-sim is installed, not run from a source checkout")
    assert str(installed / "maps") in out.splitlines()[0]
    assert {p.stem for p in (installed / "maps").glob("*.yaml")} >= {"basement_loop", "office"}
    assert _package_data() == before  # nothing written into the package


def test_installed_benchmarks_look_beside_the_working_directory(installed) -> None:
    assert shared_dir() == installed.parent / "shared"
    assert "site-packages" not in str(stata_map()) and "lib/python" not in str(stata_map())


@pytest.mark.parametrize(
    "argv",
    [
        ["bench", "mcl", "--updates", "1"],
        ["bench", "peers", "--only", "rangelibc"],
        ["bench", "replay", "--bag", "__file__"],
    ],
)
def test_a_missing_default_map_is_one_line_naming_the_flag(installed, capsys, argv) -> None:
    argv = [str(Path(__file__)) if a == "__file__" else a for a in argv]
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2
    assert len(err.strip().splitlines()) == 1, err
    expected = installed.parent / "shared" / "maps" / "stata_basement.yaml"
    assert f"error: --map: {expected} not found" in err and "give --map MAP.yaml" in err


def test_installed_replay_benchmark_without_bags_names_the_flag(installed, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["bench", "replay"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "error: --bag: none given and no bag in" in err
    assert len(err.strip().splitlines()) == 1
