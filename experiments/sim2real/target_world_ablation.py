"""Which of the target world's differences spread the learned estimate? The analysis behind
"Where the gap comes from" in docs/notebook (sim-to-real).

    python experiments/sim2real/target_world_ablation.py [--setting real-ur10-4push] [--model tp+]
        [--episodes 40] [--groups none,all,solver,friction,...]

For each group, the target world with that group's knobs put back to the training world's
values (`none`: the target world as is; `all`: every knob put back, so only what the knobs
do not reach is left: condim 4 and the links' contact priority over the table)
runs `--episodes` episodes of the learned policy for the three paper classes that are
hardest to tell apart, and prints each class's mean and std of the estimated share of
link 1. The classifier separates classes whose shares differ by 0.05, so the std is what
decides the accuracy. Episodes share seeds across groups (paired).
"""

import argparse
import time
from dataclasses import replace

import numpy as np

from masspush.models import model_and_policy
from masspush.real import (
    PAPER_CLASSES,
    TRAINING_KNOBS,
    TargetWorld,
    TargetWorldRobot,
    run_estimation,
    scaled_world,
)
from masspush.settings import get_setting

GROUPS = {
    "none": (),
    "solver": ("timestep", "solver", "solver_iterations", "cone", "contact_solref",
               "contact_solimp", "torsional_friction"),
    "friction": ("friction_range", "friction_variation"),
    "geometry": ("link_width", "link_height", "com_offset", "length_error"),
    "tracking": ("obs_noise", "obs_bias"),
    "actuation": ("action_noise", "speed_gain", "contact_bias"),
}  # fmt: skip
"""Knobs of `TargetWorld` put back to the training world's values, by kind of difference."""
CLASSES = ("0.160-0.160", "0.064-0.192", "0.064-0.256")


def world_without(group: str, groups: dict | None = None) -> TargetWorld:
    """The target world with the knobs of `group` (a key of `groups`, default `GROUPS`, or
    "all") put back to the training world's values."""
    if group == "all":
        return scaled_world(0)
    return replace(TargetWorld(), **{k: TRAINING_KNOBS[k] for k in (groups or GROUPS)[group]})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--setting", default="real-ur10-4push")
    parser.add_argument("--model", default="tp+")
    parser.add_argument("--episodes", type=int, default=40)
    parser.add_argument("--groups", default=",".join(["none", "all", *list(GROUPS)[1:]]))
    args = parser.parse_args()
    setting = get_setting(args.setting)
    predictor, _, policy = model_and_policy(args.model, setting.name)
    pushes = setting.env_config().pushes
    classes = {label: PAPER_CLASSES[label] for label in CLASSES}
    print("| target world, put back to training | " + " | ".join(classes) + " | s |")
    print("|---" * (len(classes) + 2) + "|")
    for group in args.groups.split(","):
        start, cells = time.perf_counter(), []
        for label, masses in classes.items():
            c = list(PAPER_CLASSES).index(label)
            robot = TargetWorldRobot(setting, world_without(group), seed=100_000 * c,
                                     masses=masses)  # fmt: skip
            shares = []
            while len(shares) < args.episodes:
                episode = run_estimation(robot, predictor, policy, pushes,
                                         seed=robot.seed)  # fmt: skip
                if episode.estimates:
                    shares.append(episode.estimates[-1][0])
            cells.append(f"{np.mean(shares):.3f} +- {np.std(shares):.3f}")
        print(f"| {group} | " + " | ".join(cells) + f" | {time.perf_counter() - start:.0f} |",
              flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
