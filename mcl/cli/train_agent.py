"""Train PPO to drive laps on the default map from the scan and a pose, then test it on MCL's
estimate (needs the extra [rl]: pip install torch==2.13.0 -e '.[rl]').

For each pose source in --pose (truth: the simulator's pose; estimate: obs["pose_estimate"] of MCL
in the loop) it trains a policy into OUT/<source>/ (skipped when OUT/<source>/model.zip exists and
--retrain is not given), then tests every policy on the true pose and on MCL's estimate (with each particle count of
--eval-particles; fewer particles, larger errors) and writes OUT/eval.csv, OUT/eval.md,
OUT/learning_curve.png and OUT/agent.mp4 (the last policy on the estimate, --video-seconds).

Example (the README's run):

    .venv/bin/racecar-sim train-agent --timesteps 400000 --out runs/agent
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mcl.agents.lap_env import POSE_SOURCES, LapTaskConfig


def _sources(text: str) -> tuple[str, ...]:
    names = tuple(v.strip() for v in text.split(",") if v.strip())
    bad = [n for n in names if n not in POSE_SOURCES]
    if bad or not names:
        raise argparse.ArgumentTypeError(
            f"--pose takes {' and/or '.join(POSE_SOURCES)}, comma-separated; got {text!r}"
        )
    return names


def _counts(text: str) -> tuple[int, ...]:
    try:
        counts = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        counts = ()
    if not counts or min(counts) < 1:
        raise argparse.ArgumentTypeError(
            f"expected positive integers, comma-separated; got {text!r}"
        )
    return counts


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--timesteps", type=int, default=300_000, help="env steps per policy")
    parser.add_argument("--pose", type=_sources, default=POSE_SOURCES, help="truth,estimate")
    parser.add_argument("--envs", type=int, default=8, help="envs stepped together")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--retrain", action="store_true", help="train even if a model exists")
    parser.add_argument("--no-eval", action="store_true", help="train only")
    parser.add_argument("--eval-seeds", type=int, default=5, help="test episodes per policy")
    parser.add_argument("--eval-seconds", type=float, default=60.0, help="seconds per test")
    parser.add_argument(
        "--eval-particles",
        type=_counts,
        default=(300,),
        help="particle counts of the tests on the estimate, comma-separated (e.g. 300,30)",
    )
    parser.add_argument("--video-seconds", type=float, default=20.0, help="0: no video")
    parser.add_argument("--out", type=Path, default=Path("runs/agent"))
    args = parser.parse_args(argv)
    for name in ("timesteps", "envs", "eval_seeds"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1")
    if args.eval_seconds <= 0 or args.video_seconds < 0:
        parser.error("--eval-seconds must be > 0 and --video-seconds >= 0")

    from mcl.agents.ppo import PPOSettings, load_policy, require_sb3, train

    try:
        require_sb3()
    except ImportError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
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
    tests = [LapTaskConfig(pose_source="truth")]
    tests += [LapTaskConfig(pose_source="estimate", n_particles=n) for n in args.eval_particles]
    for source, model in models.items():
        policy = load_policy(model)
        for test in tests:
            print(f"testing the policy trained on the {source} pose on the {tested_on(test)}")
            results += evaluate_policy(policy, f"{source} pose", test, seeds, args.eval_seconds)
    files = write_results(results, args.out)
    curves = {f"trained on the {s} pose": args.out / s / "learning.csv" for s in models}
    files.append(learning_curve(curves, args.out / "learning_curve.png"))
    if args.video_seconds > 0:
        source = list(models)[-1]
        video = args.out / "agent.mp4"
        with FrameWriter(video, fps=10) as writer:
            evaluate_policy(
                load_policy(models[source]),
                source,
                tests[1],
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
