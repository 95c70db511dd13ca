"""Does raising the KUKA's torque limits let it move heavy (1-10 kg links) chains?

    python scripts/kuka_torque_limits.py [--pushes 60]

Pushes the same random 2-link chains (masses in [1, 10] kg) with random actions, with the
KUKA's torque limits (actuator ctrlrange and joint actfrcrange) scaled by 1, 3 and 10, and
prints how far the root link moved. Used in docs/results.md (baselines, 2link-1-10).
"""

import argparse

import numpy as np

from masspush.arm import ArmPusher
from masspush.chain import sample_chain
from masspush.config import PhysicsConfig
from masspush.simulate import ChainSim


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--pushes", type=int, default=60)
    args = parser.parse_args()
    physics = PhysicsConfig(n_links=2, mass_range=(1.0, 10.0))
    for scale in (1, 3, 10):
        rng = np.random.default_rng(0)
        moved, failures = [], 0
        pusher = ArmPusher("kuka")
        for _ in range(args.pushes):
            chain, action = sample_chain(physics, rng), rng.uniform(-1, 1, 2)
            sim = ChainSim(chain, physics, pusher)
            model = sim.model
            acts = [model.actuator(f"kuka/joint{j}").id for j in range(1, 7)]
            joints = [model.joint(f"kuka/joint{j}").id for j in range(1, 7)]
            model.actuator_ctrlrange[acts] *= scale
            model.jnt_actfrcrange[joints] *= scale
            pusher._model = None  # re-read the limits
            before = sim.config()
            if sim.push(action).failure:
                failures += 1
                continue
            moved.append(1000 * np.linalg.norm(sim.config()[:2] - before[:2]))
        moved = np.array(moved)
        print(
            f"torque limits x{scale}: root moved median {np.median(moved):.1f} mm, "
            f"90th percentile {np.percentile(moved, 90):.1f} mm, under 2 mm "
            f"{100 * np.mean(moved < 2):.0f} %, failed pushes {failures} of {args.pushes}"
        )


if __name__ == "__main__":
    main()
