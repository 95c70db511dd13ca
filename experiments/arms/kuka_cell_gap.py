"""Why the KUKA cells miss the paper's TP+ (issue 27, item 4): three of the candidates.

For a setting's shipped TP+ (default 2link-0.1-1, the KUKA):
1. capacity: the predictor's error on episodes it was trained on (a recipe's `data-final`)
   against fresh episodes of its own policy: a predictor too small for its task errs alike
   on both; one that only lacks data errs less on what it saw;
2. saturation: the speed the policy commands (5 |a1| m/s) against the tip speed the arm
   reaches, for the policy's pushes;
3. the arm's extra randomness: the same first push repeated with the setting's action noise
   (and nothing else), the spread of the rest poses it gives with the arm and with the stiff
   pusher, relative to how far the push moves the chain.

    python experiments/arms/kuka_cell_gap.py --data runs/2link-0.1-1-kuka-train/data-final
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from masspush.data import EVAL, load_dataset, run_episodes
from masspush.metrics import percentage_error
from masspush.models import model_and_policy
from masspush.settings import get_setting
from masspush.sim import ChainSim, make_pusher


def final_error(predictor, episodes) -> float:
    ok = episodes.ok
    estimates = predictor.predict(episodes.select(ok))[:, -1]
    return percentage_error(estimates, episodes.mass_distribution[ok])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--setting", default="2link-0.1-1")
    parser.add_argument("--data", help="the recipe's data-final (the TP+ predictor's training)")
    parser.add_argument("--episodes", type=int, default=200, help="fresh episodes of the policy")
    parser.add_argument("--repeats", type=int, default=6, help="noisy repeats of a first push")
    parser.add_argument("--seed", type=int, default=4242)
    args = parser.parse_args(argv)
    if args.episodes < 2 or args.repeats < 2:
        sys.exit("error: --episodes and --repeats must be at least 2")
    try:
        setting = get_setting(args.setting)
        predictor, _, policy = model_and_policy("tp+", setting.name)
        trained = load_dataset(args.data, limit=4000)[1] if args.data else None
    except (OSError, ValueError) as err:
        sys.exit(f"error: {' '.join(str(err).split())}")
    env_config = setting.env_config()
    fresh = run_episodes(env_config, policy, np.arange(args.episodes), EVAL, args.seed)
    print(
        f"1. TP+ error on {int(fresh.ok.sum())} fresh episodes: {final_error(predictor, fresh):.2f}"
    )
    if trained is not None:
        seen = trained
        print(f"   on {int(seen.ok.sum())} of its training episodes: "
              f"{final_error(predictor, seen):.2f}")  # fmt: skip

    asked = 5.0 * np.abs(fresh.executed[fresh.ok, :, 0]).ravel()
    physics = env_config.physics
    arm, stiff = make_pusher(env_config.pusher), make_pusher("stiff")
    reached, spreads = [], {env_config.pusher: [], "stiff": []}
    moved = {env_config.pusher: [], "stiff": []}
    rng = np.random.default_rng(args.seed)
    for e in np.flatnonzero(fresh.ok)[:60]:
        chain, action = fresh.chain(e), fresh.executed[e, 0].astype(float)
        for name, pusher in ((env_config.pusher, arm), ("stiff", stiff)):
            ends = []
            for r in range(args.repeats):
                sim = ChainSim(chain, physics, pusher)
                start = sim.config()
                noisy = action if r == 0 else np.clip(
                    action + rng.normal(0, env_config.action_noise, 2), -1, 1
                )  # fmt: skip
                outcome = sim.push(noisy)
                if outcome.failure is not None:
                    break
                if r == 0 and name == env_config.pusher:
                    reached.append((5 * abs(action[0]), outcome.executed_speed))
                ends.append(sim.config())
            if len(ends) == args.repeats:
                ends = np.array(ends)
                spreads[name].append(np.linalg.norm(ends[:, :2].std(0)))
                moved[name].append(np.linalg.norm(ends[0, :2] - start[:2]))
    reached = np.array(reached)
    print(f"2. commanded speed of the policy's pushes: mean {asked.mean():.2f} m/s, "
          f"{100 * np.mean(asked > 2.6):.0f} % above 2.6 m/s")  # fmt: skip
    print(f"   first pushes: commanded {reached[:, 0].mean():.2f} m/s, the arm's tip reached "
          f"{reached[:, 1].mean():.2f} m/s (max {reached[:, 1].max():.2f})")  # fmt: skip
    for name in spreads:
        s, m = np.array(spreads[name]), np.array(moved[name])
        print(f"3. {name}: the first link's root moves {1000 * m.mean():.0f} mm; under the "
              f"action noise it ends within {1000 * s.mean():.1f} mm RMS "
              f"({100 * np.mean(s / np.maximum(m, 1e-6)):.1f} % of the move), "
              f"{len(s)} pushes")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
