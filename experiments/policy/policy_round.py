"""One more round of the recipe for a setting's learned pipeline, with a chosen frozen predictor.

PPO trains a policy against `--predictor` (frozen; its reward) from scratch or from
`--init` (a policy file, e.g. a shipped model's), its episodes collected (`--episodes`,
deterministic policy, seeds of their own) and `--predictor` fine-tuned on them; the result is
scored on fresh episodes of two seeds and left in `--out`/predictor/predictor.pt with its
policy named in its metadata, so that `masspush sim2real --learned-model FILE` runs the
protocol with it. Resumable stage by stage. For
docs/notebook/2026-12-05-real-ur10-learned-pushes.md, e.g. a fresh single-run policy
against a predictor of 256,000 random episodes:

    python experiments/policy/policy_round.py --predictor runs/rp256k/predictor.pt \\
        --runs 1 --reward paper --steps 75000 --initial-action 0.4,-0.15 --log-std -1.0 \\
        --episodes 32000 --collect-seed 900 --out runs/ppo1-probe
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from masspush.data import collect, load_dataset
from masspush.evaluate import evaluate
from masspush.learn import (
    FINETUNE,
    LearnedPolicy,
    PolicyConfig,
    PredictorEstimator,
    load_model,
    train_policy,
    train_predictor,
)
from masspush.settings import get_setting


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--setting", default="real-ur10")
    parser.add_argument("--predictor", required=True, help="the frozen predictor (reward)")
    parser.add_argument("--init", help="a policy file to go on training (default: fresh)")
    parser.add_argument("--runs", type=int, default=1, help="runs per PPO episode")
    parser.add_argument("--reward", default="paper", help="paper or gain")
    parser.add_argument("--steps", type=int, default=75_000, help="PPO pushes")
    parser.add_argument("--envs", type=int, default=64, help="PPO's environments")
    parser.add_argument("--initial-action", default="0.5,0.5", help="a fresh policy's mean")
    parser.add_argument("--log-std", type=float, default=-1.5, help="a fresh policy's")
    parser.add_argument("--seed", type=int, default=0, help="PPO's seed")
    parser.add_argument("--episodes", type=int, default=64_000, help="rollouts collected")
    parser.add_argument("--collect-seed", type=int, default=900, help="their base seed")
    parser.add_argument("--finetune-steps", type=int, default=20_000)
    parser.add_argument("--out", required=True, help="run directory (resumable)")
    parser.add_argument("--workers", type=int, default=None)
    args = parser.parse_args(argv)
    try:
        setting = get_setting(args.setting)
        start, meta = load_model(args.predictor, setting.name)
        try:
            action = tuple(float(v) for v in args.initial_action.split(","))
        except ValueError:
            raise ValueError(
                f"--initial-action must be two numbers, got {args.initial_action!r}"
            ) from None
        config = PolicyConfig(
            algo="recurrent", n_envs=args.envs, steps=args.steps, runs=args.runs,
            reward=args.reward, seed=args.seed, log_std_init=args.log_std,
            initial_action=action,
        )  # fmt: skip
        if args.init is not None and not Path(args.init).is_file():
            raise ValueError(f"--init: no policy file at {args.init}")
        if args.episodes < 2 or args.finetune_steps < 1:
            raise ValueError("--episodes must be >= 2 and --finetune-steps >= 1")
        if Path(args.out).exists() and not Path(args.out).is_dir():
            raise ValueError(f"--out {args.out} is a file, not a run directory")
        n = args.finetune_steps
        train = replace(FINETUNE, steps=n, lr=3e-3, eval_every=n, checkpoint_every=max(1, n // 4))
    except (OSError, ValueError) as err:
        sys.exit(f"error: {' '.join(str(err).split())}")
    out = Path(args.out)
    pusher = meta.get("pusher") or setting.pusher
    env_config = setting.env_config(pusher)
    policy_file = train_policy(env_config, args.predictor, out / "policy", config, init=args.init)
    policy = LearnedPolicy(policy_file, "recurrent", True, pusher, runs=args.runs)
    collect(setting, out / "data", episodes=args.episodes, pusher=pusher, policy=policy,
            base_seed=args.collect_seed, workers=args.workers)  # fmt: skip
    _, data = load_dataset(out / "data")
    meta = {**meta, "policy": "learned", "policy_file": "../policy/policy.zip",
            "policy_algo": "recurrent", "pusher": pusher, "dataset_episodes": len(data),
            "recipe_stage": "policy_round experiment"}  # fmt: skip
    if args.runs > 1:
        meta["policy_runs"] = args.runs
    train_predictor(data, out / "predictor", train, meta, init=start)
    estimator = PredictorEstimator.from_file(out / "predictor" / "predictor.pt", setting.name)
    for seed in (31, 32):
        error = evaluate(setting, estimator, 800, seed).percentage_error
        print(f"evaluation seed {seed}: percentage error {error:.2f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
