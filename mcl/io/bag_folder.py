"""When a recording may be replaced: only a folder that holds exactly a recording of ours.

A recording of [BagRecorder][mcl.io.BagRecorder] is a ROS 2 bag folder holding two regular files and
nothing else: ``metadata.yaml`` (rosbag2's, storage ``mcap``, listing the one data file) and that
``.mcap`` file, with exactly the recorder's topics and message types. Anything else at the path
(a file, a link, an empty folder, a folder with one more file, another bag) is refused, never
removed; a recording of ours is removed file by file (two ``unlink`` and one ``rmdir``).
"""

from __future__ import annotations

import itertools
import os
from pathlib import Path

from racecar_sim.file_guard import NotOurs, shown
from racecar_sim.settings.validation import load_yaml, read_text

__all__ = ["recording_problem", "remove_recording"]

_METADATA = "metadata.yaml"


def _recording_files(path: Path, topics: dict[str, str]) -> tuple[Path, Path] | str:
    """(metadata, mcap) of the recording at ``path``, or why it is not one of ours."""
    if path.is_symlink():
        return "is a link"
    if not path.is_dir():
        return "exists and is not a folder"
    with os.scandir(path) as it:
        entries = list(itertools.islice(it, 3))
    names = sorted(e.name for e in entries)
    if not names:
        return "is an existing empty folder"
    if len(entries) != 2 or _METADATA not in names:
        return "holds other files than a recording's metadata.yaml and .mcap file"
    if not all(e.is_file(follow_symlinks=False) for e in entries):
        return "holds a link or a folder"
    data = next(n for n in names if n != _METADATA)
    try:
        info = load_yaml(read_text(path / _METADATA))["rosbag2_bagfile_information"]
        recorded = {
            t["topic_metadata"]["name"]: t["topic_metadata"]["type"]
            for t in info["topics_with_message_count"]
        }
        ours = (
            info["storage_identifier"] == "mcap"
            and info["relative_file_paths"] == [data]
            and data.endswith(".mcap")
            and recorded == topics
        )
    except Exception:  # any metadata that is not rosbag2's as we write it
        ours = False
    if not ours:
        return "holds a bag that is not a racecar-sim recording (other topics or storage)"
    return path / _METADATA, path / data


def recording_problem(path: str | os.PathLike[str], topics: dict[str, str]) -> str | None:
    """Why the recording at ``path`` may not be replaced (None: nothing is there, or a recording
    of ours with exactly ``topics``, topic name -> message type)."""
    path = Path(path)
    try:
        if not os.path.lexists(path):
            return None
        found = _recording_files(path, topics)
    except OSError as exc:
        return f"{shown(path)}: {exc.strerror or exc}"
    if isinstance(found, str):
        return (
            f"{shown(path)} {found}; give a new folder (an existing one is replaced only when it "
            "holds exactly a racecar-sim recording)"
        )
    return None


def remove_recording(path: str | os.PathLike[str], topics: dict[str, str]) -> None:
    """Remove the recording of ours at ``path`` (its two files, then the empty folder).

    Raises:
        NotOurs: it is not exactly a recording of ours
            ([recording_problem][mcl.io.bag_folder.recording_problem]); nothing removed.
    """
    path = Path(path)
    problem = recording_problem(path, topics)
    if problem is not None:
        raise NotOurs(problem)
    if not os.path.lexists(path):
        return
    found = _recording_files(path, topics)
    assert not isinstance(found, str)
    for file in found:
        file.unlink()
    path.rmdir()
