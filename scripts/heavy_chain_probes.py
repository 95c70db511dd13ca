"""Why do the arms barely move heavy (1-10 kg links) chains? Three probes.

    python scripts/heavy_chain_probes.py [--pushes 60]

Each probe pushes the same 60 random 2-link chains (masses in [1, 10] kg, and [0.1, 1] kg
for comparison) with the same random actions and prints how far the root link moved:
1. the KUKA with its torque limits (actuator ctrlrange and joint actfrcrange) x1, x3, x10;
2. each pusher: KUKA, UR10, stiff;
3. the KUKA with realistic reflected rotor inertia (MuJoCo armature) on its joints.
Used in docs/results.md (baselines, 2link-1-10).
"""

import argparse

import numpy as np

from masspush.arm import ArmPusher
from masspush.chain import sample_chain
from masspush.config import PhysicsConfig
from masspush.pusher import make_pusher
from masspush.simulate import ChainSim

ARMATURE = np.array([0.7, 0.7, 0.4, 0.1, 0.1, 0.05])  # kg m^2, geared industrial joints


def probe(label, pusher_name, mass_range, pushes, torque_scale=1.0, armature=None):
    physics = PhysicsConfig(n_links=2, mass_range=mass_range)
    rng = np.random.default_rng(0)
    pusher = make_pusher(pusher_name)
    moved, failures = [], 0
    for _ in range(pushes):
        chain, action = sample_chain(physics, rng), rng.uniform(-1, 1, 2)
        sim = ChainSim(chain, physics, pusher)
        if isinstance(pusher, ArmPusher):
            h = pusher._h(sim.model)
            sim.model.actuator_ctrlrange[h.act] *= torque_scale
            sim.model.jnt_actfrcrange[[sim.model.dof_jntid[d] for d in h.dadr]] *= torque_scale
            if armature is not None:
                sim.model.dof_armature[h.dadr] = armature + 0.01
            pusher._model = None  # re-read the limits
        before = sim.config()
        if sim.push(action).failure:
            failures += 1
            continue
        moved.append(1000 * np.linalg.norm(sim.config()[:2] - before[:2]))
    moved = np.array(moved)
    print(f"{label:44s} masses {mass_range}: root moved median {np.median(moved):6.1f} mm, "
          f"under 2 mm {100 * np.mean(moved < 2):3.0f} %, failed {failures} of {pushes}")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--pushes", type=int, default=60)
    n = parser.parse_args().pushes
    heavy, light = (1.0, 10.0), (0.1, 1.0)
    for scale in (1, 3, 10):
        probe(f"1. kuka, torque limits x{scale}", "kuka", heavy, n, torque_scale=scale)
    for name in ("kuka", "ur10", "stiff"):
        for masses in (light, heavy):
            probe(f"2. {name}", name, masses, n)
    for masses in (light, heavy):
        probe("3. kuka, armature 0.7/0.7/0.4/0.1/0.1/0.05", "kuka", masses, n, armature=ARMATURE)


if __name__ == "__main__":
    main()
