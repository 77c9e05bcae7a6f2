"""The nav2 amcl peer: nav2_amcl's C++ core localizing our recorded drives, in its own venv.

PyPI's ``amcl`` (github.com/damanikjosh/amcl_python, GPL-3) wraps nav2_amcl's particle filter
(KLD-sampling, the alpha_slow / alpha_fast recovery, the differential odometry model) and its
*beam* laser model, the only one the bindings build. Being GPL, it is never a dependency of this
project and never imported by it: it lives in a venv of its own (``$AMCL_PYTHON``, else
``out/peers/amcl-venv``, made on first use by
[amcl_python][mcl.bench.peer_amcl.amcl_python]) and runs as a subprocess,
[AmclPeer][mcl.bench.peer_amcl.AmclPeer], that reads our drives converted to its frames by
[mcl.bench.amcl_inputs][] (.npz files) and writes its estimates back. `PEER_SCRIPT` only
calls the bindings' public API.

Parameters: [AmclParams][mcl.bench.peer_amcl.AmclParams] defaults are nav2's
(https://docs.nav2.org/configuration/packages/configuring-amcl.html, and
``nav2_amcl/src/amcl_node.cpp``'s declared parameters), except ``laser_model_type``: nav2's default
is ``likelihood_field``, the bindings have only ``beam``. What the bindings fix and nav2 would
set: the KLD bounds (``pf_err`` 0.01 and ``pf_z`` 3, pf.c's own, where nav2 sets 0.05 and 0.99) and
``resample_interval`` 1 (nav2's default too); the estimate is the weighted mean of all particles
(nav2 publishes the mean of the heaviest cluster: the same while tracking one pose).

Repeatability: every run goes through a process of its own, forked from the subprocess after it
loaded amcl and the map and before any filter existed, so no run sees another's state. The
state that leaked before: pf_pdf.c reseeds drand48 with a process-wide counter at every initial
pose (``srand48(++pf_pdf_seed)``), so the k-th run of a process drew from the stream of seed k,
whatever seed it was given (cluttered seed 1 of the 20-seed bench: 0.786 m alone, 0.674 m after
seed 0). Now the initial particles come from that stream of seed 1 (as in a freshly started
nav2), then drand48 is seeded from the run's seed for everything after (motion noise,
resampling). The recovery's random poses come from ``std::random_device`` and are not
repeatable: an ``amcl_recovery`` run repeats only while the recovery injects no pose.
"""

from __future__ import annotations

import json
import os
import subprocess
import tempfile
import venv
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from mcl.bench.amcl_inputs import (
    AmclGrid,
    amcl_ranges,
    estimates_between,
    odometry_poses,
    update_steps,
)
from mcl.bench.peer_process import PeerProcess
from mcl.experiments.recorded import LocalizedRun, RecordedDrive, localized_run
from mcl.wrappers.localization import TRACKING_INIT_SPREAD

__all__ = [
    "AMCL_PACKAGE",
    "NAV2_DEFAULTS",
    "PEER_SCRIPT",
    "WITH_RECOVERY",
    "AmclParams",
    "AmclPeer",
    "amcl_python",
    "localize_with_amcl",
]

AMCL_PACKAGE = "amcl==0.1.2"
"""The bindings' release the venv gets (the one this peer was written against)."""
DEFAULT_VENV = Path("out/peers/amcl-venv")
"""Where the venv is made when ``$AMCL_PYTHON`` is not set (relative to the working folder)."""


@dataclass(frozen=True)
class AmclParams:
    """nav2 amcl's parameters that the bindings take (nav2's names; defaults nav2's, see the
    module docstring).

    Attributes:
        min_particles: fewest particles KLD-sampling keeps.
        max_particles: most particles.
        alpha1: rotation noise from rotation (differential model).
        alpha2: rotation noise from translation.
        alpha3: translation noise from translation.
        alpha4: translation noise from rotation.
        alpha5: translation noise of the omni model (unused by the differential one).
        z_hit: beam model: weight of the Gaussian hit.
        z_short: weight of short readings.
        z_max: weight of max-range readings.
        z_rand: weight of random readings.
        sigma_hit: metres, standard deviation of the hit.
        lambda_short: 1/metres, decay of short readings.
        max_beams: beams of a scan used (evenly strided).
        update_min_d: metres of odometry (along the odom frame's x or y) before an update; a
            negative value updates on every fresh scan.
        update_min_a: radians of odometry heading before an update.
        recovery_alpha_slow: decay of the slow average weight (0: recovery off).
        recovery_alpha_fast: decay of the fast average weight (0: recovery off).
        laser_model_type: ``"beam"``, the one model the bindings have.
    """

    min_particles: int = 500
    max_particles: int = 2000
    alpha1: float = 0.2
    alpha2: float = 0.2
    alpha3: float = 0.2
    alpha4: float = 0.2
    alpha5: float = 0.2
    z_hit: float = 0.5
    z_short: float = 0.05
    z_max: float = 0.05
    z_rand: float = 0.5
    sigma_hit: float = 0.2
    lambda_short: float = 0.1
    max_beams: int = 60
    update_min_d: float = 0.25
    update_min_a: float = 0.2
    recovery_alpha_slow: float = 0.0
    recovery_alpha_fast: float = 0.0
    laser_model_type: str = "beam"

    def __post_init__(self) -> None:
        if not (1 <= self.min_particles <= self.max_particles):
            raise ValueError(
                f"AmclParams: need 1 <= min_particles ({self.min_particles}) <= max_particles "
                f"({self.max_particles})"
            )
        if self.max_beams < 2:
            raise ValueError(f"AmclParams.max_beams = {self.max_beams}: at least 2")
        for name in ("alpha1", "alpha2", "alpha3", "alpha4", "alpha5", "z_hit", "z_short",
                     "z_max", "z_rand", "lambda_short", "recovery_alpha_slow",
                     "recovery_alpha_fast"):  # fmt: skip
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"AmclParams.{name} = {value!r} must be a non-negative number")
        if not (np.isfinite(self.sigma_hit) and self.sigma_hit > 0):
            raise ValueError(f"AmclParams.sigma_hit = {self.sigma_hit!r} must be positive")
        if not (np.isfinite(self.update_min_d) and np.isfinite(self.update_min_a)):
            raise ValueError("AmclParams.update_min_d and update_min_a must be finite")
        if self.laser_model_type != "beam":
            raise ValueError(
                f"AmclParams.laser_model_type = {self.laser_model_type!r}: the amcl bindings "
                "build only nav2's beam model ('beam')"
            )


NAV2_DEFAULTS = AmclParams()
"""nav2's defaults (recovery off), with the beam model."""
WITH_RECOVERY = replace(NAV2_DEFAULTS, recovery_alpha_slow=0.001, recovery_alpha_fast=0.1)
"""nav2's defaults with the recovery on at the values nav2's docs suggest (0.001, 0.1)."""


def amcl_python(given: str | os.PathLike[str] | None = None,
                venv_dir: Path = DEFAULT_VENV) -> tuple[str | None, str]:  # fmt: skip
    """The Python of a venv with the amcl bindings: ``given``, else ``$AMCL_PYTHON``, else the
    one in ``venv_dir``, made there (with a message) when it is missing.

    Returns:
        (python, "") or (None, why not), the reason one line for a skip message.
    """
    given = given or os.environ.get("AMCL_PYTHON")
    if given:
        return (str(given), "") if _has_amcl(str(given)) else (
            None, f"{given} cannot import amcl (from --amcl-python or $AMCL_PYTHON)"
        )  # fmt: skip
    python = venv_dir / "bin" / "python"
    if python.exists() and _has_amcl(str(python)):
        return str(python), ""
    print(f"amcl peer: making its venv {venv_dir} (pip install {AMCL_PACKAGE} numpy; GPL-3, "
          "kept out of this project's environment) ...", flush=True)  # fmt: skip
    try:
        venv.create(venv_dir, with_pip=True, clear=python.exists())
        done = subprocess.run(
            [str(python), "-m", "pip", "install", "-q", AMCL_PACKAGE, "numpy"],
            capture_output=True, text=True, timeout=900,
        )  # fmt: skip
    except (OSError, subprocess.SubprocessError) as exc:
        return None, f"could not make the amcl venv {venv_dir}: {exc}"
    if done.returncode != 0 or not _has_amcl(str(python)):
        tail = (done.stderr or done.stdout).strip().splitlines()[-1:] or ["no output"]
        return None, f"could not install {AMCL_PACKAGE} into {venv_dir}: {tail[0]}"
    return str(python), ""


def _has_amcl(python: str) -> bool:
    try:
        return subprocess.run([python, "-c", "import amcl, numpy"], capture_output=True,
                              timeout=120).returncode == 0  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return False


PEER_SCRIPT = r"""
import ctypes, json, multiprocessing, os, sys, time
import numpy as np
import amcl

libc = ctypes.CDLL(None)
grids = {}


def localize(req):
    p = req["params"]
    d = np.load(req["input"])
    loc = amcl.AMCL(p["min_particles"], p["max_particles"], p["recovery_alpha_slow"],
                    p["recovery_alpha_fast"],
                    amcl.MotionParameters(p["alpha1"], p["alpha2"], p["alpha3"], p["alpha4"],
                                          p["alpha5"]),
                    amcl.LaserParameters(p["z_hit"], p["z_short"], p["z_max"], p["z_rand"],
                                         p["sigma_hit"], p["lambda_short"], 0.0, p["max_beams"]),
                    "differential")
    loc.set_map(grids[req["grid"]])
    loc.set_laser_pose(amcl.Vector3D(float(d["mount_offset"]), 0.0, 0.0))
    var = d["init_var"]
    # pf_init reseeds drand48 with pf_pdf.c's process-wide counter (1 in this fresh process)
    loc.set_initial_pose(amcl.Vector3D(*[float(v) for v in d["init_pose"]]),
                         amcl.create_diagonal_covariance(*[float(v) for v in var]))
    seed = int(req["seed"])  # then the run's seed; low word 0x5EED: never a srand48(k) state
    libc.seed48((ctypes.c_ushort * 3)(0x5EED, seed & 0xFFFF, (seed >> 16) & 0xFFFF))
    ranges, odom, range_max = d["ranges"], d["odom"], float(d["range_max"])
    out = np.empty((len(odom), 3))
    t0 = time.process_time()
    for u in range(len(odom)):
        scan = amcl.create_laser_scan_from_list(ranges[u].tolist(), range_max)
        loc.update(scan, amcl.Vector3D(*[float(v) for v in odom[u]]))
        pose = loc.get_pose_mean()
        out[u] = (pose.x, pose.y, pose.theta)
    cpu = time.process_time() - t0
    np.save(req["output"], out)
    return {"done": req["output"], "cpu_s": cpu}


def run_and_send(req, send):
    try:
        msg = localize(req)
    except BaseException as exc:
        msg = {"done": None, "error": f"{type(exc).__name__}: {exc}"}
    send.send(msg)


def in_own_process(req):  # a forked child runs the filter: no state of one run reaches the next
    context = multiprocessing.get_context("fork")
    receive, send = context.Pipe(duplex=False)
    child = context.Process(target=run_and_send, args=(req, send))
    child.start()
    send.close()
    try:
        msg = receive.recv()
    except EOFError:  # the child died before it answered
        msg = None
    child.join()
    return msg or {"done": None, "error": f"the run's process ended with status {child.exitcode}"}


print(json.dumps({"ready": True}), flush=True)
for line in sys.stdin:
    req = json.loads(line)
    if req.get("op") == "quit":
        break
    try:
        if req["grid"] not in grids:
            g = np.load(req["grid"])
            data = g["data"]
            grid = amcl.OccupancyGrid(int(data.shape[1]), int(data.shape[0]),
                                      float(g["resolution"]), float(g["origin_x"]),
                                      float(g["origin_y"]))
            grid.data = data.ravel().tolist()
            grids[req["grid"]] = grid
        msg = in_own_process(req)
    except Exception as exc:  # one failed run is reported, the peer keeps serving
        msg = {"done": None, "error": f"{type(exc).__name__}: {exc}"}
    print(json.dumps(msg), flush=True)
"""
"""The subprocess: per request (JSON line: ``grid``, ``input``, ``output`` .npz/.npy paths,
``params``, ``seed``) one amcl filter through the drive's update steps, in a process forked for
that run alone; answers ``{"done": path, "cpu_s": s}`` or ``{"done": None, "error": ...}``."""


class AmclPeer(PeerProcess):
    """One amcl subprocess with ``params``, each run in a process forked for it alone (a run's
    result does not depend on the runs before it); runs are queued
    ([submit][mcl.bench.peer_amcl.AmclPeer.submit]) and collected in order
    ([collect][mcl.bench.peer_amcl.AmclPeer.collect]), so the caller can run our filter
    meanwhile.

    Args:
        python: the amcl venv's Python ([amcl_python][mcl.bench.peer_amcl.amcl_python]).
        grid: the filter's map converted ([amcl_grid][mcl.bench.amcl_inputs.amcl_grid]).
        params: amcl's parameters.
        work: a folder for the exchanged files (a temporary one when None).
    """

    def __init__(self, python: str, grid: AmclGrid, params: AmclParams = NAV2_DEFAULTS,
                 work: str | os.PathLike[str] | None = None) -> None:  # fmt: skip
        self.params = params
        self._tmp = tempfile.TemporaryDirectory(prefix="amcl-peer-") if work is None else None
        self.work = Path(self._tmp.name if self._tmp else work)
        self.work.mkdir(parents=True, exist_ok=True)
        self._ours: set[Path] = set()  # the files this peer named fresh: the only ones it removes
        self._grid_path = self._claim(self.work / f"grid_{os.getpid()}_{id(self)}.npz")
        origin_x, origin_y = grid.amcl_origin
        np.savez(self._grid_path, data=grid.data, resolution=grid.resolution,
                 origin_x=origin_x, origin_y=origin_y)  # fmt: skip
        self.proc = subprocess.Popen(
            [python, "-c", PEER_SCRIPT], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True, bufsize=1,
        )  # fmt: skip
        self.answer("ready")
        self._pending: list[tuple[RecordedDrive, np.ndarray, np.ndarray, Path]] = []
        self._count = 0

    def submit(self, drive: RecordedDrive, seed: int,
               init_spread: tuple[float, float, float] = TRACKING_INIT_SPREAD) -> None:  # fmt: skip
        """Queue ``drive`` for amcl, started on the reset's true pose with standard deviations
        ``init_spread`` (x m, y m, theta rad) and seeded with ``seed``."""
        poses = odometry_poses(drive.odom, drive.dt_steps)
        at = update_steps(poses, drive.fresh, self.params.update_min_d, self.params.update_min_a)
        ranges = amcl_ranges(drive.scans[drive.scan_rows[at]], drive.beam_angles, drive.max_range)
        self._count += 1
        stem = self.work / f"run_{os.getpid()}_{id(self)}_{self._count}"
        for made in (f"{stem}_in.npz", f"{stem}_out.npy"):  # ours to write, later to remove
            self._claim(Path(made))
        np.savez(f"{stem}_in.npz", ranges=ranges, odom=poses[at], range_max=drive.max_range,
                 mount_offset=drive.mount_offset, init_pose=drive.truth[0],
                 init_var=np.square(np.asarray(init_spread, dtype=np.float64)))  # fmt: skip
        request = {
            "grid": str(self._grid_path),
            "input": f"{stem}_in.npz",
            "output": f"{stem}_out.npy",
            "params": asdict(self.params),
            "seed": int(seed),
        }
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps(request) + "\n")
        self.proc.stdin.flush()
        self._pending.append((drive, poses, at, stem))

    def collect(self) -> tuple[LocalizedRun, float]:
        """The oldest queued run's estimates at every step and amcl's CPU seconds.

        Raises:
            RuntimeError: amcl failed on the run (its error) or the subprocess ended.
        """
        drive, poses, at, stem = self._pending.pop(0)
        msg = self.answer("done")
        self._remove(Path(f"{stem}_in.npz"))
        if msg["done"] is None:
            raise RuntimeError(f"amcl failed: {msg.get('error')}")
        output = Path(f"{stem}_out.npy")  # the file this run asked for, and only that one
        if Path(msg["done"]) != output:
            raise RuntimeError(
                f"amcl answered with {msg['done']!r}, not the file asked for ({output})"
            )
        updates = np.load(output)
        self._remove(output)
        return localized_run(estimates_between(updates, at, poses), drive.truth), float(
            msg["cpu_s"]
        )

    def _claim(self, path: Path) -> Path:
        """``path``, a name this peer will write and later remove: refused if something is
        already there (the peer removes only files it made)."""
        if os.path.lexists(path):
            raise FileExistsError(
                f"amcl peer: {path} exists; it writes and removes only its own files"
            )
        self._ours.add(path)
        return path

    def _remove(self, path: Path) -> None:
        """Remove ``path`` if this peer claimed it (and it is a file, not a link or folder put
        there since); anything else stays."""
        if path not in self._ours:
            return
        self._ours.discard(path)
        if path.is_file() and not path.is_symlink():
            path.unlink()

    def close(self) -> None:
        """Stop the subprocess and remove its files."""
        super().close()
        self._remove(self._grid_path)
        if self._tmp is not None:
            self._tmp.cleanup()


def localize_with_amcl(python: str, grid: AmclGrid, drive: RecordedDrive, seed: int,
                       params: AmclParams = NAV2_DEFAULTS) -> LocalizedRun:  # fmt: skip
    """One drive through a fresh amcl subprocess (tests and one-off runs)."""
    peer = AmclPeer(python, grid, params)
    try:
        peer.submit(drive, seed)
        return peer.collect()[0]
    finally:
        peer.close()


