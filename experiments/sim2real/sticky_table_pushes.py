"""How far does a push carry a chain on a sticky table, with the stationary UR10 and with
the stiff pusher, and how much of that does the tool's friction take?

In the training world's own physics the particle filter sorted lab 12's chains at 98.7 %
after 16 pushes on a table of friction 0.75 and at 72.0 % on one of 0.993
(docs/notebook/2026-12-07-sticky-tables.md). This probe pushes the same random chains (the
setting's, lengths `--lengths` if given) with the same random pushes (speeds in the
stationary UR10's band, any contact point) at each table friction, with each pusher and
each tool friction (`PhysicsConfig.tool_friction`; the link-tool contact takes the larger of
it and `link_friction`, which is set to the smaller of the two so that the tool's counts),
and prints the distance the chain's first link moved (median and mean), the peak speed it
reached, and the tool's contact force's downward part over its horizontal part, averaged
over the contact (the stiff pusher moves only horizontally; an arm's tip sinks a little,
and its friction then presses the link onto the table).

    python experiments/sim2real/sticky_table_pushes.py [--frictions 0.5,0.75,1.0]
        [--tool-frictions 1.0,0.5] [--pushers stiff,ur10-stationary] [--pushes 40]
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import mujoco
import numpy as np
from tqdm import tqdm

from masspush.real import PAPER_CLASSES
from masspush.settings import get_setting
from masspush.sim import PUSHER_KINDS, ChainSim, make_pusher, sample_chain

SPEEDS = (0.5, 2.0)  # m/s: the stationary UR10's band (docs/notebook/2026-12-01-arm-speed.md)
CLASS = "0.064-0.192"  # a paper class: a light first link, the objects that slide farthest


def numbers(text: str, name: str, parser: argparse.ArgumentParser) -> list[float]:
    """Comma-separated positive numbers, or a one-line error naming the option."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        parser.error(f"{name}: comma-separated numbers, got {text!r}")
    if not all(np.isfinite(v) and v > 0 for v in values):
        parser.error(f"{name} must all be positive, got {text!r}")
    return values


def push_once(physics, chain, pusher: str, action: np.ndarray) -> tuple[float, float, float]:
    """One push: how far the first link moved (m), its peak speed (m/s), and the tool's
    mean downward force over its mean horizontal force while in contact (nan if the push
    failed)."""
    made = make_pusher(pusher)
    sim = ChainSim(chain, physics, made)
    if sim.initial_failure is not None:
        return (np.nan,) * 3
    model, data = sim.model, sim.data
    tool = model.geom(made.tool).id
    peak, down, across = [0.0], [], []
    force = np.zeros(6)

    def watch() -> None:
        peak[0] = max(peak[0], float(np.linalg.norm(data.qvel[:2])))
        on_tool = np.zeros(3)
        for i in range(data.ncon):
            contact = data.contact[i]
            if tool in (contact.geom1, contact.geom2):
                mujoco.mj_contactForce(model, data, i, force)
                on_tool += contact.frame.reshape(3, 3).T @ force[:3]
        if on_tool.any():
            down.append(abs(on_tool[2]))
            across.append(float(np.linalg.norm(on_tool[:2])))

    sim.on_step = watch
    start = sim.config()[:2].copy()
    if sim.push(action).failure is not None:
        return (np.nan,) * 3
    ratio = float(np.mean(down) / np.mean(across)) if across else np.nan
    return float(np.linalg.norm(sim.config()[:2] - start)), peak[0], ratio


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--setting", default="real-ur10")
    parser.add_argument("--frictions", default="0.5,0.75,1.0", help="table frictions")
    parser.add_argument("--tool-frictions", default="1.0,0.5",
                        help="the tool's (1.0: as every shipped model was trained)")  # fmt: skip
    parser.add_argument("--pushers", default="stiff,ur10-stationary")
    parser.add_argument("--pushes", type=int, default=40, help="chains, one push each")
    parser.add_argument("--lengths", default=None, help="the links' lengths, m, comma-separated")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    frictions = numbers(args.frictions, "--frictions", parser)
    tools = numbers(args.tool_frictions, "--tool-frictions", parser)
    pushers = args.pushers.split(",")
    unknown = sorted(set(pushers) - set(PUSHER_KINDS))
    if unknown:
        parser.error(f"--pushers: unknown {unknown}; known: {', '.join(PUSHER_KINDS)}")
    if args.pushes < 1:
        parser.error("--pushes must be >= 1")
    if args.seed < 0:
        parser.error(f"--seed must be >= 0, got {args.seed}")
    try:
        physics = get_setting(args.setting).physics()
    except (KeyError, ValueError) as err:
        parser.error(f"--setting: {err}")
    pins = {"masses": list(PAPER_CLASSES[CLASS])}
    if args.lengths is not None:
        pins["lengths"] = numbers(args.lengths, "--lengths", parser)
        if len(pins["lengths"]) != physics.n_links:
            parser.error(f"--lengths: {physics.n_links} lengths, got {args.lengths!r}")
    rng = np.random.default_rng(args.seed)
    draws = []
    for _ in range(args.pushes):
        chain = sample_chain(physics, rng, pins, allow_out_of_range=True)
        a1 = rng.choice([-1, 1]) * rng.uniform(*SPEEDS) / physics.push_speed_max
        draws.append((chain, np.array([a1, rng.uniform(-1, 1)])))
    print(f"{args.setting}, class {CLASS}, {args.pushes} chains with one random push each "
          f"(speeds {SPEEDS[0]}-{SPEEDS[1]} m/s), seed {args.seed}")  # fmt: skip
    print("| pusher | tool friction | table friction | pushes | first link moved, median / "
          "mean (m) | peak speed, median (m/s) | tool force down / across |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    jobs = [(p, t, f) for p in pushers for t in tools for f in frictions]
    for pusher, tool, friction in tqdm(jobs, desc="pushers and frictions", leave=False):
        world = replace(physics, tool_friction=tool, link_friction=min(physics.link_friction, tool))
        rows = np.array([push_once(world, replace(chain, friction=friction), pusher, action)
                         for chain, action in draws])  # fmt: skip
        rows = rows[np.isfinite(rows[:, 0])]
        if not len(rows):
            print(f"| {pusher} | {tool:g} | {friction:g} | 0 | - | - | - |")
            continue
        print(f"| {pusher} | {tool:g} | {friction:g} | {len(rows)} "
              f"| {np.median(rows[:, 0]):.3f} / {np.mean(rows[:, 0]):.3f} "
              f"| {np.median(rows[:, 1]):.2f} | {np.nanmean(rows[:, 2]):.2f} |",
              flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
