"""The lap task against scripted opponents (no torch needed): overtakes and contacts counted on
scripted races, the agent starting last on the grid, the penalty on a car contact; and the
train-agent command end to end for the race and the single-track car when stable-baselines3 is
installed."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mcl.agents.evaluate import EpisodeResult, race_table
from mcl.agents.lap_env import LapTaskConfig, make_lap_env
from mcl.agents.race_tally import RaceTally
from mcl.agents.task_env import make_task_env
from racecar_sim.drivers import PurePursuit
from racecar_sim.race.grid import start_grid
from racecar_sim.race.single import RacecarRaceEnv
from tests.skips import NO_SB3, RL_MISSING

FAST = (("n_beams", 181),)
NEEDS_SB3 = pytest.mark.skipif(NO_SB3, reason=RL_MISSING)


def _parked(obs, pose) -> np.ndarray:
    return np.zeros(2)


def _line(race: RacecarRaceEnv, offset: float) -> np.ndarray:
    """The race's centerline moved ``offset`` metres to its left (negative: right)."""
    pts = race.track.points
    d = np.roll(pts, -1, axis=0) - np.roll(pts, 1, axis=0)
    normal = np.stack([-d[:, 1], d[:, 0]], axis=1) / np.linalg.norm(d, axis=1, keepdims=True)
    return pts + offset * normal


def _race(agent_line: float, opponent, steps: int, pole: str = "opponent"):
    """Car 0 follows the centerline shifted by ``agent_line`` m at 2 m/s (or stays parked when
    ``agent_line`` is None) against one opponent; ``pole``: who starts in front. Returns the
    tally and the last info."""
    race = RacecarRaceEnv(
        opponents=1, opponent_driver=[opponent], terminate_on_collision=False, n_beams=181
    )
    # the staggered grid's first two slots: pole on the left, second on the right
    grid = start_grid(race.track, 2, race.car_params, race.race.cars[0].physics.pose_is_free)
    obs, info = race.reset(seed=0, options={"poses": grid[::-1] if pole == "opponent" else grid})
    drive = (
        _parked
        if agent_line is None
        else PurePursuit(_line(race, agent_line), speed=2.0, loop=True, car=race.car_params)
    )
    tally = RaceTally()
    tally.begin(info)
    for _ in range(steps):
        obs, _, _, _, info = race.step(drive(obs, info["pose"]))
        tally.update(info)
    return tally, info


# ---------------------------------------------------------------------- the counts
def test_tally_counts_rank_changes_and_separate_contacts() -> None:
    tally = RaceTally()
    tally.begin({"rank": 3})
    steps = [
        (3, ()), (2, ("car_1",)), (2, ("car_1",)), (2, ()), (1, ("wall",)),
        (1, ("wall", "car_2")), (2, ("wall",)), (1, ()), (1, ("wall",)),
    ]  # fmt: skip
    for rank, contacts in steps:
        tally.update({"rank": rank, "contacts": contacts})
    c = tally.counts()
    assert (c["overtakes"], c["overtaken"]) == (3, 1)  # 3->2, 2->1, 2->1; 1->2
    assert (c["start_rank"], c["rank"]) == (3, 1)
    assert (c["wall_contacts"], c["wall_steps"]) == (2, 4)  # steps 5-7 are one contact, 9 another
    assert (c["car_contacts"], c["car_steps"]) == (2, 3)  # steps 2-3, and 6
    tally.begin({"rank": 2})
    assert tally.counts()["overtakes"] == 0 and tally.counts()["wall_steps"] == 0


@given(st.integers(1, 4), st.lists(st.integers(1, 4), max_size=60))
def test_overtakes_minus_overtaken_is_the_rank_gained(start, ranks) -> None:
    tally = RaceTally()
    tally.begin({"rank": start})
    for rank in ranks:
        tally.update({"rank": rank, "contacts": ()})
    final = ranks[-1] if ranks else start
    assert tally.overtakes - tally.overtaken == start - final
    assert tally.overtakes >= max(0, start - min([start, *ranks]))


# ---------------------------------------------------------------------- scripted races
def test_passing_a_parked_car_is_one_overtake_without_contact() -> None:
    tally, info = _race(-0.3, _parked, steps=120)  # 6 s at 2 m/s on the right of the line
    c = tally.counts()
    assert c["start_rank"] == 2 and c["rank"] == 1 and info["rank"] == 1
    assert (c["overtakes"], c["overtaken"]) == (1, 0)
    assert c["car_contacts"] == 0 and c["wall_contacts"] == 0
    assert info["progress"] > 4.0  # from a standing start


def test_driving_into_a_parked_car_is_a_car_contact() -> None:
    tally, _ = _race(0.25, _parked, steps=60)  # the parked car stands 0.25 m left of the line
    c = tally.counts()
    assert c["car_contacts"] >= 1 and c["car_steps"] >= 1
    assert c["wall_contacts"] == 0


def test_a_car_passing_the_parked_agent_is_counted_as_overtaken() -> None:
    race = RacecarRaceEnv(opponents=1, n_beams=181)  # only for the opponent's line
    passer = PurePursuit(_line(race, -0.3), speed=2.0, loop=True, car=race.car_params)
    tally, _ = _race(None, passer, steps=160, pole="agent")
    c = tally.counts()
    assert (c["start_rank"], c["rank"]) == (1, 2)
    assert (c["overtakes"], c["overtaken"]) == (0, 1)
    assert c["car_contacts"] == 0


# ---------------------------------------------------------------------- the race task
@pytest.mark.parametrize("opponents", [1, 3])
def test_race_task_starts_the_agent_last_and_counts_its_race(opponents) -> None:
    config = LapTaskConfig(pose_source="truth", opponents=opponents, start_s=0.0, env=FAST)
    env = make_task_env(config)
    obs, info = env.reset(seed=5)
    assert obs.shape == env.observation_space.shape == (57,)
    assert info["race"]["start_rank"] == opponents + 1 and info["race"]["opponents"] == opponents
    track = env.unwrapped.track
    s_agent, _ = track.project(info["pose"])
    s_opp = [track.project(p)[0] for p in info["opponent_poses"]]
    assert all(0 < (s - s_agent) % track.length < 5.0 for s in s_opp), "opponents just ahead"
    total = 0.0
    for _ in range(400):  # full speed straight ahead: into a wall or a car
        obs, reward, terminated, _, info = env.step(np.array([0.0, 1.0]))
        total += reward
        if terminated:
            break
    assert terminated, "full speed straight ahead hit nothing in 10 s"
    assert info["collision"] != ""
    assert reward < -4.0  # the step's progress minus the penalty of 5
    race = info["race"]
    assert race["wall_contacts"] + race["car_contacts"] == 1


def test_race_task_random_starts_keep_the_agent_behind_in_race_order() -> None:
    config = LapTaskConfig(pose_source="truth", opponents=3, env=FAST)
    env = make_task_env(config)
    starts = set()
    _, info = env.reset(seed=0)
    for _ in range(60):  # the track narrows in places: a grid there is drawn again
        assert info["race"]["start_rank"] == 4, "the grid straddles the wrap"
        starts.add(round(float(info["pose"][0]), 1))
        _, info = env.reset()
    assert len(starts) >= 30, "the training starts are not spread over the track"


def test_race_table_totals_the_counts() -> None:
    common = dict(policy="p", tested_on="truth, 1 opponent", seconds=60.0, progress_per_min=1.0,
                  collision_steps=0, contacts=0, mean_error=float("nan"), max_error=float("nan"),
                  opponents=1, start_rank=2)  # fmt: skip
    rows = [
        EpisodeResult(seed=0, laps=2, lap_times=(20.0, 18.0), wall_contacts=1, car_contacts=0,
                      overtakes=2, overtaken=1, final_rank=1, **common),
        EpisodeResult(seed=1, laps=1, lap_times=(22.0,), wall_contacts=0, car_contacts=3,
                      overtakes=0, overtaken=0, final_rank=2, **common),
    ]  # fmt: skip
    line = race_table(rows).splitlines()[2]
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert cells == ["p", "truth, 1 opponent", "2", "3", "21.00", "18.00", "1", "3", "2", "1",
                     "2", "1.5", "1.0"]  # fmt: skip


def test_race_task_config_refuses_what_it_cannot_run() -> None:
    with pytest.raises(ValueError, match="runs no MCL"):
        LapTaskConfig(pose_source="estimate", opponents=1)
    with pytest.raises(ValueError, match="opponent_speeds"):
        LapTaskConfig(pose_source="truth", opponents=2, opponent_speeds=(2.0,))
    with pytest.raises(ValueError, match="opponent_driver"):
        LapTaskConfig(pose_source="truth", opponents=1, opponent_driver="rally")
    with pytest.raises(ValueError, match="make_task_env"):
        make_lap_env(LapTaskConfig(pose_source="truth", opponents=1))


# ---------------------------------------------------------------------- the command
@pytest.mark.parametrize(
    ("flags", "named"),
    [
        (["--opponents", "0"], "--opponents"),
        (["--opponents", "1", "--pose", "estimate"], "--pose"),
        (["--env", "car_model=rally"], "--env car_model"),
        (["--opponents", "3", "--opponent-speeds", "2,3"], "--opponent-speeds"),
        (["--eval-car-models", "bicycle"], "--eval-car-models"),
    ],
)
def test_train_agent_names_the_bad_flag(flags, named, capsys, tmp_path) -> None:
    from mcl.cli.train_agent import main

    with pytest.raises(SystemExit) as exc:
        main([*flags, "--out", str(tmp_path / "out")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert named in err and "Traceback" not in err


@pytest.mark.slow
@NEEDS_SB3
def test_train_agent_races_on_the_single_track_car_end_to_end(tmp_path) -> None:
    from mcl.cli.train_agent import main

    code = main(
        [
            "--pose", "truth", "--timesteps", "64", "--envs", "2", "--opponents", "1,2",
            "--env", "car_model=single_track", "--env", "n_beams=181",
            "--eval-car-models", "single_track,kinematic", "--eval-opponents", "1",
            "--eval-poses", "truth", "--eval-seeds", "1", "--eval-seconds", "2", "--video-seconds", "0",
            "--out", str(tmp_path),
        ]
    )  # fmt: skip
    assert code == 0
    config = (tmp_path / "truth" / "config.json").read_text()
    assert '"opponents": 2' in config and '"single_track"' in config
    with (tmp_path / "eval.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [r["tested_on"] for r in rows] == [
        "truth, single_track, 1 opponent",
        "truth, 1 opponent",
    ]
    assert {r["policy"] for r in rows} == {"true pose, single_track, vs 1,2 opponents"}
    assert all(r["opponents"] == "1" and r["start_rank"] == "2" for r in rows)
    assert "overtakes" in (tmp_path / "eval.md").read_text()


@pytest.mark.slow
@NEEDS_SB3
def test_train_stops_at_max_minutes(tmp_path) -> None:
    import json

    from mcl.agents.ppo import PPOSettings, train

    task = LapTaskConfig(pose_source="truth", env=FAST)
    settings = PPOSettings(n_envs=2, n_steps=64, batch_size=64, n_epochs=1)
    report = train(task, 10**7, tmp_path, settings=settings, max_minutes=0.002)  # 0.12 s
    assert 0 < report.timesteps < 10**7
    assert json.loads((tmp_path / "train.json").read_text())["stopped_by_max_minutes"] is True
    assert (tmp_path / "model.zip").is_file()
