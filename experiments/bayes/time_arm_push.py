"""Time the particle filter's arm push (`ArmScene.push`): milliseconds per push, one core.

    python experiments/bayes/time_arm_push.py --setting 3link-0.1-1 [--pushes 40] [--profile]

To compare two versions, run it under each back to back (e.g. an older checkout's src on
PYTHONPATH), with nothing else running: this machine's speed drifts by tens of percent.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time
from dataclasses import replace

import numpy as np

from masspush.bayes import ArmScene, BayesConfig
from masspush.settings import get_setting


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--setting", default="3link-0.1-1")
    parser.add_argument("--pushes", type=int, default=40)
    parser.add_argument("--profile", action="store_true", help="print the top of a profile")
    args = parser.parse_args()
    setting = get_setting(args.setting)
    # The filter's settling cap, as the filter runs it.
    physics = replace(setting.physics(), settle_time_cap=BayesConfig().settle_cap)
    n = physics.n_links
    scene = ArmScene(physics, setting.pusher, (0.12,) * n)
    rng = np.random.default_rng(0)
    jobs = [
        (np.concatenate([[0.0, 0.0, 0.0], rng.uniform(-1, 1, n - 1)]),
         rng.uniform(-1, 1, 2), rng.uniform(*physics.mass_range, n),
         rng.uniform(*physics.friction_range))
        for _ in range(args.pushes)
    ]  # fmt: skip

    def run() -> None:
        for start, action, masses, mu in jobs:
            scene.push(start, action, masses, float(mu))

    t = time.perf_counter()
    run()
    print(f"{args.setting}: {(time.perf_counter() - t) / args.pushes * 1e3:.1f} ms per arm push")
    if args.profile:
        profile = cProfile.Profile()
        profile.runcall(run)
        pstats.Stats(profile).sort_stats("tottime").print_stats(15)


if __name__ == "__main__":
    main()
