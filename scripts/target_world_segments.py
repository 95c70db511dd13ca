"""Would more pushes per episode close the sim-to-real gap? The analysis behind "More pushes
of the same episode" in docs/results.md (sim-to-real).

    python scripts/target_world_segments.py [--setting real-ur10-4push] [--model tp+]
        [--episodes 30] [--segments 4] [--worlds target,training] [--severity 1]

Each episode runs the learned policy for `--segments` consecutive segments of the setting's
pushes on the same chain, in the same world, with the same per-episode biases (tracker
bias, contact bias, speed gain, centre of mass, friction field): each segment starts where
the last one left the chain, and the model estimates each segment on its own. Averaging the
segments' estimates averages the per-push noise away, as a model trained for that many
pushes could at best, but not what is fixed for the episode. For the three paper classes
that are hardest to tell apart it prints the per-class mean +- std of the estimated share
of link 1 over episodes, averaged over the first 1, 2, 4... segments. Classes 0.05 apart in
that share need a std of about 0.02 for the classifier to reach 90 %. `--severity` scales
the target world's differences from training (`masspush.target_world.scaled_world`).
"""

import argparse
import time
from dataclasses import replace

import numpy as np

from masspush.env import ChainEnv
from masspush.evaluate import model_and_policy
from masspush.finetune import PAPER_CLASSES
from masspush.robot import RestPose, SimRobot, run_estimation
from masspush.settings import get_setting
from masspush.target_world import TargetWorldRobot, scaled_world

CLASSES = ("0.160-0.160", "0.064-0.192", "0.064-0.256")


def segment_shares(robot, predictor, policy, pushes: int, segments: int, episodes: int):
    """(episodes, segments): link 1's estimated share after each segment of each episode
    in which no push failed."""
    rows = []
    while len(rows) < episodes:
        rest = robot.start()
        shares = []
        for s in range(segments):
            episode = run_estimation(robot, predictor, policy, pushes, start=rest,
                                     seed=robot.seed * segments + s)  # fmt: skip
            if episode.failure is not None or len(episode.estimates) < pushes:
                break
            shares.append(float(episode.estimates[-1][0]))
            rest = RestPose(episode.reports[-1].config, rest.lengths)
        if len(shares) == segments:
            rows.append(shares)
    return np.array(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--setting", default="real-ur10-4push")
    parser.add_argument("--model", default="tp+")
    parser.add_argument("--episodes", type=int, default=30)
    parser.add_argument("--segments", type=int, default=4)
    parser.add_argument("--worlds", default="target,training")
    parser.add_argument("--severity", type=float, default=1.0, help="of the target world")
    args = parser.parse_args()
    setting = get_setting(args.setting)
    predictor, _, policy = model_and_policy(args.model, setting.name)
    pushes = setting.env_config().pushes
    counts = [k for k in (1, 2, 4, 8, 16) if k <= args.segments]
    print("| world | class (true share of link 1) | "
          + " | ".join(f"{k * pushes} pushes ({k} segment{'s' * (k > 1)})" for k in counts)
          + " |")  # fmt: skip
    print("|---" * (len(counts) + 2) + "|")
    for world in args.worlds.split(","):
        start = time.perf_counter()
        name = f"{world} x{args.severity:g}" if world == "target" and args.severity != 1 else world
        for label in CLASSES:
            masses = PAPER_CLASSES[label]
            c = list(PAPER_CLASSES).index(label)
            if world == "target":
                robot = TargetWorldRobot(setting, scaled_world(args.severity),
                                         seed=100_000 * c, masses=masses)  # fmt: skip
            else:  # the training world's episodes end after the setting's pushes: allow all
                robot = SimRobot(setting, seed=100_000 * c, masses=masses)
                robot.env.close()
                robot.env = ChainEnv.from_config(
                    replace(setting.env_config(), pushes=pushes * args.segments)
                )
            shares = segment_shares(robot, predictor, policy, pushes, args.segments,
                                    args.episodes)  # fmt: skip
            robot.close()
            truth = masses[0] / sum(masses)
            cells = [f"{shares[:, :k].mean(1).mean():.3f} +- {shares[:, :k].mean(1).std():.3f}"
                     for k in counts]  # fmt: skip
            print(f"| {name} | {label} ({truth:.2f}) | " + " | ".join(cells) + " |", flush=True)
        print(f"<!-- {name}: {time.perf_counter() - start:.0f} s -->", flush=True)


if __name__ == "__main__":
    main()
