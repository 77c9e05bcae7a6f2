"""What racecar-sim (and mcl) may write, replace or remove: only what it made itself.

- **Folders.** An output folder is *ours* when it, or a folder above it with no link in between,
  holds the marker file [MARKER][racecar_sim.file_guard.MARKER];
  [claim_folder][racecar_sim.file_guard.claim_folder] writes the marker when it creates the folder
  or first writes into an empty one. A command writes into a folder only when the folder does not
  exist yet, is empty, or is ours ([folder_problem][racecar_sim.file_guard.folder_problem]);
  anything else is refused before anything runs.
- **Files.** A file is replaced ([writable][racecar_sim.file_guard.writable]) only when it is a
  regular file (not a link) in one of our folders, or when its content shows that racecar-sim wrote
  it (the caller's ``recognise``, e.g. [starts_with][racecar_sim.file_guard.starts_with] an error
  log's header).
- **Removal.** Only what this process created: [Claim.release][racecar_sim.file_guard.Claim.release]
  removes the marker it wrote and the folders it created, when they hold nothing else, with
  ``os.rmdir`` (which cannot remove a file or a folder that is not empty). Nothing here removes a
  tree.
- **Names.** A path given on a command line must be one the operating system and Python take
  ([path_problem][racecar_sim.file_guard.path_problem]): not empty, no NUL, every name at most
  [NAME_MAX][racecar_sim.file_guard.NAME_MAX] bytes, the whole at most
  [PATH_MAX][racecar_sim.file_guard.PATH_MAX] bytes and
  [MAX_DEPTH][racecar_sim.file_guard.MAX_DEPTH] names.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

__all__ = [
    "MARKER",
    "MAX_DEPTH",
    "NAME_MAX",
    "PATH_MAX",
    "Claim",
    "NotOurs",
    "claim_folder",
    "folder_problem",
    "in_our_folder",
    "is_marked",
    "overlaps",
    "path_problem",
    "replace_problem",
    "shown",
    "starts_with",
    "writable",
]

MARKER = ".racecar-sim"
"""The file that makes a folder ours (its text says so)."""
MARKER_TEXT = (
    "This folder was made by racecar-sim. Its commands may replace the files they wrote here;\n"
    "they write into no other folder that already holds files.\n"
)
NAME_MAX = 255
"""Bytes of one file or folder name (Linux's NAME_MAX; longer names are refused by the system)."""
PATH_MAX = 4096
"""Bytes of a whole path with its terminating NUL (Linux's PATH_MAX)."""
MAX_DEPTH = 256
"""Most names in a path: Python's ``Path.mkdir(parents=True)`` (and rosbags' writer with it) makes
one nested call per missing folder, and its recursion limit is 1000 calls."""


class NotOurs(FileExistsError):
    """A file or folder racecar-sim did not make, where it would write or remove (one line)."""


def shown(path: str | os.PathLike[str], limit: int = 120) -> str:
    """``path`` as text of at most ``limit`` characters (its middle cut out) for a message."""
    text = os.fspath(path)
    if len(text) <= limit:
        return text
    half = (limit - 3) // 2
    return f"{text[:half]}...{text[-half:]}"


def path_problem(text: str) -> str | None:
    """Why ``text`` cannot name a file or folder (None: it can): empty, a NUL character, a name
    longer than [NAME_MAX][racecar_sim.file_guard.NAME_MAX] bytes, a path longer than
    [PATH_MAX][racecar_sim.file_guard.PATH_MAX] - 1 bytes or deeper than
    [MAX_DEPTH][racecar_sim.file_guard.MAX_DEPTH] names."""
    if text == "":
        return "is empty; give a folder or file name"
    if "\0" in text:
        return "contains a NUL character"
    raw = os.fsencode(text)
    if len(raw) >= PATH_MAX:
        return f"is {len(raw)} bytes long, more than the system's limit of {PATH_MAX - 1}"
    parts = raw.split(b"/")
    depth = sum(1 for part in parts if part not in (b"", b"."))
    if depth > MAX_DEPTH:
        return f"is {depth} folders deep, more than {MAX_DEPTH}"
    for part in parts:
        if len(part) > NAME_MAX:
            name = shown(os.fsdecode(part), 40)
            return f"has a name of {len(part)} bytes ({name}), more than the system's {NAME_MAX}"
    return None


def is_marked(folder: Path) -> bool:
    """Whether ``folder`` holds our marker (a regular file, not a link)."""
    marker = Path(folder) / MARKER
    return marker.is_file() and not marker.is_symlink()


def in_our_folder(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` lies in one of our folders: a folder above where it really is (links
    resolved: a link in our folder could lead anywhere) holds the marker."""
    folder = Path(os.path.realpath(Path(path).parent))
    while True:
        if is_marked(folder):
            return True
        if folder.parent == folder:
            return False
        folder = folder.parent


def _some_names(folder: Path, n: int = 3) -> tuple[list[str], bool]:
    """Up to ``n`` names in ``folder`` (sorted among the first hundred) and whether there are
    more."""
    with os.scandir(folder) as entries:
        names = sorted(e.name for e in itertools.islice(entries, 100))
    return names[:n], len(names) > n


def folder_problem(folder: str | os.PathLike[str]) -> str | None:
    """Why racecar-sim may not write into ``folder`` (None: it may): it exists and is not a
    folder, or holds files and is not ours."""
    folder = Path(folder)
    try:
        if not os.path.lexists(folder):
            return None
        if not folder.is_dir():
            return f"{shown(folder)} exists and is not a folder"
        if is_marked(folder) or in_our_folder(folder / MARKER):
            return None
        names, more = _some_names(folder)
    except OSError as exc:
        return f"{shown(folder)}: {exc.strerror or exc}"
    if not names:
        return None
    listed = ", ".join(shown(n, 40) for n in names) + (", ..." if more else "")
    return (
        f"{shown(folder)} already holds files racecar-sim did not write ({listed}); give a new or "
        f"empty folder (racecar-sim's own folders hold a file {MARKER})"
    )


@dataclass
class Claim:
    """A folder taken by [claim_folder][racecar_sim.file_guard.claim_folder]: what it created, to
    undo when nothing was written.

    Attributes:
        folder: the claimed folder.
        created: the folders the claim created, outermost first.
        marker_written: whether the claim wrote the marker.
    """

    folder: Path
    created: list[Path] = field(default_factory=list)
    marker_written: bool = False

    def release(self) -> bool:
        """Undo the claim if the folder holds nothing but the marker and empty folders: remove the
        marker it wrote, those empty folders (``os.rmdir``) and the folders it created. Returns
        whether it did; a folder holding any file (a run's logs) is kept as it is."""
        if not self.marker_written and not self.created:
            return False
        try:
            folders = _empty_tree(self.folder)
            if folders is None:
                return False
            if self.marker_written:
                (self.folder / MARKER).unlink()
            for folder in reversed(folders[1:]):  # the deepest first
                os.rmdir(folder)
            for folder in reversed(self.created):
                os.rmdir(folder)
        except OSError:
            return False
        return True


def _empty_tree(top: Path) -> list[Path] | None:
    """The folders below ``top`` (``top`` first, parents before children) when they hold nothing
    but folders and ``top``'s marker; None when there is anything else (a file, a link). Walked
    with a list, not recursion (a tree may be thousands of folders deep)."""
    folders, i = [top], 0
    while i < len(folders):
        with os.scandir(folders[i]) as entries:
            for e in entries:
                if e.is_dir(follow_symlinks=False):
                    folders.append(Path(e.path))
                elif not (i == 0 and e.name == MARKER and e.is_file(follow_symlinks=False)):
                    return None
        i += 1
    return folders


def claim_folder(folder: str | os.PathLike[str], mark: bool = True) -> Claim:
    """Create ``folder`` (and its parents) or take an existing empty or our one, and mark it as ours
    (unless it already is). With ``mark`` False, a shared folder (make-maps' maps folder) is taken
    as it is, unmarked: the caller checks each file it replaces with
    [writable][racecar_sim.file_guard.writable].

    Raises:
        NotOurs: [folder_problem][racecar_sim.file_guard.folder_problem] says why not.
        OSError: the folder cannot be created.
    """
    folder = Path(folder)
    if mark:
        problem = folder_problem(folder)
    elif os.path.lexists(folder) and not folder.is_dir():
        problem = f"{shown(folder)} exists and is not a folder"
    else:
        problem = None
    if problem is not None:
        raise NotOurs(problem)
    created = []
    for parent in [folder, *folder.parents]:
        if os.path.lexists(parent):
            break
        created.insert(0, parent)
    made: list[Path] = []
    try:  # one level at a time: Path.mkdir(parents=True) recurses once per missing level
        for new in created:
            try:
                new.mkdir()
                made.append(new)
            except FileExistsError:  # "a/b/.." is "a", made one step before
                if not new.is_dir():
                    raise
        folder.mkdir(exist_ok=True)
    except OSError:  # e.g. a path too long for the system, found only part of the way down
        for new in reversed(made):
            try:
                os.rmdir(new)
            except OSError:
                break
        raise
    claim = Claim(folder, made)
    if mark and not (is_marked(folder) or in_our_folder(folder / MARKER)):
        with open(folder / MARKER, "x", encoding="utf-8") as f:
            f.write(MARKER_TEXT)
        claim.marker_written = True
    return claim


def starts_with(prefix: bytes) -> Callable[[Path], bool]:
    """A ``recognise`` for [writable][racecar_sim.file_guard.writable]: the file begins with
    ``prefix``."""

    def recognise(path: Path) -> bool:
        with open(path, "rb") as f:
            return f.read(len(prefix)) == prefix

    return recognise


def replace_problem(
    path: str | os.PathLike[str], recognise: Callable[[Path], bool] | None = None
) -> str | None:
    """Why racecar-sim may not write the file ``path`` (None: it may): it exists and is a link,
    not a regular file, or a file neither in our folder nor recognised as ours."""
    path = Path(path)
    try:
        if not os.path.lexists(path):
            return None
        if path.is_symlink():
            return f"{shown(path)} is a link; racecar-sim writes no file through a link"
        if not path.is_file():
            return f"{shown(path)} exists and is not a file"
        if in_our_folder(path) or (recognise is not None and recognise(path)):
            return None
    except OSError as exc:
        return f"{shown(path)}: {exc.strerror or exc}"
    return f"{shown(path)} exists and was not written by racecar-sim; move it or write elsewhere"


def writable(path: str | os.PathLike[str], recognise: Callable[[Path], bool] | None = None) -> Path:
    """``path`` as a Path once [replace_problem][racecar_sim.file_guard.replace_problem] finds
    nothing against writing it.

    Raises:
        NotOurs: it exists and is not ours.
    """
    problem = replace_problem(path, recognise)
    if problem is not None:
        raise NotOurs(problem)
    return Path(path)


def overlaps(a: str | os.PathLike[str], b: str | os.PathLike[str]) -> bool:
    """Whether paths ``a`` and ``b`` are the same or one lies inside the other (links resolved)."""
    ra, rb = Path(a).resolve(), Path(b).resolve()
    return ra == rb or ra in rb.parents or rb in ra.parents
