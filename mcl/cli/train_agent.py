"""Train PPO to drive laps on the default map from the scan and a pose, then test it on MCL's
estimate (needs the extra [rl]: pip install torch==2.13.0 -e '.[rl]').

For each pose source in --pose (truth: the simulator's pose; estimate: obs["pose_estimate"] of MCL
in the loop) it trains a policy into OUT/<source>/ (skipped when OUT/<source>/model.zip exists and
--retrain is not given), then tests every policy on the true pose, with no pose (the pose features
held constant: how much the policy needs the pose) and on MCL's estimate (with each filter of
--eval-filters; fewer particles and beams, larger errors) and writes OUT/eval.csv,
OUT/eval.md, OUT/learning_curve.png and OUT/agent.mp4 (the last policy on the estimate).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mcl.agents.lap_env import POSE_SOURCES, LapTaskConfig
from mcl.cli.common import Parser, non_negative_float, positive_float, positive_int

EXAMPLES = """\
example (the README's run, about 12 + 25 minutes of training on 2 busy cores):
  racecar-sim train-agent --timesteps 150000 --eval-filters 300,10,5x2 --out runs/agent
"""


_NAMES = {"truth": "true pose", "estimate": "MCL estimate", "none": "no pose (scan only)"}
"""Pose source -> the policy's name in the tables."""


def _sources(text: str) -> tuple[str, ...]:
    names = tuple(v.strip() for v in text.split(",") if v.strip())
    bad = [n for n in names if n not in POSE_SOURCES]
    if bad or not names:
        raise argparse.ArgumentTypeError(
            f"takes {' and/or '.join(POSE_SOURCES)}, comma-separated; got {text!r}"
        )
    return names


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
    add("--seed", type=int, default=0, help="training seed")
    add("--retrain", action="store_true", help="train even if OUT/<source>/model.zip exists")
    add("--no-eval", action="store_true", help="train only")
    add("--eval-seeds", type=positive_int, default=5, help="test episodes per policy and test")
    add("--eval-seconds", type=positive_float, default=60.0, help="seconds per test episode")
    add(
        "--eval-filters",
        type=_filters,
        default=((300, 60),),
        metavar="N[xB],...",
        help="filters of the tests on the estimate: particles, optionally x beams per particle "
        "(fewer, larger errors), e.g. 300,30,5x2",
    )
    add("--video-seconds", type=non_negative_float, default=20.0, help="0: no video")
    add("--out", type=Path, default=Path("runs/agent"), metavar="DIR", help="output folder")
    args = parser.parse_args(argv)

    from mcl.agents.ppo import PPOSettings, load_policy, require_sb3, train

    try:
        require_sb3()
    except ImportError as exc:
        parser.error(str(exc))
    settings = PPOSettings(n_envs=args.envs)
    models: dict[str, Path] = {}
    for source in args.pose:
        folder = args.out / source
        model = folder / "model.zip"
        if args.retrain or not model.is_file():
            print(f"training on the {source} pose: {args.timesteps} timesteps into {folder}")
            report = train(
                LapTaskConfig(pose_source=source),
                args.timesteps,
                folder,
                settings=settings,
                seed=args.seed,
                progress=sys.stderr.isatty(),
            )
            print(f"  {report.timesteps} timesteps in {report.wall_s / 60:.1f} min")
        models[source] = model
    if args.no_eval:
        return 0
    return _evaluate(args, models, load_policy)


def _evaluate(args: argparse.Namespace, models: dict[str, Path], load_policy) -> int:
    from mcl.agents.evaluate import evaluate_policy, learning_curve, tested_on, write_results
    from mcl.experiments.video import FrameWriter

    results = []
    seeds = list(range(1000, 1000 + args.eval_seeds))  # not the training seeds
    tests = [LapTaskConfig(pose_source="truth"), LapTaskConfig(pose_source="none")]
    tests += [
        LapTaskConfig(pose_source="estimate", n_particles=n, filter_beams=b)
        for n, b in args.eval_filters
    ]
    for source, model in models.items():
        policy = load_policy(model)
        for test in tests:
            print(f"testing the policy trained on the {source} pose on the {tested_on(test)}")
            results += evaluate_policy(policy, _NAMES[source], test, seeds, args.eval_seconds)
    files = write_results(results, args.out)
    curves = {f"trained on: {_NAMES[s]}": args.out / s / "learning.csv" for s in models}
    files.append(learning_curve(curves, args.out / "learning_curve.png"))
    if args.video_seconds > 0:
        source = list(models)[-1]
        video = args.out / "agent.mp4"
        with FrameWriter(video, fps=10) as writer:
            evaluate_policy(
                load_policy(models[source]),
                source,
                tests[2],
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
