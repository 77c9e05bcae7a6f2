"""The race video's frames: the race's own ``render()`` with each car's name beside it and, when
localized, each car's MCL estimate (an arrow) and particles (dots) in its colour, and a panel on
the right with the race clock, the lap counter, the standings and a legend.

The overlay is drawn with a [`racecar_sim.render.MapRenderer`][racecar_sim.render.MapRenderer] of
the race's map at the default scale, the geometry ``RaceEnv.render()`` draws with, so labels sit on
the cars.
"""

from __future__ import annotations

import numpy as np

from mcl.experiments.frame_text import draw_legend, put_label
from mcl.experiments.race_run import RaceSpec, RaceState
from racecar_sim.maps import OccupancyMap
from racecar_sim.race.drawing import CAR_COLOURS
from racecar_sim.render import MapRenderer

__all__ = ["PANEL_WIDTH", "RaceFrames"]

PANEL_WIDTH = 330
"""Pixels of the panel beside the map."""
_ROW = 22  # pixels per line of the panel


def _colour(i: int) -> tuple[int, int, int]:
    return CAR_COLOURS[i % len(CAR_COLOURS)]


class RaceFrames:
    """Call with a race frame and its [`RaceState`][mcl.experiments.race_run.RaceState]: the
    labelled frame (the map, then the panel; see the module doc).

    Args:
        occupancy_map: the race's map.
        spec: the race (drivers, speeds, laps, whether it is localized).
    """

    def __init__(self, occupancy_map: OccupancyMap, spec: RaceSpec) -> None:
        self.renderer = MapRenderer(occupancy_map)
        self.spec = spec

    def __call__(self, frame: np.ndarray, state: RaceState) -> np.ndarray:
        img = np.ascontiguousarray(frame)
        renderer = self.renderer
        for agent, particles in state.particles.items():
            renderer.draw_particles(img, particles, _colour(int(agent[4:])))
        for estimate in state.estimates.values():
            renderer.draw_pose(img, estimate, (0, 0, 0))
        for agent, info in state.infos.items():
            u, v = renderer.world_to_pixel(np.asarray(info["pose"][:2]))
            put_label(img, agent[4:], (u + 9, v - 7), _colour(int(agent[4:])), 0.55, thickness=2)
        panel = self._panel(img.shape[0], state)
        height = max(img.shape[0], panel.shape[0])
        if img.shape[0] < height:
            pad = np.full((height - img.shape[0], img.shape[1], 3), 255, dtype=np.uint8)
            img = np.vstack([img, pad])
        return np.hstack([img, panel])

    def _panel(self, height: int, state: RaceState) -> np.ndarray:
        spec = self.spec
        cars = sorted(state.infos.items(), key=lambda item: item[1]["rank"])
        lines = 4 + len(cars) + 6
        panel = np.full((max(height, lines * _ROW + 20), PANEL_WIDTH, 3), 255, dtype=np.uint8)
        leader_laps = max(int(info["lap"]) for _, info in cars)
        target = f" of {spec.laps}" if spec.laps is not None else ""
        y = 28
        put_label(panel, f"race clock {state.time:6.2f} s", (12, y), scale=0.65, thickness=2)
        y += _ROW + 6
        put_label(panel, f"laps done (leader): {leader_laps}{target}", (12, y), scale=0.55)
        y += _ROW + 8
        put_label(panel, "pos car driver, speed", (12, y), (90, 90, 90), 0.45)
        put_label(panel, "laps", (PANEL_WIDTH - 42, y), (90, 90, 90), 0.45)
        for agent, info in cars:
            y += _ROW
            i = int(agent[4:])
            colour = _colour(i)
            panel[y - 12 : y + 2, 12:26] = colour
            text = f"{info['rank']}  {i}  {spec.drivers[i].name[:12]:<12s} {spec.speeds[i]:.1f} m/s"
            put_label(panel, text, (32, y), scale=0.45, outline=None)
            put_label(panel, str(info["lap"]), (PANEL_WIDTH - 30, y), scale=0.5, outline=None)
        legend = [
            ("car (true pose), its number", (90, 90, 90), "box"),
            ("its lidar hits", (170, 170, 170), "dots"),
            ("track centerline", (200, 200, 200), "line"),
        ]
        if spec.localize:
            legend += [
                ("MCL estimate", (0, 0, 0), "arrow"),
                ("its particles (car's colour)", (90, 90, 90), "dots"),
            ]
        draw_legend(panel, legend, "bottom-left")
        return panel
