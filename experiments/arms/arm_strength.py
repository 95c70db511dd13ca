"""How much of the KUKA cells' gap is the arm's strength (issue 27, item 4)?

Our KR 5 model's torque limits are estimates (KUKA publishes none; docs/arms.md), and with
them the tip tops out near 2.6 m/s where the policy asks for up to 5. This measures, for
the shipped TP+ policy's first pushes on fresh chains, what a stronger arm (every joint's
torque limit scaled) and the stiff pusher make of the same push:

- the tip speed reached and how far the chain's root slides;
- the signal: how far the rest pose moves when a twentieth of the chain's mass is moved
  from its first link to its last (the total unchanged), without noise;
- the noise: the spread of the rest pose under the setting's action noise, with its
  observation noise added (in quadrature: both blur what the predictor sees);
- their ratio, for the root's position and for the angles (yaw and joints): how well one
  push tells two mass distributions apart.

The arm's top speed is set by how far its torques can accelerate the tip before contact
(v^2 = 2 a d: the speed goes as the square root of the torque scale), so `--placements`
also measures the arm as it is, its base farther back and its run-up longer
(`BASE:RUN_UP`, metres; ours 0.60:0.08, the farthest the KR 5 reaches, docs/arms.md).

    python experiments/arms/arm_strength.py [--setting 2link-0.1-1] [--chains 40] \
        [--placements 0.64:0.13]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Callable

import mujoco
import numpy as np

from masspush.data import EVAL, run_episodes
from masspush.models import model_and_policy
from masspush.settings import get_setting
from masspush.sim import ArmPusher, ChainSim, make_pusher, pusher_kind, wrap_angle

SHIFT = 0.05
"""Share of the chain's mass moved from its first link to its last for the signal."""


def stronger(scale: float) -> Callable[[mujoco.MjModel], None]:
    """An `adjust` for ChainSim: every torque-limited joint and its motor `scale` times as
    strong (the law reads its limits from the model)."""

    def adjust(model: mujoco.MjModel) -> None:
        model.jnt_actfrcrange[model.jnt_actfrclimited.astype(bool)] *= scale
        model.actuator_ctrlrange[model.actuator_ctrllimited.astype(bool)] *= scale

    return adjust


def placed(arm: str, base: float, run_up: float) -> Callable[[], ArmPusher]:
    """A factory of `arm` with its base `base` m behind the contact and a run-up of at most
    `run_up` m (the push's 30 ms at its speed, as in the package)."""

    def make() -> ArmPusher:
        pusher = ArmPusher(arm)
        pusher.arm = dataclasses.replace(pusher.arm, base_distance=base, max_standoff=run_up)
        return pusher

    return make


def parse_placements(text: str) -> list[tuple[float, float]]:
    """'0.64:0.13,0.66:0.15' -> [(0.64, 0.13), (0.66, 0.15)]; ValueError naming the bad one."""
    pairs = []
    for item in filter(None, text.split(",")):
        try:
            base, run_up = (float(v) for v in item.split(":"))
        except ValueError:
            raise ValueError(f"--placements takes BASE:RUN_UP pairs, got {item!r}") from None
        if not (0 < run_up < base < 2):
            raise ValueError(f"--placements needs 0 < RUN_UP < BASE < 2 m, got {item!r}")
        pairs.append((base, run_up))
    return pairs


def shifted(masses: np.ndarray) -> np.ndarray | None:
    """The same total with SHIFT of it moved from the first link to the last (None where
    the first link is too light for it)."""
    total = masses.sum()
    shares = masses / total
    if shares[0] <= SHIFT + 0.02:
        return None
    shares = shares.copy()
    shares[0] -= SHIFT
    shares[-1] += SHIFT
    return shares * total


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--setting", default="2link-0.1-1")
    parser.add_argument("--chains", type=int, default=40, help="fresh chains (first pushes)")
    parser.add_argument("--repeats", type=int, default=6, help="noisy repeats of each push")
    parser.add_argument("--scales", default="1,1.5,2,3", help="torque-limit scales of the arm")
    parser.add_argument(
        "--placements", default="", help="extra arms at x1: BASE:RUN_UP pairs in metres"
    )
    parser.add_argument("--seed", type=int, default=4243)
    args = parser.parse_args(argv)
    try:
        scales = [float(s) for s in args.scales.split(",")]
    except ValueError:
        sys.exit(f"error: --scales must be numbers separated by commas, got {args.scales!r}")
    try:
        placements = parse_placements(args.placements)
    except ValueError as err:
        sys.exit(f"error: {err}")
    if args.chains < 1 or args.repeats < 2 or min(scales) <= 0:
        sys.exit("error: --chains >= 1, --repeats >= 2 and scales > 0 are required")
    try:
        setting = get_setting(args.setting)
        _, _, policy = model_and_policy("tp+", setting.name)
    except (OSError, ValueError) as err:
        sys.exit(f"error: {' '.join(str(err).split())}")
    env_config = setting.env_config()
    if not pusher_kind(env_config.pusher).arm:
        sys.exit(f"error: {setting.name} is pushed by {env_config.pusher!r}, not an arm")
    physics = env_config.physics
    fresh = run_episodes(env_config, policy, np.arange(3 * args.chains), EVAL, args.seed)
    picked = [e for e in np.flatnonzero(fresh.ok) if shifted(fresh.masses[e]) is not None]
    picked = picked[: args.chains]
    arm = env_config.pusher
    variants = [(f"{arm} x{s:g}", lambda: make_pusher(arm), stronger(s)) for s in scales]
    variants += [
        (f"{arm} x1, base {b:g} m, run-up {r:g} m", placed(arm, b, r), None) for b, r in placements
    ]
    variants.append(("stiff", lambda: make_pusher("stiff"), None))
    rng = np.random.default_rng(args.seed)
    noise = rng.normal(0, env_config.action_noise, (len(picked), args.repeats, 2))
    obs = env_config.obs_noise
    print(f"{setting.name}: {len(picked)} chains, the TP+ policy's first pushes "
          f"(asked {5 * np.abs(fresh.executed[picked, 0, 0]).mean():.2f} m/s on average), "
          f"{args.repeats} noisy repeats, observation noise {obs}")  # fmt: skip
    print(
        "| pusher | tip speed (m/s) | root slides (mm) | signal xy (mm) / angles (mrad) "
        "| noise xy (mm) / angles (mrad) | signal / noise: xy, angles (median) | failed |"
    )
    print("|---|---|---|---|---|---|---|")
    for label, make, adjust in variants:
        pusher = make()
        speed, slide, sig, spread, snr = [], [], [], [], []
        failed: dict[str, int] = {}
        for k, e in enumerate(picked):
            action = fresh.executed[e, 0].astype(float)
            ends = []
            for masses, a in [(None, action), (shifted(fresh.masses[e]), action)] + [
                (None, np.clip(action + n, -1, 1)) for n in noise[k]
            ]:
                sim = ChainSim(fresh.chain(e, masses), physics, pusher, adjust)
                start = sim.config()
                outcome = sim.push(a)
                if outcome.failure is not None:
                    failed[outcome.failure] = failed.get(outcome.failure, 0) + 1
                    break
                if not ends:
                    speed.append(outcome.executed_speed)
                    slide.append(np.linalg.norm(sim.config()[:2] - start[:2]))
                ends.append(sim.config())
            if len(ends) < 2 + args.repeats:
                continue
            ends = np.array(ends)
            d = ends[1] - ends[0]
            d[2:] = wrap_angle(d[2:])
            s = np.array([np.linalg.norm(d[:2]), np.linalg.norm(d[2:])])
            jitter = ends[2:] - ends[0]
            jitter[:, 2:] = wrap_angle(jitter[:, 2:])  # angles about the noiseless push's
            n = np.array(
                [np.linalg.norm(jitter[:, :2].std(0)), np.linalg.norm(jitter[:, 2:].std(0))]
            )
            n = np.sqrt(n**2 + obs**2 * np.array([2, ends.shape[1] - 2]))
            sig.append(s)
            spread.append(n)
            snr.append(s / n)
        fails = ", ".join(f"{n} {why}" for why, n in sorted(failed.items())) or "0"
        if not snr:
            print(f"| {label} | | | | | | {fails} (of {len(picked)} chains) |")
            continue
        sig, spread, snr = np.array(sig), np.array(spread), np.array(snr)
        tip = f"{np.mean(speed):.2f}" if label != "stiff" else "as asked"
        print(f"| {label} | {tip} | {1000 * np.mean(slide):.0f} "
              f"| {1000 * sig[:, 0].mean():.1f} / {1000 * sig[:, 1].mean():.1f} "
              f"| {1000 * spread[:, 0].mean():.1f} / {1000 * spread[:, 1].mean():.1f} "
              f"| {np.median(snr[:, 0]):.2f}, {np.median(snr[:, 1]):.2f} | {fails} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
