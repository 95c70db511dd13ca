"""The speed governor with the training world's slide bounds against bounds fitted in a lab:
chains lost over runs of the policy in a target-world lab.

    python experiments/sim2real/governor_in_lab.py --lab 5 --fit RECORDING [--runs 8] [--chains 40]

RECORDING: random pushes in that lab (e.g. `results/sim2real-governed-lab-16push/5/random.jsonl`
from `masspush sim2real --lab 5 --segments 8`), fitted by `masspush.real.governor.fit_governor`.
The same chains (the robot's seed) for every policy and governor.
"""

import argparse
from pathlib import Path

import numpy as np
import torch

from masspush.models import model_and_policy
from masspush.real import TargetWorldRobot, fit_governor, run_segments
from masspush.settings import get_setting
from masspush.sim import REACH_FAILURES


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--setting", default="real-ur10")
    parser.add_argument("--lab", type=int, default=5)
    parser.add_argument("--fit", type=Path, required=True)
    parser.add_argument("--runs", type=int, default=8)
    parser.add_argument("--chains", type=int, default=40)
    parser.add_argument("--seed", type=int, default=777)
    args = parser.parse_args()
    torch.set_num_threads(1)
    if args.chains < 1 or args.runs < 1:
        parser.error("--chains and --runs must be >= 1")
    try:  # before any work
        setting = get_setting(args.setting)
        shipped = TargetWorldRobot(setting, lab=args.lab).governor
        if shipped is None:
            raise ValueError(f"{setting.name}'s robot follows the chain: it has no governor")
        governors = {"training": shipped, "fitted": fit_governor(shipped, args.fit)}
    except (ValueError, OSError) as err:
        parser.error(str(err))
    pushes = setting.env_config().pushes
    for name, governor in governors.items():
        for model in ("tp+", "rp"):
            predictor, _, policy = model_and_policy(model, setting.name)
            robot = TargetWorldRobot(setting, seed=args.seed, lab=args.lab)
            robot.governor = governor
            lost, speeds = [], []
            for _ in range(args.chains):
                episode = run_segments(robot, predictor, policy, pushes, args.runs, seed=robot.seed)
                speeds += [abs(float(a[0])) for a in episode.actions]
                if episode.failure in REACH_FAILURES:
                    lost.append(len(episode.reports))
            print(f"{name:8s} governor, {model:3s}: lost {len(lost)} of {args.chains} over "
                  f"{args.runs} runs (at pushes {sorted(lost)}); mean |a1| {np.mean(speeds):.2f}",
                  flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
