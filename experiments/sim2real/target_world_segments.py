"""Would more pushes per episode close the sim-to-real gap? The analysis behind "More pushes
of the same episode" in docs/notebook (sim-to-real).

    python experiments/sim2real/target_world_segments.py [--setting real-ur10-4push] [--model tp+]
        [--episodes 30] [--segments 4] [--worlds target,training] [--severity 1] [--lab SEED]

Each episode runs the learned policy for `--segments` consecutive segments of the setting's
pushes on the same chain, in the same world, with the same per-episode biases (tracker
bias, contact bias, speed gain, centre of mass, friction field): each segment starts where
the last one left the chain, and the model estimates each segment on its own. Averaging the
segments' estimates averages the per-push noise away, as a model trained for that many
pushes could at best, but not what is fixed for the episode. For the three paper classes
that are hardest to tell apart it prints the per-class mean +- std of the estimated share
of link 1 over episodes, averaged over the first 1, 2, 4... segments. Classes 0.05 apart in
that share need a std of about 0.02 for the classifier to reach 90 %. `--severity` scales
the target world's differences from training (`masspush.real.target_world.scaled_world`);
`--lab` runs every target-world episode in one lab (`masspush.real.target_world.Lab`), so that
only the chain's placement and the noise differ between episodes.
"""

import argparse
import time

import numpy as np

from masspush.models import model_and_policy
from masspush.real import (
    PAPER_CLASSES,
    ClassifierConfig,
    SimRobot,
    TargetWorldRobot,
    cross_validate,
    run_segments,
    scaled_world,
)
from masspush.settings import get_setting

CLASSES = ("0.160-0.160", "0.064-0.192", "0.064-0.256")


def segment_estimates(robot, predictor, policy, pushes: int, segments: int, episodes: int):
    """(episodes, segments, links): the estimated mass distribution after each segment of
    each episode in which no push failed."""
    rows = []
    while len(rows) < episodes:
        run = run_segments(robot, predictor, policy, pushes, segments, seed=robot.seed)
        if len(run.estimates) == pushes * segments:
            rows.append(run.run_estimates)
    return np.array(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--setting", default="real-ur10-4push")
    parser.add_argument("--model", default="tp+")
    parser.add_argument("--episodes", type=int, default=30)
    parser.add_argument("--segments", type=int, default=4)
    parser.add_argument("--worlds", default="target,training")
    parser.add_argument("--severity", type=float, default=1.0, help="of the target world")
    parser.add_argument("--lab", type=int, default=None, help="one lab's seed (target world)")
    parser.add_argument(
        "--accuracy", action="store_true",
        help="run all five paper classes and print the cross-validated accuracy of sim2real's "
        "classifier on the segments' averaged estimate",
    )  # fmt: skip
    args = parser.parse_args()
    setting = get_setting(args.setting)
    predictor, _, policy = model_and_policy(args.model, setting.name)
    pushes = setting.env_config().pushes
    counts = [k for k in (1, 2, 4, 8, 16) if k <= args.segments]
    print("| world | class (true share of link 1) | "
          + " | ".join(f"{k * pushes} pushes ({k} segment{'s' * (k > 1)})" for k in counts)
          + " |")  # fmt: skip
    print("|---" * (len(counts) + 2) + "|")
    accuracies = []
    for world in args.worlds.split(","):
        start = time.perf_counter()
        estimates, labels = [], []
        name = f"{world} x{args.severity:g}" if world == "target" and args.severity != 1 else world
        if world == "target" and args.lab is not None:
            name += f", lab {args.lab}"
        for label in PAPER_CLASSES if args.accuracy else CLASSES:
            masses = PAPER_CLASSES[label]
            c = list(PAPER_CLASSES).index(label)
            if world == "target":
                robot = TargetWorldRobot(setting, scaled_world(args.severity), seed=100_000 * c,
                                         masses=masses, lab=args.lab)  # fmt: skip
            else:
                robot = SimRobot(setting, seed=100_000 * c, masses=masses,
                                 pushes=pushes * args.segments)  # fmt: skip
            estimate = segment_estimates(robot, predictor, policy, pushes, args.segments,
                                         args.episodes)  # fmt: skip
            robot.close()
            estimates.append(estimate)
            labels += [c] * len(estimate)
            shares = estimate[..., 0]
            truth = masses[0] / sum(masses)
            cells = [f"{shares[:, :k].mean(1).mean():.3f} +- {shares[:, :k].mean(1).std():.3f}"
                     for k in counts]  # fmt: skip
            print(f"| {name} | {label} ({truth:.2f}) | " + " | ".join(cells) + " |", flush=True)
        print(f"<!-- {name}: {time.perf_counter() - start:.0f} s -->", flush=True)
        if args.accuracy:
            every = np.concatenate(estimates)
            cells = []
            for k in counts:
                features = np.log(every[:, :k].mean(1))
                scores = cross_validate(features, np.array(labels), len(PAPER_CLASSES),
                                        ClassifierConfig())  # fmt: skip
                cells.append(f"{100 * scores['accuracy']:.1f} %")
            accuracies.append(f"| {name} | classifier accuracy, 5 classes | " + " | ".join(cells)
                              + " |")  # fmt: skip
    print("\n".join(accuracies))


if __name__ == "__main__":
    main()
