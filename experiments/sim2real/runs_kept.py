"""Does a stationary robot keep the chain over runs of the policy? Chains lost, per policy.

    python experiments/sim2real/runs_kept.py [--setting real-ur10] [--learned tp+] \
        [--random rp] [--runs 1,8] [--chains 40] [--seed 777] [--settings-file F]

The robot of the setting (the stationary UR10 of `real-ur10`) pushes `--chains` chains of the
training world, each for R runs of the setting's pushes in a row (`run_segments`: the chain
kept, the predictor's history restarting each run; a policy trained on runs keeps its memory
as in training), with the learned model's policy and with random pushes. Per policy and R:
the chains lost (`REACH_FAILURES`) and at which push, and the predictor's error after each
run's last push on the chains still there. The same chains for every policy (the robot's
seed). Used in docs/notebook/2026-12-02-runs-of-the-policy.md and by the test of the shipped
models (`tests/test_models.py`), which checks the 95 % bar on the same set.
"""

import argparse

import numpy as np

from masspush.metrics import percentage_error
from masspush.models import model_and_policy
from masspush.real import SimRobot, run_segments
from masspush.settings import get_setting
from masspush.sim import REACH_FAILURES


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--setting", default="real-ur10")
    parser.add_argument("--learned", default="tp+", help="model whose policy pushes")
    parser.add_argument("--random", default="rp", help="a random-push model")
    parser.add_argument("--runs", default="1,8")
    parser.add_argument("--chains", type=int, default=40)
    parser.add_argument("--seed", type=int, default=777)
    parser.add_argument("--settings-file", help="TOML settings (e.g. an override of --setting)")
    args = parser.parse_args()
    setting = get_setting(args.setting, args.settings_file)
    pushes = setting.env_config().pushes
    for runs in (int(r) for r in args.runs.split(",")):
        for model in (args.learned, args.random):
            predictor, _, policy = model_and_policy(model, setting.name)
            robot = SimRobot(setting, seed=args.seed, pushes=pushes * runs)
            lost_at, estimates, truths = [], [], []
            for _ in range(args.chains):
                episode = run_segments(robot, predictor, policy, pushes, runs, seed=robot.seed)
                if episode.failure in REACH_FAILURES:
                    lost_at.append(len(episode.reports))
                elif episode.failure is None:
                    estimates.append(episode.run_estimates)
                    truths.append(robot.truth["mass_distribution"])
            robot.close()
            per_run = [
                percentage_error(np.array([e[r] for e in estimates]), np.array(truths))
                for r in range(runs)
            ] if estimates else []  # fmt: skip
            print(
                f"{model:4s} {runs} run(s) of {pushes}: lost {len(lost_at)} of {args.chains}"
                f" (at pushes {sorted(lost_at)}); error after each run on the {len(estimates)}"
                f" kept whole: {[round(e, 1) for e in per_run]}"
            )


if __name__ == "__main__":
    main()
