"""Why does a common mass scale move the stiff pusher's rest pose? (issue 27, item 6;
docs/notebook/2026-12-01-stiff-mass-scale.md)

The issue's case: masses [0.3, 0.7] against k x [0.3, 0.7], friction 0.7, lengths 0.12, joint
angle 0.3, straight root, action (-0.4, 0.5). Prints how far the rest pose moves with k, and
with each candidate term that does not scale with mass changed: the pusher's finite mass,
the solver's tolerance and iterations, the contact softness (solref, solimp), the
torsional and rolling friction.

    .venv/bin/python experiments/pushers/stiff_mass_scale.py
"""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np

from masspush.config import PhysicsConfig
from masspush.sim import ChainSim, make_pusher, sample_chain, wrap_angle

BASE = [0.3, 0.7]
ACTION = np.array([-0.4, 0.5])


def rest(scale: float, physics: PhysicsConfig, adjust=None, pins=None, action=ACTION):
    pins = pins or {"masses": BASE, "friction": 0.7, "lengths": [0.12, 0.12],
                    "joint_angles": [0.3], "root_pose": [0.0, 0.0, 0.0]}  # fmt: skip
    pins = {**pins, "masses": [scale * m for m in pins["masses"]]}
    chain = sample_chain(physics, np.random.default_rng(3), pins, allow_out_of_range=True)
    sim = ChainSim(chain, physics, make_pusher("stiff"), adjust)
    outcome = sim.push(action)
    return None if outcome.failure else sim.config()


def moved(a: np.ndarray | None, b: np.ndarray | None) -> str:
    if a is None or b is None:
        return "a push failed"
    d = a - b
    d[2:] = wrap_angle(d[2:])
    return f"xy {1000 * np.linalg.norm(d[:2]):7.2f} mm, angles {np.abs(d[2:]).max():.4f} rad"


def tight_solver(model: mujoco.MjModel) -> None:
    model.opt.tolerance = 1e-14
    model.opt.iterations = 1000
    model.opt.ls_tolerance = 1e-6


def no_torsion(model: mujoco.MjModel) -> None:
    model.geom_friction[:, 1:] = 0.0


def stiff_contacts(model: mujoco.MjModel) -> None:
    model.geom_solref[:, 0] = 0.002
    model.geom_solimp[:, :2] = [0.99, 0.999]


def main() -> None:
    physics = PhysicsConfig()
    print("common mass scale k, against k = 1 (the stiff pusher as shipped):")
    ref = rest(1.0, physics)
    for k in (1.001, 1.01, 1.1, 1.5, 2.0, 3.0, 10.0):
        print(f"  k = {k:6.3f}: {moved(rest(k, physics), ref)}")
    variants = {
        "as shipped": (physics, None),
        "pusher 100x heavier (10^6 kg)": (replace(physics, pusher_mass=1e6), None),
        "pusher 100x lighter (100 kg)": (replace(physics, pusher_mass=1e2), None),
        "solver tolerance 1e-14, 1000 iterations": (physics, tight_solver),
        "no torsional / rolling friction": (physics, no_torsion),
        "stiffer contacts (solref 2 ms, solimp .99)": (physics, stiff_contacts),
    }
    print("k = 3 against k = 1, with one term changed:")
    for name, (p, adjust) in variants.items():
        print(f"  {name:45s} {moved(rest(3.0, p, adjust), rest(1.0, p, adjust))}")
    print("random chains of the 2link-0.1-1 ranges and random pushes, against k = 1:")
    rng = np.random.default_rng(0)
    for pusher_mass, change in ((1e4, "k = 3"), (1e6, "k = 3"), (1e6, "joint + 1e-6 rad")):
        p = replace(physics, pusher_mass=pusher_mass)
        angles = []
        for _ in range(200):
            chain = sample_chain(physics, rng)
            pins = {"masses": list(chain.masses), "friction": chain.friction,
                    "lengths": list(chain.lengths), "joint_angles": list(chain.joint_angles),
                    "root_pose": list(chain.root_pose)}  # fmt: skip
            action = rng.uniform(-1, 1, 2)
            if change == "k = 3":
                a = rest(3.0, p, pins=pins, action=action)
            else:  # the chaos baseline: a change far below any measurement
                nudged = {**pins, "joint_angles": [q + 1e-6 for q in pins["joint_angles"]]}
                a = rest(1.0, p, pins=nudged, action=action)
            b = rest(1.0, p, pins=pins, action=action)
            if a is not None and b is not None:
                d = a - b
                angles.append(np.abs(wrap_angle(d[2:])).max())
        angles = np.array(angles)
        print(
            f"  pusher {pusher_mass:.0e} kg, {change}: {len(angles)} pushes, largest angle "
            f"change: median {np.median(angles):.2e}, "
            f"90th percentile {np.quantile(angles, 0.9):.2e}, "
            f"max {angles.max():.3f} rad; over 0.01 rad: {np.mean(angles > 0.01):.1%}"
        )


if __name__ == "__main__":
    main()
