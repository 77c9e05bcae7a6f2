"""Every video says what it draws: the drive's and the replay's frames carry a legend whose
swatches are drawn in the frame's own colours; the race's panel (tests/cli/test_race.py) too."""

from __future__ import annotations

import numpy as np
import pytest

import mcl.experiments.replay_output as replay_output
from mcl.experiments.frame_text import draw_legend, put_label
from mcl.experiments.replay import ReplayConfig, replay
from mcl.io import read_bag
from tests.io.bag_fixtures import record_drive


def _has(region: np.ndarray, colour) -> bool:
    return bool(np.all(region == np.array(colour, dtype=np.uint8), axis=-1).any())


def test_a_legend_box_holds_a_swatch_of_each_colour_in_its_corner() -> None:
    img = np.zeros((300, 400, 3), dtype=np.uint8)
    entries = [("box", (200, 10, 10), "box"), ("dots", (10, 200, 10), "dots"),
               ("arrow", (10, 10, 200), "arrow"), ("line", (200, 200, 10), "line")]  # fmt: skip
    x0, y0, x1, y1 = draw_legend(img, entries, "bottom-right")
    assert y1 > 250 and x0 > 150 and x1 < 400  # the bottom-right corner
    region = img[y0 : y1 + 1, x0 : x1 + 1]
    for _, colour, _ in entries:
        assert _has(region, colour)
        assert not _has(img[:y0], colour)  # nothing drawn outside the box
    assert region.mean() > 150  # a light box on the black frame
    with pytest.raises(ValueError, match="swatch"):
        draw_legend(img, [("x", (0, 0, 0), "star")])
    with pytest.raises(ValueError, match="at least one"):
        draw_legend(img, [])


def test_a_label_is_readable_on_any_background() -> None:
    img = np.zeros((40, 120, 3), dtype=np.uint8)
    put_label(img, "car 3", (5, 25), (255, 0, 0))
    assert _has(img, (255, 0, 0)) and _has(img, (255, 255, 255))  # the text and its outline


def test_the_drive_video_frame_has_its_legend() -> None:
    from mcl.cli.drive import DRIVE_LEGEND, _caption

    frame = np.full((400, 600, 3), 255, dtype=np.uint8)
    info = {
        "time": 1.0,
        "localization": {"position_error": 0.01, "heading_error": 0.0, "n_eff": 500},
    }
    _caption(frame, info)
    corner = frame[:150, 350:]
    for text, colour, _ in DRIVE_LEGEND:
        assert _has(corner, colour), text
    assert {t for t, _, _ in DRIVE_LEGEND} == {
        "car (true pose)",
        "lidar hits",
        "particles",
        "MCL estimate",
    }


def test_the_replay_video_frames_have_their_legend(monkeypatch, room, tmp_path) -> None:
    frames: list[np.ndarray] = []

    class Keep:
        def __init__(self, path, fps) -> None:
            self.path = path

        def write(self, frame: np.ndarray) -> None:
            frames.append(frame[:, :, ::-1])  # back to the BGR the frame was drawn in

        def __enter__(self):
            return self

        def __exit__(self, *exc) -> None:
            pass

    monkeypatch.setattr(replay_output, "FrameWriter", Keep)
    record_drive(tmp_path / "bag", room, duration=1.0)
    result = replay(read_bag(tmp_path / "bag"), room, ReplayConfig(init=(5.0, 2.0, 0.0)))
    replay_output.write_video(result, room, "unused.mp4", fps=4.0)
    assert len(frames) >= 4  # 4 per second of recording
    h, w = frames[-1].shape[:2]
    corner = frames[-1][h // 2 :, : w // 2]
    for text, colour, _ in replay_output.REPLAY_LEGEND_BGR:
        assert _has(corner, colour), text
