"""Does a push on a stickier table say less about how a chain's mass is shared?

Over six target-world labs the three with the stickiest tables sorted the paper's close
pairs of classes worst (docs/notebook/2026-12-07-lab-12.md). This probe asks the training
world's physics directly, with the idealised stiff pusher (no arm, no governor): for each
table friction, the same start poses and pushes (speeds in the stationary UR10's band) are
given to both objects of each close pair, and each push's rest poses are compared in units
of their scatter: the first object pushed again `--jitters` times from a start pose and with
an action jittered by the sensing and actuation noise (`EnvConfig.obs_noise`,
`action_noise`), as the particle filter scales its likelihood. Since the table's friction
is unknown to an estimator, the second object is also pushed at frictions a little apart
(`--friction-spread`), and the nearest of its rest poses counts: what one push tells the
two objects apart by when friction may take up some of the difference.

Prints, per friction and pair, the median and mean of the per-push separation d (distance
over scatter) with and without the friction allowance, the median scatter and the median
distance the chain's root moved; then, per pair, on how many of the same pushes the
separation with the friction allowance was larger at the first friction than at each other
(exact two-sided sign test).

    python experiments/sim2real/friction_information.py --frictions 0.5,0.75,1.0 --pushes 40
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from masspush.config import EnvConfig
from masspush.real import PAPER_CLASSES, sign_test
from masspush.settings import get_setting
from masspush.sim import ChainSim, sample_chain, wrap_angle

# The paper's close pairs: first-link shares 0.25 / 0.20 and 0.75 / 0.80.
PAIRS = (("0.064-0.192", "0.064-0.256"), ("0.192-0.064", "0.256-0.064"))
SPEEDS = (0.5, 2.0)  # m/s: the stationary UR10's band (docs/notebook/2026-12-01-arm-speed.md)


def rest_pose(physics, chain, masses, friction, action) -> np.ndarray | None:
    """The chain's configuration at rest after the push, or None if the push failed."""
    sim = ChainSim(replace(chain, masses=tuple(float(m) for m in masses), friction=friction),
                   physics)  # fmt: skip
    if sim.initial_failure is not None:
        return None
    outcome = sim.push(action)
    return None if outcome.failure is not None else sim.config()


def distance(a: np.ndarray, b: np.ndarray) -> float:
    """Distance between two configurations (m and rad, angles wrapped)."""
    diff = a - b
    diff[2:] = wrap_angle(diff[2:])
    return float(np.linalg.norm(diff))


def jittered(chain, action: np.ndarray, rng: np.random.Generator, env: EnvConfig):
    """The chain seen from a start pose and pushed with an action jittered by the noise."""
    pose = np.array([*chain.root_pose, *chain.joint_angles])
    pose += rng.normal(0, env.obs_noise, pose.shape)
    shaken = replace(chain, root_pose=tuple(pose[:3]), joint_angles=tuple(pose[3:]))
    return shaken, np.clip(action + rng.normal(0, env.action_noise, 2), -1, 1)


def main() -> None:
    sys.path.insert(0, str(Path(__file__).parent))  # the sibling probe's option parsing
    from sticky_table_pushes import numbers

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--setting", default="real-ur10")
    parser.add_argument("--frictions", default="0.5,0.75,1.0",
                        help="comma-separated table frictions (default 0.5,0.75,1.0)")  # fmt: skip
    parser.add_argument("--pushes", type=int, default=40, help="start poses and pushes each")
    parser.add_argument("--friction-spread", type=float, default=0.1,
                        help="the second object also at friction x (1 +- this) and (1 +- half "
                        "of it); default 0.1")  # fmt: skip
    parser.add_argument("--jitters", type=int, default=4,
                        help="jittered pushes for each push's scatter (default 4)")  # fmt: skip
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    frictions = numbers(args.frictions, "--frictions", parser)
    if args.pushes < 1:
        parser.error("--pushes must be >= 1")
    if args.jitters < 2:
        parser.error("--jitters must be >= 2")
    if args.seed < 0:
        parser.error(f"--seed must be >= 0, got {args.seed}")
    if not 0 <= args.friction_spread < 1:
        parser.error(f"--friction-spread must be in [0, 1), got {args.friction_spread}")
    try:
        physics = get_setting(args.setting).physics()
    except (KeyError, ValueError) as err:
        parser.error(f"--setting: {err}")
    env = EnvConfig()
    spread = args.friction_spread
    factors = sorted({1.0, 1 - spread, 1 - spread / 2, 1 + spread / 2, 1 + spread})
    rng = np.random.default_rng(args.seed)
    draws = []
    for _ in range(args.pushes):
        chain = sample_chain(physics, rng)
        speed = rng.uniform(*SPEEDS)
        a1 = rng.choice([-1, 1]) * speed / physics.push_speed_max
        draws.append((chain, np.array([a1, rng.uniform(-1, 1)])))
    print(f"{args.setting}, stiff pusher, {args.pushes} pushes a friction, speeds "
          f"{SPEEDS[0]}-{SPEEDS[1]} m/s, {args.jitters} jitters; the second object also at "
          f"friction x {factors}")  # fmt: skip
    print("| friction | pair | pushes | d, same friction: median / mean | d, nearest friction: "
          "median / mean | scatter (median) | root moved (median, m) |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    jobs = [(f, pair) for f in frictions for pair in PAIRS]
    per_push: dict[tuple, np.ndarray] = {}  # (friction, pair): each push's d, nearest friction
    for friction, (first, second) in tqdm(jobs, desc="frictions and pairs", leave=False):
        same, nearest, scatter, moved = [], [], [], []
        jitter_rng = np.random.default_rng([args.seed, 1])
        per_push[friction, first] = np.full(len(draws), np.nan)
        for i, (chain, action) in enumerate(draws):
            a = rest_pose(physics, chain, PAPER_CLASSES[first], friction, action)
            others = {k: rest_pose(physics, chain, PAPER_CLASSES[second], friction * k, action)
                      for k in factors}  # fmt: skip
            shaken = []
            for _ in range(args.jitters):
                seen, pushed = jittered(chain, action, jitter_rng, env)
                shaken.append(rest_pose(physics, seen, PAPER_CLASSES[first], friction, pushed))
            if a is None or any(o is None for o in [*others.values(), *shaken]):
                continue
            scale = float(np.sqrt(np.mean([distance(j, a) ** 2 for j in shaken])))
            scatter.append(scale)
            same.append(distance(a, others[1.0]) / scale)
            nearest.append(min(distance(a, o) for o in others.values()) / scale)
            per_push[friction, first][i] = nearest[-1]
            moved.append(float(np.linalg.norm(a[:2] - np.asarray(chain.root_pose[:2]))))
        if not same:
            print(f"| {friction} | {first} / {second} | 0 | - | - | - | - |")
            continue
        print(f"| {friction} | {first} / {second} | {len(same)} "
              f"| {np.median(same):.2f} / {np.mean(same):.2f} "
              f"| {np.median(nearest):.2f} / {np.mean(nearest):.2f} "
              f"| {np.median(scatter):.4f} | {np.median(moved):.3f} |")  # fmt: skip

    print(f"\nThe same pushes, d with the friction allowance at {frictions[0]} against each "
          "other friction:")  # fmt: skip
    for first, second in PAIRS:
        for friction in frictions[1:]:
            low, other = per_push[frictions[0], first], per_push[friction, first]
            both = np.isfinite(low) & np.isfinite(other)
            wins = int(np.sum(low[both] > other[both]))
            losses = int(np.sum(low[both] < other[both]))
            p = sign_test(wins, losses)
            print(f"  {first} / {second}, {frictions[0]} against {friction}: larger on "
                  f"{wins} of {wins + losses} pushes, p = {p:.2g}")  # fmt: skip


if __name__ == "__main__":
    main()
