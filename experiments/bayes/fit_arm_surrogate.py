"""Which stiff push reproduces an arm's push best? The fit behind `bayes.ARM_SURROGATE`.

    python experiments/bayes/fit_arm_surrogate.py [--setting 2link-0.1-1] [--arm kuka] [--pushes
    150]
        [--max-push 0.15] [--scales 0.5,0.6,0.7,0.8,1.0] [--holds 0.01] [--ramps 0,0.005]

Pushes `--pushes` random chains of the setting once each with the arm, without noise, at
random actions with |a1| <= max-push, then pushes the same chains from the same start poses
on the batch path with a stiff pusher of speed scale x hold time x ramp time, and prints the
RMS and median difference of the rest poses per component (root x, y in m; yaw and joints
in rad). The particle filter's likelihood simulates the best row where that arm pushes.
"""

import argparse
import itertools
from dataclasses import replace

import numpy as np
from tqdm import tqdm

from masspush.bayes import ARM_MAX_PUSH, config_difference
from masspush.env import ChainEnv
from masspush.settings import get_setting
from masspush.sim import ChainBatch, ChainParams


def arm_pushes(setting, arm: str, pushes: int, max_push: float, seed: int = 0) -> list[tuple]:
    env = ChainEnv.from_config(setting.env_config(arm, obs_noise=0, action_noise=0))
    rng = np.random.default_rng(seed)
    rows = []
    for i in tqdm(range(pushes), desc=f"{arm} pushes"):
        _, info = env.reset(seed=10_000 + i)
        if info["failure"] is not None:
            continue
        action = rng.uniform(-1, 1, 2) * (max_push, 1.0)
        start = info["config"]
        _, _, _, _, after = env.step(action.astype(np.float32))
        if after["failure"] is None:
            rows.append((info["masses"], info["friction"], info["lengths"], start, action,
                         after["config"]))  # fmt: skip
    return rows


def stiff_difference(physics, rows: list[tuple]) -> tuple[np.ndarray, np.ndarray, float]:
    chains = [
        ChainParams(tuple(map(float, m)), float(mu), tuple(map(float, lengths)),
                    tuple(float(v) for v in start[3:]), tuple(float(v) for v in start[:3]))
        for m, mu, lengths, start, _, _ in rows
    ]  # fmt: skip
    batch = ChainBatch(chains, physics, 0)
    outcomes = batch.push(np.array([row[4] for row in rows]))
    ok = np.array([o is not None and o.failure is None for o in outcomes])
    diff = config_difference(batch.configs(), np.array([row[5] for row in rows]))[ok]
    return np.sqrt(np.mean(diff**2, axis=0)), np.median(np.abs(diff), axis=0), float(ok.mean())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--setting", default="2link-0.1-1")
    parser.add_argument("--arm", default="kuka")
    parser.add_argument("--pushes", type=int, default=150)
    parser.add_argument("--max-push", type=float, default=ARM_MAX_PUSH)
    parser.add_argument("--scales", default="0.5,0.6,0.7,0.8,1.0")
    parser.add_argument("--holds", default="0.01")
    parser.add_argument("--ramps", default="0,0.005")
    args = parser.parse_args()
    setting = get_setting(args.setting)
    rows = arm_pushes(setting, args.arm, args.pushes, args.max_push)
    print(f"{len(rows)} {args.arm} pushes on {setting.name}, |a1| <= {args.max_push}")
    print("| speed scale | hold s | ramp s | RMS difference | median difference | stiff ok |")
    print("|---|---|---|---|---|---|")
    grid = itertools.product(*(map(float, v.split(",")) for v in (args.scales, args.holds,
                                                                   args.ramps)))  # fmt: skip
    base = setting.physics()
    for scale, hold, ramp in grid:
        physics = replace(base, push_speed_max=scale * base.push_speed_max,
                          push_hold_time=hold, push_ramp_time=ramp)  # fmt: skip
        rms, median, ok = stiff_difference(physics, rows)
        print(f"| {scale} | {hold} | {ramp} | {np.round(rms, 3).tolist()} "
              f"| {np.round(median, 3).tolist()} | {ok:.2f} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
