"""Runs the file-safety fuzz cases (tests/fuzz/file_mutations.py) for tests/fuzz/worker.py.

A path case runs its command in-process from ``<case folder>/cwd``, after putting the things of
[EXISTING][tests.fuzz.file_mutations.EXISTING] there; a run that would take long (an experiment, a
training) is stubbed: reaching it counts as the command accepting its paths. Afterwards every
file the command did not own must be there with its content (else the outcome is ``loss``), and a
refused command must have created nothing. A scan case writes a bag with the case's LaserScan
header and reads or replays it.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import os
from pathlib import Path
from typing import Any

import numpy as np

from tests.fuzz.mutations import decode

__all__ = ["remove_case_folder", "run_path", "run_scan"]


class RunStarted(Exception):
    """A stubbed long run was reached: the command accepted its command line."""


def _started(*args: Any, **kwargs: Any) -> None:
    raise RunStarted


_STUBS = (
    ("mcl.cli.experiment", "run_experiment"),
    ("mcl.cli.experiment", "run_recovery_experiment"),
    ("mcl.cli.recovery_ablation", "run_recovery_experiment"),
    ("mcl.experiments.fast_laps", "run_fast_laps"),
    ("mcl.cli.opponents", "_run"),
    ("mcl.cli.train_agent", "_train_and_evaluate"),
    ("mcl.calibration.pipeline", "calibrate"),
)


def remove_case_folder(top: Path) -> None:
    """Remove a case's temporary folder (made by the worker with mkdtemp), however deep a path
    case made it (shutil.rmtree recurses once per level); links are removed, never followed."""
    folders, i = [top], 0
    while i < len(folders):
        with os.scandir(folders[i]) as entries:
            for e in entries:
                if e.is_dir(follow_symlinks=False):
                    folders.append(Path(e.path))
                else:
                    os.unlink(e.path)
        i += 1
    for folder in reversed(folders):
        os.rmdir(folder)


def _make(existing: list[str], root: Path) -> set[str]:
    """Put the named things in ``root``; returns the files that must survive (relative names)."""
    from mcl.io import BagRecorder
    from racecar_sim.file_guard import claim_folder
    from tests.conftest import room_map

    user = root / "user"
    if "user" in existing or "link" in existing:
        (user / "nested").mkdir(parents=True)
        (user / "data.txt").write_text("keep")
        (user / ".hidden").write_bytes(b"\x00secret")
        (user / "nested" / "metadata.yaml").write_text("mine: true\n")
    if "file" in existing:
        (root / "file").write_text("a file, not a folder")
    if "empty" in existing:
        (root / "empty").mkdir()
    if "ours" in existing:
        claim_folder(root / "ours")
        (root / "ours" / "notes.txt").write_text("a user's note in our folder")
    if "link" in existing:
        (root / "link").symlink_to(user, target_is_directory=True)
    replaceable = set()
    if "recording" in existing:
        with BagRecorder(root / "recording", room_map(), np.linspace(-1, 1, 5), 10.0, 0.2) as rec:
            rec.write_static(0.0)
        replaceable = {str(p.relative_to(root)) for p in (root / "recording").iterdir()}
    keep = {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file() and not p.is_symlink()}
    return keep - replaceable


def _digest(root: Path, names: set[str]) -> dict[str, str]:
    out = {}
    for name in names:
        path = root / name
        if path.is_file():
            out[name] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def _paths(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def run_path(case: dict[str, Any], tmp: Path) -> dict[str, Any]:
    from unittest import mock

    from mcl.cli.main import main

    cwd = tmp / "cwd"
    cwd.mkdir()
    (tmp / "sentinel.txt").write_text("the parent folder's own file")  # '..' holds files
    keep = _make(case["existing"], cwd) | {"../sentinel.txt"}
    before = _digest(cwd, keep)
    assert len(before) == len(keep), "the case's files were not all made"
    made_before = _paths(tmp)
    argv = list(case["argv"])
    for i, arg in enumerate(argv):
        for name in ("user", "file", "empty", "ours", "recording", "link"):
            arg = arg.replace("{" + name + "}", name)
        argv[i] = arg
    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()
    with contextlib.ExitStack() as stack:
        for module, name in _STUBS:
            stack.enter_context(mock.patch(f"{module}.{name}", _started))
        stack.enter_context(contextlib.redirect_stdout(out))
        stack.enter_context(contextlib.redirect_stderr(err))
        os.chdir(cwd)
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
        except RunStarted:
            code = 0
        finally:
            os.chdir(here)
    after = _digest(cwd, keep)
    lost = sorted(name for name in keep if after.get(name) != before[name])
    left = sorted(_paths(tmp) - made_before) if code != 0 else []
    result = {"outcome": "exit", "exit": code, "stderr": err.getvalue()[-2000:], "left": left}
    if lost:
        result = {"outcome": "loss", "lost": lost, "exit": code, "stderr": err.getvalue()[-500:]}
    return result


def run_scan(case: dict[str, Any], tmp: Path) -> dict[str, Any] | None:
    from mcl.io import read_bag
    from tests.io.scan_bags import write_scan_bag

    fields = decode(case["fields"])
    bag = write_scan_bag(tmp / "bag", case["storage"], **fields)
    if case["via"] == "cli":
        from mcl.cli.main import main

        argv = ["replay", str(bag), "--map", "corridor", "--init", "2,1.5,0", "--video-fps", "0",
                "--out", str(tmp / "out")]  # fmt: skip
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(argv)
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else 1
        left = ["out"] if code != 0 and os.path.lexists(tmp / "out") else []
        stderr = "\n".join(ln for ln in err.getvalue().splitlines() if not ln.startswith("warning"))
        return {"outcome": "exit", "exit": code, "stderr": stderr, "left": left}
    data = read_bag(bag)
    assert data.n_beams >= 1 and data.scans.shape == (data.n_scans, data.n_beams), "scan shape"
    assert np.isfinite(data.angles).all(), "beam angles not finite"
    assert np.isfinite(data.range_max) and data.range_max > 0, "range_max not a range"
    assert np.ptp(data.angles) <= 2 * np.pi + 1e-6, "a fan wider than a turn"
    return None
