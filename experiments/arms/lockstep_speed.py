"""Arms in lockstep on the batch path against one process per core (issue 27, item 2).

The same chains and random pushes three ways: the arm in lockstep (`ChainBatch`, MuJoCo's
threads), the arm one chain at a time in a process per core (`ChainSim`, the compiled law),
and the stiff pusher's batch; pushes per second of each, and whether the two arm paths end
in the same rest poses.

    python experiments/arms/lockstep_speed.py --links 2 --chains 200
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from masspush.config import PhysicsConfig
from masspush.sim import ChainBatch, ChainSim, make_pusher, pusher_kind, sample_chain


def one_at_a_time(args) -> tuple[np.ndarray, int]:
    arm, physics, chains, actions = args
    pusher = make_pusher(arm)
    configs, pushes = [], 0
    for chain, chain_actions in zip(chains, actions, strict=True):
        sim = ChainSim(chain, physics, pusher)
        for action in chain_actions:
            if sim.initial_failure is not None or sim.push(action).failure is not None:
                break
            pushes += 1
        configs.append(sim.config())
    return np.array(configs), pushes


def in_lockstep(pusher, physics, chains, actions) -> tuple[np.ndarray, int]:
    batch = ChainBatch(chains, physics, pusher=pusher)
    batch.failed[:] = batch.initial_failures_mask()
    pushes = 0
    for step in range(actions.shape[1]):
        pushes += sum(o is not None and o.failure is None for o in batch.push(actions[:, step]))
    return batch.configs(), pushes


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--links", type=int, default=2)
    parser.add_argument("--chains", type=int, default=200)
    parser.add_argument("--pushes", type=int, default=2, help="pushes per chain")
    parser.add_argument("--arm", default="kuka")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if args.links not in (2, 3) or args.chains < 2 or args.pushes < 1:
        sys.exit("error: --links must be 2 or 3, --chains at least 2, --pushes at least 1")
    try:
        if not pusher_kind(args.arm).arm:
            sys.exit(f"error: --arm must be an arm, not {args.arm!r}")
    except ValueError as err:
        sys.exit(f"error: --arm: {err}")
    physics = PhysicsConfig(n_links=args.links, mass_range=(0.1, 1.0))
    rng = np.random.default_rng(args.seed)
    chains = [sample_chain(physics, rng) for _ in range(args.chains)]
    actions = rng.uniform(-1, 1, (args.chains, args.pushes, 2))

    rates = {}
    start = time.perf_counter()
    lockstep, pushes = in_lockstep(args.arm, physics, chains, actions)
    rates["arm, lockstep"] = pushes / (time.perf_counter() - start)
    workers = os.cpu_count() or 1
    parts = np.array_split(np.arange(args.chains), workers)
    jobs = [(args.arm, physics, [chains[i] for i in p], actions[p]) for p in parts]
    start = time.perf_counter()
    with ProcessPoolExecutor(workers) as pool:
        results = list(pool.map(one_at_a_time, jobs))
    rates[f"arm, {workers} processes"] = sum(r[1] for r in results) / (time.perf_counter() - start)
    start = time.perf_counter()
    _, pushes = in_lockstep("stiff", physics, chains, actions)
    rates["stiff pusher, batch"] = pushes / (time.perf_counter() - start)
    separate = np.concatenate([r[0] for r in results])
    for name, rate in rates.items():
        print(f"{name}: {rate:.1f} pushes/s")
    same = np.array_equal(lockstep, separate, equal_nan=True)
    print(f"same rest poses in lockstep and one at a time: {same}")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
