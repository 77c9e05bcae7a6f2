"""Train PPO to drive laps on the default map from the scan and a pose, then test it on MCL's
estimate (needs the extra [rl]: pip install torch==2.13.0 -e '.[rl]').

For each pose source in --pose (truth: the simulator's pose; estimate: obs["pose_estimate"] of MCL
in the loop) it trains a policy into OUT/<source>/ (skipped when OUT/<source>/model.zip exists and
--retrain is not given), then tests every policy on the true pose, with no pose (the pose features
held constant: how much the policy needs the pose) and on MCL's estimate (with each filter of
--eval-filters; fewer particles and beams, larger errors) and writes OUT/eval.csv,
OUT/eval.md, OUT/learning_curve.png and OUT/agent.mp4 (the last policy on the estimate).

--env NAME=VALUE sets the simulator for training and tests (e.g. --env car_model=single_track);
--eval-car-models tests every policy on each car model listed (e.g. kinematic,single_track).
--opponents K[,K...] trains against K scripted opponents (RacecarRace-v0, the agent starting last
on the grid; a list is spread over the envs: 1,2,3 gives env i the count i % 3); the policies are
then tested against each count of --eval-opponents, and OUT/eval.md adds a race table: laps, wall
and car contacts, overtakes (rank gains) and times overtaken. Races run no MCL: the estimate's
tests are skipped there.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mcl.agents.lap_env import POSE_SOURCES, LapTaskConfig
from mcl.cli.common import (
    ENV_HELP,
    Parser,
    check_env,
    check_out,
    duration_or_zero,
    duration_seconds,
    number_list,
    output_folder,
    path_arg,
    positive_float,
    positive_int,
)
from racecar_sim.car.models import CAR_MODELS
from racecar_sim.race.single import DRIVERS

EXAMPLES = """\
examples (the first is the README's run, about 12 + 25 minutes of training on 2 busy cores):
  racecar-sim train-agent --timesteps 150000 --eval-filters 300,10,5x2 --out runs/agent
  racecar-sim train-agent --pose truth --env car_model=single_track \\
      --eval-car-models kinematic,single_track --eval-poses truth --out runs/agent_st
  racecar-sim train-agent --pose truth --opponents 1,2,3 --eval-opponents 1,3 \\
      --eval-poses truth --out runs/agent_race
"""


_NAMES = {"truth": "true pose", "estimate": "MCL estimate", "none": "no pose (scan only)"}
"""Pose source -> the policy's name in the tables."""


def _choices(choices: tuple[str, ...]):
    """argparse type: comma-separated names out of ``choices`` (at least one)."""

    def parse(text: str) -> tuple[str, ...]:
        names = tuple(v.strip() for v in text.split(",") if v.strip())
        bad = [n for n in names if n not in choices]
        if bad or not names:
            raise argparse.ArgumentTypeError(
                f"takes {' and/or '.join(choices)}, comma-separated; got {text!r}"
            )
        return names

    return parse


_sources = _choices(POSE_SOURCES)


def _counts(text: str) -> tuple[int, ...]:
    """argparse type: comma-separated whole numbers >= 1 (opponents)."""
    try:
        counts = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        counts = ()
    if not counts or min(counts) < 1:
        raise argparse.ArgumentTypeError(
            f"expected whole numbers >= 1, comma-separated (e.g. 1,2,3); got {text!r}"
        )
    return counts


def _filters(text: str) -> tuple[tuple[int, int], ...]:
    """``N`` or ``NxB`` items (particles, beams per particle), comma-separated."""
    out = []
    for item in (v.strip() for v in text.split(",")):
        if not item:
            continue
        n, _, beams = item.partition("x")
        try:
            pair = (int(n), int(beams) if beams else LapTaskConfig.filter_beams)
        except ValueError:
            pair = (0, 0)
        if min(pair) < 1:
            raise argparse.ArgumentTypeError(
                f"expected PARTICLES or PARTICLESxBEAMS items, comma-separated; got {text!r}"
            )
        out.append(pair)
    if not out:
        raise argparse.ArgumentTypeError("expected at least one filter, e.g. 300 or 5x2")
    return tuple(out)


def main(argv: list[str] | None = None) -> int:
    """Run ``racecar-sim train-agent``; returns the exit code (2: a user mistake)."""
    parser = Parser("racecar-sim train-agent", __doc__, EXAMPLES)
    add = parser.add_argument
    add("--timesteps", type=positive_int, default=150_000, help="env steps per policy")
    add(
        "--pose",
        type=_sources,
        default=POSE_SOURCES[:2],
        help="pose sources to train on: truth, estimate, none (scan only)",
    )
    add("--envs", type=positive_int, default=8, help="envs stepped together")
    add(
        "--max-minutes",
        type=positive_float,
        default=None,
        metavar="MIN",
        help="stop each training after MIN wall minutes even short of --timesteps "
        "(OUT/<source>/train.json says so)",
    )
    add("--seed", type=int, default=0, help="training seed")
    add("--retrain", action="store_true", help="train even if OUT/<source>/model.zip exists")
    add("--no-eval", action="store_true", help="train only")
    add("--eval-seeds", type=positive_int, default=5, help="test episodes per policy and test")
    add("--eval-seconds", type=duration_seconds, default=60.0,
        help="simulated seconds per test episode")  # fmt: skip
    add(
        "--eval-filters",
        type=_filters,
        default=((300, 60),),
        metavar="N[xB],...",
        help="filters of the tests on the estimate: particles, optionally x beams per particle "
        "(fewer, larger errors), e.g. 300,30,5x2",
    )
    add(
        "--eval-poses",
        type=_sources,
        default=("truth", "none", "estimate"),
        help="poses of the tests: truth, none (features held), estimate (each --eval-filters)",
    )
    add("--env", action="append", default=[], metavar="NAME=VALUE", help=ENV_HELP)
    add(
        "--eval-car-models",
        type=_choices(CAR_MODELS),
        default=None,
        metavar="MODEL,...",
        help=f"test every policy on each of these car models ({', '.join(CAR_MODELS)}; "
        "default: the --env car_model)",
    )
    add(
        "--opponents",
        type=_counts,
        default=(),
        metavar="K[,K...]",
        help="train against K scripted opponents; a list is spread over the envs (default: none)",
    )
    add(
        "--eval-opponents",
        type=_counts,
        default=None,
        metavar="K[,K...]",
        help="test against each count (default: the --opponents counts)",
    )
    add(
        "--opponent-driver",
        choices=DRIVERS,
        default="racing",
        help="the opponents' driver (racing: knows the other cars; pure_pursuit: blind to them)",
    )
    add(
        "--opponent-speeds",
        type=number_list,
        default=None,
        metavar="V,...",
        help="m/s of opponents 1, 2, ...: a race of K takes the first K (default 2.0, 2.4, 2.8, ...)",
    )
    add("--video-seconds", type=duration_or_zero, default=20.0, help="0: no video")
    add("--out", type=path_arg, default=Path("runs/agent"), metavar="DIR",
        help="output folder: a new or empty one, or one racecar-sim made")  # fmt: skip
    args = parser.parse_args(argv)
    args.env = check_env(parser, args.env)
    most = max((*args.opponents, *(args.eval_opponents or ())), default=0)
    if args.opponent_speeds is not None and len(args.opponent_speeds) < most:
        parser.fail(
            "--opponent-speeds",
            f"{len(args.opponent_speeds)} speeds for races of up to {most} opponents",
        )
    if args.opponents and "estimate" in args.pose:
        parser.fail("--pose", "a race (--opponents) runs no MCL: train on truth or none")
    if args.eval_opponents is None:
        args.eval_opponents = tuple(sorted(set(args.opponents)))
    check_out(parser, args.out)

    from mcl.agents.ppo import require_sb3

    try:
        require_sb3()
    except ImportError as exc:
        parser.error(str(exc))
    with output_folder(parser, args.out):
        return _train_and_evaluate(args)


def _train_and_evaluate(args: argparse.Namespace) -> int:
    """Train (or reuse) a policy per --pose in ``args.out``, then evaluate them."""
    from mcl.agents.ppo import PPOSettings, load_policy, train

    settings = PPOSettings(n_envs=args.envs)
    models: dict[str, Path] = {}
    for source in args.pose:
        folder = args.out / source
        model = folder / "model.zip"
        if args.retrain or not model.is_file():
            print(f"training on the {source} pose: {args.timesteps} timesteps into {folder}")
            tasks = [_task(args, source, k) for k in args.opponents or (0,)]
            report = train(
                tasks,
                args.timesteps,
                folder,
                settings=settings,
                seed=args.seed,
                progress=sys.stderr.isatty(),
                max_minutes=args.max_minutes,
            )
            print(f"  {report.timesteps} timesteps in {report.wall_s / 60:.1f} min")
        models[source] = model
    if args.no_eval:
        return 0
    return _evaluate(args, models, load_policy)


def _task(args: argparse.Namespace, source: str, opponents: int, **changes) -> LapTaskConfig:
    """The lap task of the run's --env and opponents settings."""
    speeds = args.opponent_speeds
    return LapTaskConfig(
        pose_source=source,
        env=args.env,
        opponents=opponents,
        opponent_driver=args.opponent_driver,
        opponent_speeds=None if speeds is None or not opponents else speeds[:opponents],
        **changes,
    )


def _policy_name(args: argparse.Namespace, source: str) -> str:
    """``"true pose"``, ``"true pose, single_track, vs 1-3 opponents"``, ..."""
    name = _NAMES[source]
    model = dict(args.env).get("car_model", "kinematic")
    if model != "kinematic":
        name += f", {model}"
    if args.opponents:
        counts = sorted(set(args.opponents))
        shown = str(counts[0]) if len(counts) == 1 else ",".join(map(str, counts))
        name += f", vs {shown} opponent{'s' if counts[-1] > 1 else ''}"
    return name


def _tests(args: argparse.Namespace) -> list[LapTaskConfig]:
    """Every test: each car model, each opponent count (none without), each pose (no estimate
    in a race)."""
    car_models = args.eval_car_models or (dict(args.env).get("car_model", "kinematic"),)
    tests = []
    for model in car_models:
        env_args = argparse.Namespace(**{**vars(args), "env": (*args.env, ("car_model", model))})
        for k in args.eval_opponents or (0,):
            for source in args.eval_poses:
                if source != "estimate":
                    tests.append(_task(env_args, source, k))
                elif not k:
                    tests += [
                        _task(env_args, source, 0, n_particles=n, filter_beams=b)
                        for n, b in args.eval_filters
                    ]
    return tests


def _evaluate(args: argparse.Namespace, models: dict[str, Path], load_policy) -> int:
    from mcl.agents.evaluate import evaluate_policy, learning_curve, tested_on, write_results
    from mcl.experiments.video import FrameWriter

    results = []
    seeds = list(range(1000, 1000 + args.eval_seeds))  # not the training seeds
    tests = _tests(args)
    for source, model in models.items():
        policy = load_policy(model)
        for test in tests:
            print(f"testing the policy trained on the {source} pose on the {tested_on(test)}")
            results += evaluate_policy(
                policy, _policy_name(args, source), test, seeds, args.eval_seconds
            )
    files = write_results(results, args.out)
    curves = {f"trained on: {_policy_name(args, s)}": args.out / s / "learning.csv" for s in models}
    files.append(learning_curve(curves, args.out / "learning_curve.png"))
    if args.video_seconds > 0:
        source = list(models)[-1]
        video = args.out / "agent.mp4"
        with FrameWriter(video, fps=10) as writer:
            evaluate_policy(
                load_policy(models[source]),
                source,
                next((t for t in tests if t.localized), tests[-1]),
                [seeds[0]],
                args.video_seconds,
                on_frame=writer.write,
            )
        files.append(video)
    print((args.out / "eval.md").read_text())
    print("wrote " + ", ".join(str(f) for f in files))
    return 0


if __name__ == "__main__":
    sys.exit(main())
