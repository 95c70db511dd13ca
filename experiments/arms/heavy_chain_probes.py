"""Why do the arms barely move heavy (1-10 kg links) chains? Three probes.

    python experiments/arms/heavy_chain_probes.py [--pushes 60]

Each probe pushes the same 60 random 2-link chains (masses in [1, 10] kg, and [0.1, 1] kg
for comparison) with the same random actions and prints how far the root link moved:
1. the KUKA with its torque limits (actuator ctrlrange and joint actfrcrange) x1, x3, x10;
2. each pusher: KUKA, UR10, stiff;
3. the KUKA with realistic reflected rotor inertia (MuJoCo armature) on its joints;
4. where the push goes: the impulse the KUKA's tip gives the chain during its 10 ms hold
   (pushes at half speed, 2.5 m/s), the speed that would give the whole chain, and how far
   the chain then moved.
`--probes 4` runs only the fourth. Used in docs/notebook (baselines, heavy chains).
"""

import argparse

import mujoco
import numpy as np

from masspush.config import PhysicsConfig
from masspush.sim import ArmPusher, ChainSim, make_pusher, sample_chain

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
    print(
        f"{label:44s} masses {mass_range}: root moved median {np.median(moved):6.1f} mm, "
        f"under 2 mm {100 * np.mean(moved < 2):3.0f} %, failed {failures} of {pushes}"
    )


def impulse_probe(mass_range, pushes):
    physics = PhysicsConfig(n_links=2, mass_range=mass_range)
    rng = np.random.default_rng(0)
    pusher = make_pusher("kuka")
    impulses, speeds, moved = [], [], []
    for _ in range(pushes):
        chain, action = sample_chain(physics, rng), rng.uniform(-1, 1, 2)
        action[0] = 0.5 * np.sign(action[0])  # 2.5 m/s
        sim = ChainSim(chain, physics, pusher)
        force = np.zeros(6)
        total = [0.0]

        def on_step(sim=sim, total=total, force=force):
            ee = pusher._h(sim.model).ee
            for c in range(sim.data.ncon):
                if ee in (sim.data.contact[c].geom1, sim.data.contact[c].geom2):
                    mujoco.mj_contactForce(sim.model, sim.data, c, force)
                    total[0] += force[0] * sim.model.opt.timestep

        sim.on_step = on_step
        before = sim.config()
        if sim.push(action).failure:
            continue
        impulses.append(total[0])
        speeds.append(total[0] / sum(chain.masses))
        moved.append(1000 * np.linalg.norm(sim.config()[:2] - before[:2]))
    print(
        f"4. kuka at 2.5 m/s, masses {mass_range}: contact impulse median "
        f"{np.median(impulses):5.2f} N s, that over the chain's mass {np.median(speeds):5.2f} "
        f"m/s, root moved median {np.median(moved):6.1f} mm ({len(moved)} pushes)"
    )


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--pushes", type=int, default=60)
    parser.add_argument("--probes", default="1,2,3,4", help="which probes, comma-separated")
    args = parser.parse_args()
    n, which = args.pushes, set(args.probes.split(","))
    heavy, light = (1.0, 10.0), (0.1, 1.0)
    if "1" in which:
        for scale in (1, 3, 10):
            probe(f"1. kuka, torque limits x{scale}", "kuka", heavy, n, torque_scale=scale)
    if "2" in which:
        for name in ("kuka", "ur10", "stiff"):
            for masses in (light, heavy):
                probe(f"2. {name}", name, masses, n)
    if "3" in which:
        for masses in (light, heavy):
            probe(
                "3. kuka, armature 0.7/0.7/0.4/0.1/0.1/0.05", "kuka", masses, n, armature=ARMATURE
            )
    if "4" in which:
        for masses in (light, heavy):
            impulse_probe(masses, n)


if __name__ == "__main__":
    main()
