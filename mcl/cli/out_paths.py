"""The folders and files a command writes (``--out``, ``--bag``): checked before anything runs, so
that a command never writes into, replaces or removes what racecar-sim did not make
([file_guard][racecar_sim.file_guard]).

- Every path flag's text must be a name the system takes ([path_arg][mcl.cli.out_paths.path_arg]):
  ``''`` (which would be the current folder), a name over 255 bytes, a path over 4095 bytes or
  more than 256 folders deep stop the command naming the flag.
- ``--out`` is a new folder, an empty one, or one of ours, with room for any file name inside
  ([check_out][mcl.cli.out_paths.check_out]); the command then claims it
  ([output_folder][mcl.cli.out_paths.output_folder]) and undoes the claim if it fails before writing
  anything.
- A ``--out`` that names files (``update-map``'s map YAML and its PGM) is new files only
  ([check_new_files][mcl.cli.out_paths.check_new_files]).
- ``--bag`` is a new folder or exactly a recording of ours, and neither holds the other's folder
  nor lies in it ([check_bag][mcl.cli.out_paths.check_bag]); its name leaves room for
  ``<name>.mcap``.
"""

from __future__ import annotations

import argparse
import contextlib
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import NoReturn, Protocol

from racecar_sim.file_guard import (
    NAME_MAX,
    PATH_MAX,
    NotOurs,
    claim_folder,
    folder_problem,
    overlaps,
    path_problem,
    replace_problem,
    shown,
)

__all__ = [
    "check_bag",
    "check_file_out",
    "check_new_files",
    "check_out",
    "output_folder",
    "path_arg",
]


class Parser(Protocol):
    """What the checks need of [mcl.cli.common.Parser][mcl.cli.common.Parser]."""

    def fail(self, flag: str, problem: str) -> NoReturn:
        """Stop with ``FLAG: PROBLEM`` (exit code 2)."""

    def error(self, message: str) -> NoReturn:
        """Stop with ``PROBLEM`` (exit code 2)."""


def path_arg(text: str) -> Path:
    """argparse type of a path flag: refuses ``''``, a NUL, a name over 255 bytes, a path over
    4095 bytes and one more than 256 folders deep
    ([path_problem][racecar_sim.file_guard.path_problem])."""
    problem = path_problem(text)
    if problem is not None:
        raise argparse.ArgumentTypeError(problem)
    return Path(text)


def _check_parent(parser: Parser, path: Path, flag: str) -> None:
    """The nearest existing folder above ``path`` is a folder we may write into."""
    parent = path
    while not os.path.lexists(parent):
        parent = parent.parent
    if not parent.is_dir():
        parser.fail(flag, f"{shown(parent)} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        parser.fail(flag, f"cannot write into {shown(parent)}")


def check_out(parser: Parser, path: Path, flag: str = "--out", owned: bool = True) -> Path:
    """Check that folder ``path`` can be created or written into (nothing is created here): short
    enough for any file name inside (at most 3839 bytes), not a file, the folder above it
    writable and, with ``owned``, it is new, empty or ours
    ([folder_problem][racecar_sim.file_guard.folder_problem]). Without ``owned`` (a shared folder
    such as make-maps' maps folder) the caller checks each file it would replace."""
    size = len(os.fsencode(path))
    if size > PATH_MAX - 2 - NAME_MAX:
        parser.fail(
            flag,
            f"is {size} bytes long; a folder's path may have at most {PATH_MAX - 2 - NAME_MAX} "
            f"bytes, so that every file in it stays within the system's {PATH_MAX - 1}",
        )
    try:
        if os.path.lexists(path) and not path.is_dir():
            parser.fail(flag, f"{shown(path)} exists and is not a folder")
        problem = folder_problem(path) if owned else None
        if problem is not None:
            parser.fail(flag, problem)
        _check_parent(parser, path, flag)
    except OSError as exc:
        parser.fail(flag, f"{shown(path)}: {exc.strerror or exc}")
    return path


def check_file_out(
    parser: Parser, path: Path, flag: str, recognise: Callable[[Path], bool] | None = None
) -> Path:
    """Check that file ``path`` can be written: not a folder, the folder above it writable, and,
    when it exists, ours (in our folder, or ``recognise`` says racecar-sim wrote it)."""
    try:
        if path.is_dir():
            parser.fail(flag, f"{shown(path)} is a folder; give a file name")
        problem = replace_problem(path, recognise)
        if problem is not None:
            parser.fail(flag, problem)
        _check_parent(parser, path.parent, flag)
    except OSError as exc:
        parser.fail(flag, f"{shown(path)}: {exc.strerror or exc}")
    return path


def check_new_files(parser: Parser, paths: tuple[Path, ...], flag: str) -> None:
    """Check that none of ``paths`` (a file and the files written beside it) exists and that the
    nearest existing folder above them is one we may write into; nothing is created here."""
    try:
        for path in paths:
            if os.path.lexists(path):
                parser.fail(flag, f"{shown(path)} is already there; the command writes new files only")
        _check_parent(parser, paths[0].parent, flag)
    except OSError as exc:
        parser.fail(flag, f"{shown(paths[0])}: {exc.strerror or exc}")


def check_bag(parser: Parser, bag: Path, out: Path, flag: str = "--bag") -> Path:
    """Check the recording folder ``bag`` before anything runs: outside ``out`` (and ``out``
    outside it), and new or exactly a recording of ours ([bag_folder][mcl.io.bag_folder])."""
    from mcl.io.bag_folder import recording_problem
    from mcl.io.bag_writer import TOPICS

    check_out(parser, bag, flag, owned=False)
    name = len(os.fsencode(bag.name))
    if name + len(".mcap") > NAME_MAX:
        parser.fail(
            flag,
            f"has a last name of {name} bytes; the recording's file <name>.mcap must stay "
            f"within the system's {NAME_MAX}: at most {NAME_MAX - len('.mcap')}",
        )
    try:
        if overlaps(bag, out):
            parser.fail(
                flag,
                f"{shown(bag)} and --out {shown(out)} overlap; give the recording a folder outside "
                "the output folder",
            )
    except (OSError, RuntimeError) as exc:
        parser.fail(flag, f"{shown(bag)}: {exc}")
    problem = recording_problem(bag, TOPICS)
    if problem is not None:
        parser.fail(flag, problem)
    return bag


@contextlib.contextmanager
def output_folder(
    parser: Parser, path: Path, flag: str = "--out", mark: bool = True
) -> Iterator[Path]:
    """Claim folder ``path`` for the body ([claim_folder][racecar_sim.file_guard.claim_folder]:
    created with its parents, or an empty or our existing one, marked as ours unless ``mark`` is
    False); stop naming ``flag`` if it cannot be. If the body raises while nothing was written, the
    claim is undone (the marker and the folders it created are removed); whatever was written is
    kept.

    A map problem found only when the env is built or reset ([MapError][racecar_sim.maps.MapError]:
    no room for the car, no free start pose, no room for obstacles) ends the command like any
    other mistake: one line and exit code 2.
    """
    from racecar_sim.maps import MapError

    try:
        claim = claim_folder(path, mark=mark)
    except NotOurs as exc:
        parser.fail(flag, str(exc))
    except OSError as exc:
        parser.fail(flag, f"cannot create folder {shown(path)}: {exc.strerror or exc}")
    try:
        yield path
    except BaseException as exc:
        claim.release()
        if isinstance(exc, MapError):
            parser.error(str(exc))
        raise
