"""How hard the learned policy pushes in each run of an episode, with and without the
stationary robot's speed governor (training world): the mean |a1| of the pushes made, per
run. Run: python experiments/sim2real/governed_actions_by_run.py real-ur10-4push [--no-governor]
"""

from __future__ import annotations

import argparse

import numpy as np

from masspush.models import model_and_policy
from masspush.real import SimRobot, run_segments
from masspush.settings import get_setting


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("setting")
    parser.add_argument("--no-governor", action="store_true")
    parser.add_argument("--chains", type=int, default=12)
    parser.add_argument("--runs", type=int, default=8)
    parser.add_argument("--seed", type=int, default=4242)
    args = parser.parse_args()
    if args.chains < 1 or args.runs < 1:
        parser.error("--chains and --runs must be >= 1")
    try:  # before any work
        setting = get_setting(args.setting)
        predictor, _, policy = model_and_policy("tp+", args.setting)
    except (ValueError, OSError) as err:
        parser.error(str(err))
    k = setting.env_config().pushes
    robot = SimRobot(setting, seed=args.seed, pushes=k * args.runs)
    if args.no_governor:
        robot.governor = None
    pushed = np.full((args.chains, args.runs * k), np.nan)
    for i in range(args.chains):
        episode = run_segments(robot, predictor, policy, k, args.runs, seed=robot.seed)
        a1 = np.abs(np.asarray(episode.actions, float)[:, 0])
        pushed[i, : len(a1)] = a1
    robot.close()
    per_run = np.nanmean(pushed.reshape(args.chains, args.runs, k), axis=(0, 2))
    print("governor" if not args.no_governor else "no governor", "mean |a1| per run:",
          " ".join(f"{v:.2f}" for v in per_run))  # fmt: skip


if __name__ == "__main__":
    main()
