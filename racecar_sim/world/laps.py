"""Progress, laps, lap times and race order of the cars on a [`Track`][racecar_sim.world.track.Track].

Each car carries ``u``: metres along the centerline from the start line, unwrapped (it keeps
growing lap after lap, and is negative behind the line). A step adds the short-way arc length
between the car's old and new nearest centerline points, so driving backwards takes ``u`` back.
A lap is completed when ``u`` first reaches ``L, 2 L, ...`` (``L`` the track's length): only
crossing the start line forwards, beyond everything the car had covered before, counts, so
driving backwards over the line and forwards again is not a lap. The crossing time is
interpolated within the step; the first lap is timed from the race start (time 0: a standing
start from the grid behind the line). A car placed ahead of the line starts with ``u`` in
``[0, L/2)``, behind it in ``[-L/2, 0)``.

Race order (``rank``, 1 = leading) is by ``u``, ties by car index.
"""

from __future__ import annotations

import numpy as np

from racecar_sim.world.track import Track

__all__ = ["LapCounter"]


class LapCounter:
    """The laps of ``n`` cars on ``track`` (see the module doc)."""

    def __init__(self, track: Track, n: int) -> None:
        self.track = track
        self.n = n
        self.u = np.zeros(n)
        """(N,) metres along the centerline from the start line, unwrapped."""
        self.start_u = np.zeros(n)
        self.best = np.zeros(n)
        self.laps = np.zeros(n, dtype=np.int64)
        self.lap_times: list[list[float]] = [[] for _ in range(n)]
        self._last_cross = np.zeros(n)
        self._s = np.zeros(n)
        self._hint = np.full(n, -1, dtype=np.int64)

    def reset(self, xy: np.ndarray) -> None:
        """Start the race with the cars at world ``xy`` (N, 2) (their rear axles), time 0."""
        length = self.track.length
        self._s, self._hint = self.track.arc_lengths(xy)
        self.u = np.where(self._s >= length / 2, self._s - length, self._s)
        self.start_u = self.u.copy()
        self.best = self.u.copy()
        self.laps[:] = 0
        self.lap_times = [[] for _ in range(self.n)]
        self._last_cross[:] = 0.0

    def update(
        self, xy: np.ndarray, time: float, dt: float, cars: np.ndarray | None = None
    ) -> None:
        """The cars ``cars`` (indices; default all) moved to world ``xy`` (their rows of an (N, 2)
        array) during the step ending at ``time`` seconds, ``dt`` long."""
        idx = np.arange(self.n) if cars is None else np.asarray(cars, dtype=np.int64)
        if len(idx) == 0:
            return
        length = self.track.length
        s, hint = self.track.arc_lengths(xy[idx], self._hint[idx])
        du = np.mod(s - self._s[idx] + length / 2, length) - length / 2
        old_u = self.u[idx]
        new_u = old_u + du
        self._s[idx], self._hint[idx] = s, hint
        self.u[idx] = new_u
        old_laps = np.floor(self.best[idx] / length)
        self.best[idx] = np.maximum(self.best[idx], new_u)
        gained = np.floor(self.best[idx] / length) - old_laps
        for j in np.flatnonzero(gained > 0).tolist():  # a lap completed: rare, a few cars a step
            i = int(idx[j])
            for k in range(int(old_laps[j]) + 1, int(old_laps[j] + gained[j]) + 1):
                if k < 1:
                    continue
                frac = (
                    (k * length - old_u[j]) / (new_u[j] - old_u[j]) if new_u[j] != old_u[j] else 1.0
                )
                t_cross = float(time - dt + dt * min(max(frac, 0.0), 1.0))
                self.lap_times[i].append(t_cross - float(self._last_cross[i]))  # plain floats
                self._last_cross[i] = t_cross
                self.laps[i] = k

    def ranks(self) -> np.ndarray:
        """(N,) race position of each car, 1 = leading (by ``u``, ties by index)."""
        order = np.lexsort((np.arange(self.n), -self.u))
        rank = np.empty(self.n, dtype=np.int64)
        rank[order] = np.arange(1, self.n + 1)
        return rank

    def info(self, ranks: np.ndarray, i: int) -> dict[str, object]:
        """Car ``i``'s ``progress`` (m since its start), ``lap``, ``lap_times`` (s) and ``rank``."""
        return {
            "progress": float(self.u[i] - self.start_u[i]),
            "lap": int(self.laps[i]),
            "lap_times": list(self.lap_times[i]),
            "rank": int(ranks[i]),
        }
