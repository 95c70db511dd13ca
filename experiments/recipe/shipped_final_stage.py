"""A shipped TP+ given a larger final stage: more of its own policy's episodes, longer training.

The recipe's TP+ is predictor-M fine-tuned on the deterministic final policy's rollouts
(docs/training.md). The real settings' were trained small (8,000 final episodes for
`real-ur10`), and on the stationary UR10 the particle filter estimates far better from
pushes of the same robot (docs/notebook/2026-12-04-stationary-ur10-density.md). Does the
predictor gain from more data of its own policy? This script collects `--episodes`
rollouts of the shipped model's policy in the training world (in `--out`/data, resumable,
seeds of their own), fine-tunes the shipped predictor on the first `--use` of them with
each `--steps` (from scratch with `--scratch`, as many `--members` averaged), and scores
each, and the shipped one, on `--eval-episodes` fresh episodes of two seeds:

    python experiments/recipe/shipped_final_stage.py --setting real-ur10 --model tp+ \\
        --episodes 64000 --use 16000,64000 --steps 20000 --out runs/final-stage-real-ur10

Each predictor is left in `--out`/<name>/predictor.pt with its policy's file named in its
metadata (relative), so `masspush sim2real --learned-model FILE` runs the protocol with it.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from dataclasses import replace
from pathlib import Path

from masspush.data import collect, load_dataset
from masspush.evaluate import evaluate
from masspush.learn import FINETUNE, PredictorEstimator, train_ensemble, train_predictor
from masspush.models import model_and_policy, resolve_model
from masspush.settings import get_setting

# Seed stream of the rollouts: the recipe's streams are 0..M+1 and final_stage.py's 500
# (docs/reproduce.md); the evaluation episodes' seeds are set apart by evaluate().
STREAM = 700


def ints(name: str, text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",")]
    except ValueError:
        raise ValueError(f"{name} must be a list of integers, got {text!r}") from None
    if not values or any(v < 1 for v in values):
        raise ValueError(f"{name}: every value must be >= 1, got {text!r}")
    return values


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--setting", default="real-ur10")
    parser.add_argument("--model", default="tp+", help="shipped name or model file")
    parser.add_argument("--episodes", type=int, default=64_000, help="rollouts to collect")
    parser.add_argument("--use", default="64000", help="rollouts trained on, a list")
    parser.add_argument("--steps", default="20000", help="training steps, a list")
    parser.add_argument("--lr", type=float, default=3e-3, help="learning rate")
    parser.add_argument("--members", type=int, default=1, help="predictors averaged")
    parser.add_argument("--scratch", action="store_true", help="train from scratch")
    parser.add_argument("--out", default=None, help="run directory (resumable)")
    parser.add_argument("--eval-episodes", type=int, default=800)
    parser.add_argument("--seeds", default="31,32", help="evaluation seeds, a list")
    parser.add_argument("--workers", type=int, default=None)
    args = parser.parse_args(argv)
    try:
        setting = get_setting(args.setting)
        uses, steps = ints("--use", args.use), ints("--steps", args.steps)
        try:
            seeds = [int(s) for s in args.seeds.split(",")]
        except ValueError:
            raise ValueError(f"--seeds must be a list of integers, got {args.seeds!r}") from None
        if args.episodes < 2:
            raise ValueError(f"--episodes must be >= 2, got {args.episodes}")
        if max(uses) > args.episodes:
            raise ValueError("--use must not exceed --episodes")
        if args.eval_episodes < 1 or args.members < 1 or not 0 < args.lr < 1:
            raise ValueError("--eval-episodes and --members >= 1, --lr in (0, 1)")
        out = Path(args.out or f"runs/final-stage-{setting.name}")
        if out.exists() and not out.is_dir():
            raise ValueError(f"--out {out} is a file, not a run directory")
        # Each training's configuration, checked before any episode is collected.
        trains = {n: replace(FINETUNE, steps=n, lr=args.lr, eval_every=n,
                             checkpoint_every=max(1, n // 4)) for n in steps}  # fmt: skip
        source = resolve_model(args.model, setting.name)
        predictor, meta, policy = model_and_policy(source, setting.name)
    except ValueError as err:
        sys.exit(f"error: {' '.join(str(err).split())}")
    if meta.get("policy") != "learned":
        sys.exit(f"error: {source} was trained on random pushes; this is for a learned policy's")
    # The model's policy file beside the run, so that its predictors name it as shipped ones do.
    policy_file = out / Path(meta["policy_file"]).name
    out.mkdir(parents=True, exist_ok=True)
    if not policy_file.exists():
        shutil.copy(source.parent / meta["policy_file"], policy_file)
    pusher = meta.get("pusher", setting.pusher)
    collect(setting, out / "data", episodes=args.episodes, pusher=pusher, policy=policy,
            base_seed=STREAM, workers=args.workers)  # fmt: skip
    _, data = load_dataset(out / "data")
    rows = [(f"shipped {args.model}", meta.get("dataset_episodes", 0), 0, source)]
    for use in uses:
        for n in steps:
            kind = "scratch" if args.scratch else "tuned"
            name = f"{kind}-use{use}-steps{n}-lr{args.lr:g}" + (
                f"-x{args.members}" if args.members > 1 else ""
            )
            train = trains[n]
            here = {**meta, "policy_file": f"../{policy_file.name}", "dataset_episodes": use,
                    "recipe_stage": "shipped final-stage experiment"}  # fmt: skip
            init = None if args.scratch else predictor
            subset = data.select(data.index < use)
            if args.members > 1:
                train_ensemble(subset, out / name, train, args.members, here, init=init)
            else:
                train_predictor(subset, out / name, train, here, init=init)
            rows.append((name, use, n, out / name / "predictor.pt"))
    heads = " ".join(f"{'seed ' + str(s):>9s}" for s in seeds)
    print(f"{'predictor':36s} {'episodes':>9s} {'steps':>6s} {heads}")
    for name, episodes, n, path in rows:
        estimator = PredictorEstimator.from_file(path, setting.name)
        errors = [evaluate(setting, estimator, args.eval_episodes, s) for s in seeds]
        cells = " ".join(f"{e.percentage_error:9.2f}" for e in errors)
        print(f"{name:36s} {episodes:9d} {n:6d} {cells}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
