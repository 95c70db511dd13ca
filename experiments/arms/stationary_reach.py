"""Where can the stationary UR10 push? The scan behind its workspace's bounds.

    python experiments/arms/stationary_reach.py [--pushes 600] [--seed 0]

Chains of the real setting (2 links, 0.01-0.3 kg) are placed at random over a ring around
the stationary UR10's base wider than its workspace (link centres 0.25-1.2 m from the base's
axis, bearings within +-80 degrees of the way it faces), each pushed once with a random
action by the UR10 standing where `ur10-stationary` stands. The table: per band of the
pushed link's distance and bearing, the pushes the arm could not make ('unreachable', or
'arm_contact': another part of the arm touched the chain). The workspace
(`masspush.sim.pushers.arm.ARMS["ur10-stationary"].workspace`) is the region where both
stay at zero. Used in docs/real-robot.md, "The workspace".
"""

import argparse
import itertools
import math
import time
from dataclasses import replace

import numpy as np

from masspush.config import PhysicsConfig
from masspush.sim import ChainSim, Workspace, link_poses, make_pusher, sample_chain

BANDS_R = (0.25, 0.35, 0.4, 0.5, 0.9, 1.0, 1.05, 1.1, 1.2)
BANDS_BEARING = (0.0, 0.6, 1.0, 1.2, 1.4)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--pushes", type=int, default=600)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    physics = PhysicsConfig(n_links=2, mass_range=(0.01, 0.3))
    pusher = make_pusher("ur10-stationary")
    workspace = pusher.workspace
    # Wider than the workspace, so that the scan sees past its edges.
    pusher.workspace = replace(workspace, r_min=0.2, r_max=1.3, max_bearing=math.radians(85))
    bx, by, byaw = workspace.base
    rng = np.random.default_rng(args.seed)
    rows = []
    start = time.perf_counter()
    for i in range(args.pushes):
        r, bearing = rng.uniform(0.25, 1.2), rng.uniform(-1.4, 1.4)
        x, y = bx + r * math.cos(byaw + bearing), by + r * math.sin(byaw + bearing)
        options = {"root_pose": (x, y, rng.uniform(-math.pi, math.pi))}
        chain = sample_chain(physics, rng, options)
        sim = ChainSim(chain, physics, pusher)
        if sim.initial_failure is not None:
            continue
        action = rng.uniform(-1, 1, 2)
        link = min(int(action[1] + 1), 1)
        centres, _ = link_poses(sim.config(), chain.lengths, physics.joint_gap)
        r_link, b_link = workspace.polar(centres[link])
        failure = sim.push(action).failure
        rows.append((float(r_link), abs(float(b_link)), failure))
        if (i + 1) % 100 == 0:
            print(f"{i + 1} pushes, {time.perf_counter() - start:.0f} s", flush=True)
    report(rows, workspace)


def report(rows, workspace: Workspace) -> None:
    r = np.array([row[0] for row in rows])
    b = np.array([row[1] for row in rows])
    arm = np.array([row[2] in ("unreachable", "arm_contact") for row in rows])
    print(f"\n{len(rows)} pushes; the workspace: r in [{workspace.r_min}, {workspace.r_max}] m, "
          f"|bearing| <= {workspace.max_bearing:.2f} rad")  # fmt: skip
    print("| distance (m) | " + " | ".join(
        f"bearing {lo:.1f}-{hi:.1f}" for lo, hi in itertools.pairwise(BANDS_BEARING)
    ) + " |")  # fmt: skip
    print("|---" * len(BANDS_BEARING) + "|")
    for lo, hi in itertools.pairwise(BANDS_R):
        cells = []
        for blo, bhi in itertools.pairwise(BANDS_BEARING):
            m = (r >= lo) & (r < hi) & (b >= blo) & (b < bhi)
            cells.append(f"{arm[m].sum()} / {m.sum()}" if m.any() else "-")
        print(f"| {lo:.2f}-{hi:.2f} | " + " | ".join(cells) + " |")
    inside = (r >= workspace.r_min) & (r <= workspace.r_max) & (b <= workspace.max_bearing)
    print(f"\ninside the workspace: {arm[inside].sum()} of {inside.sum()} pushes could not be "
          f"made; outside: {arm[~inside].sum()} of {(~inside).sum()}")  # fmt: skip


if __name__ == "__main__":
    main()
