"""Tests of the main job, scripts/drive.py, and of the frame writer it uses (mcl.experiments.video)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

import mcl.experiments.video
from mcl.experiments.video import FrameWriter
from mcl.wrappers.error_log import read_error_log
from racecar_sim.file_guard import MARKER

REPO = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.filterwarnings(
    "ignore:.*(symmetric and normalized|infinity. This is probably).*:UserWarning"
)


def _load_script():
    spec = importlib.util.spec_from_file_location("drive_script", REPO / "scripts" / "drive.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["drive_script"] = module
    spec.loader.exec_module(module)
    return module


drive = _load_script()


def test_main_job_writes_log_plot_and_video(tmp_path, capsys) -> None:
    out = tmp_path / "drive"
    args = ["--out", str(out), "--duration", "2", "--particles", "150", "--quiet"]
    assert drive.main([*args, "--video-fps", "10"]) == 0
    printed = capsys.readouterr().out
    assert "position error: mean" in printed
    assert f"output folder: {out.resolve()}" in printed

    log = read_error_log(out / "error_log.csv")
    assert len(log) == 80  # 2 s at the env's 0.025 s steps
    np.testing.assert_allclose(log.time[-1], 2.0)
    assert log.position_error.max() < 0.5  # tracking on the default map

    plot = cv2.imread(str(out / "error.png"))
    assert plot is not None and plot.shape[0] > 100

    video = cv2.VideoCapture(str(out / "drive.mp4"))
    assert video.isOpened()
    frames = []
    while True:
        ok, frame = video.read()
        if not ok:
            break
        frames.append(frame)
    video.release()
    assert len(frames) == 1 + 80 // 4  # the reset, then every 4th step at 10 frames per second
    assert not np.array_equal(frames[0], frames[-1])  # the car moved


def test_main_job_without_video(tmp_path, capsys) -> None:
    out = tmp_path / "novideo"
    drive.main(["--out", str(out), "--duration", "0.5", "--particles", "50", "--video-fps", "0"])
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "error.png", "error_log.csv"]
    assert "drive.mp4" not in capsys.readouterr().out


def _frames(n: int, size=(41, 60)) -> list[np.ndarray]:
    rng = np.random.default_rng(0)
    return [rng.integers(0, 256, (*size, 3), dtype=np.uint8) for _ in range(n)]


def test_frame_writer_falls_back_to_png_frames(tmp_path, monkeypatch) -> None:
    class Broken:
        def __init__(self, *args) -> None:
            pass

        def isOpened(self) -> bool:
            return False

        def release(self) -> None:
            pass

    monkeypatch.setattr(mcl.experiments.video.cv2, "VideoWriter", Broken)
    frames = _frames(3)
    with FrameWriter(tmp_path / "clip.mp4", fps=5) as writer:
        for f in frames:
            writer.write(f)
    assert writer.kind == "png" and writer.n_frames == 3
    assert writer.path == tmp_path / "clip_frames"
    files = sorted(writer.path.glob("*.png"))
    assert len(files) == 3
    back = cv2.cvtColor(cv2.imread(str(files[1])), cv2.COLOR_BGR2RGB)
    np.testing.assert_array_equal(back[:41, :60], frames[1])  # padded to even size, lossless


def test_frame_writer_writes_an_mp4(tmp_path) -> None:
    with FrameWriter(tmp_path / "clip.mp4", fps=5) as writer:
        for f in _frames(4, (40, 64)):
            writer.write(f)
    assert writer.kind == "mp4"
    cap = cv2.VideoCapture(str(tmp_path / "clip.mp4"))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 4
    cap.release()


def test_frame_writer_rejects_bad_frames(tmp_path) -> None:
    writer = FrameWriter(tmp_path / "clip.mp4", fps=5, force_png=True)
    with pytest.raises(ValueError, match="RGB uint8"):
        writer.write(np.zeros((4, 4), dtype=np.uint8))
    writer.write(np.zeros((4, 4, 3), dtype=np.uint8))
    with pytest.raises(ValueError, match="differs"):
        writer.write(np.zeros((6, 4, 3), dtype=np.uint8))
    with pytest.raises(ValueError, match="fps"):
        FrameWriter(tmp_path / "x.mp4", fps=0)


def test_filter_settings_reach_the_filter_and_bad_ones_are_one_line(tmp_path, capsys) -> None:
    """``--filter KEY=VALUE``: a calibration that says the wheels read 1 m/s over the truth makes
    the filter move its estimate 1 m/s slower than the car, so it falls behind; the defaults
    track. A malformed or out-of-range setting is a one-line error naming the flag, no folder."""
    base = ["--duration", "2", "--particles", "150", "--quiet", "--video-fps", "0"]
    errors = {}
    for name, extra in (("defaults", []),
                        ("biased", ["--filter", "filter.odometry_bias.offset=[1.0, 0.0, 0.0]",
                                    "--filter", "filter.odometry_scale.learn=false"])):  # fmt: skip
        assert drive.main([*base, "--out", str(tmp_path / name), *extra]) == 0
        errors[name] = read_error_log(tmp_path / name / "error_log.csv").position_error
    capsys.readouterr()
    assert errors["defaults"].max() < 0.5
    assert errors["biased"].mean() > 3 * errors["defaults"].mean()
    for bad, says in (("nonsense", "KEY=VALUE"), ("filter.odometry_scale.initial=5", "initial"),
                      ("filter.no_such_setting=1", "no_such_setting"),
                      ("filter.n_particles=500", "--particles")):  # fmt: skip
        out = tmp_path / f"bad_{says}"
        with pytest.raises(SystemExit) as exited:
            drive.main([*base, "--out", str(out), "--filter", bad])
        err = capsys.readouterr().err
        assert exited.value.code == 2 and "--filter" in err and says in err
        assert "Traceback" not in err and len(err.strip().splitlines()) == 1 and not out.exists()
