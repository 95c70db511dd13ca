"""The recipe's last stage at other sizes: does TP+ gain from more of the final policy's data?

The recipe's TP+ is predictor-M fine-tuned on `final_episodes` rollouts of the deterministic
policy-M (docs/training.md). This script collects `--extra` more of those rollouts beside a
finished run (in `<run>/data-final-extra`, resumable, seeds of their own), fine-tunes
predictor-M on data-final (its first `--final`) plus the first `--use` of them with
`--steps` steps, and scores each on the recipe's evaluation episodes (the run's seed) and on
`--fresh-seed` ones, beside the run's TP+:

    python experiments/recipe/final_stage.py --run runs/2link-0.1-1-kuka-train \\
        --final 16000 --extra 112000 --use 0,16000,48000,112000 --steps 5000,20000,40000
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

from masspush.data import Episodes, collect, load_dataset
from masspush.evaluate import evaluate
from masspush.learn import FINETUNE, LearnedPolicy, PredictorEstimator, load_model, train_predictor
from masspush.settings import get_setting

# Seed stream of the extra rollouts: the recipe's streams are 0..M+1 (docs/reproduce.md).
EXTRA_STREAM = 500


def ints(name: str, text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",")]
    except ValueError:
        raise ValueError(
            f"{name} must be a comma-separated list of integers, got {text!r}"
        ) from None
    if any(v < 0 for v in values):
        raise ValueError(f"{name}: negative value in {text!r}")
    return values


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", required=True, help="a finished recipe's run directory")
    parser.add_argument("--final", type=int, help="use the first this many of data-final")
    parser.add_argument("--extra", type=int, default=48_000, help="extra final rollouts")
    parser.add_argument("--use", default="0,16000,48000", help="extra rollouts used, a list")
    parser.add_argument("--steps", default="5000,20000", help="fine-tuning steps, a list")
    parser.add_argument("--eval-episodes", type=int, default=800)
    parser.add_argument("--fresh-seed", type=int, default=31)
    args = parser.parse_args(argv)
    run = Path(args.run)
    try:
        state = json.loads((run / "state.json").read_text())
        config = state["config"]
        setting = get_setting(config["setting"]["name"])
        m = int(config["meta_iterations"])
        uses, steps = ints("--use", args.use), ints("--steps", args.steps)
        if max(uses) > args.extra or min(steps) < 1 or args.eval_episodes < 1:
            raise ValueError("--use must not exceed --extra; --steps and --eval-episodes >= 1")
        if "predictor-final" not in state["timings"]:
            raise ValueError(f"{run} has not finished its recipe")
        if args.final is not None and args.final < 2:
            raise ValueError(f"--final must be >= 2, got {args.final}")
        _, final = load_dataset(run / "data-final", limit=args.final)
    except (OSError, KeyError, ValueError) as err:
        sys.exit(f"error: {' '.join(str(err).split())}")

    pusher, algo = config["pusher"], config["policy"]["algo"]
    policy = LearnedPolicy(run / f"policy-{m}" / "policy.zip", algo, True, pusher)
    extra_dir, extra = run / "data-final-extra", None
    if args.extra:
        collect(setting, extra_dir, episodes=args.extra, pusher=pusher, policy=policy,
                base_seed=1000 * config["seed"] + EXTRA_STREAM)  # fmt: skip
        extra = load_dataset(extra_dir)[1]
    start = run / f"predictor-{m}" / "predictor.pt"
    # predictor-M's record names its policy as TP+'s does; a redone final stage may be absent.
    meta = json.loads((run / f"predictor-{m}" / "config.json").read_text())["meta"]
    meta["recipe_stage"] = "final-stage experiment"
    tp_plus = run / "predictor-final"
    rows = []
    if (tp_plus / "predictor.pt").exists():
        record = json.loads((tp_plus / "config.json").read_text())
        trained_on = record["meta"]["dataset_episodes"]
        rows.append(("run's TP+", trained_on, record["train"]["steps"], tp_plus))
    for use in uses:
        data = (
            Episodes.concatenate([final, extra.select(extra.index < use)])
            if extra is not None and use
            else final
        )
        for n in steps:
            out = run / f"final-stage/final{len(final)}-extra{use}-steps{n}"
            train = replace(FINETUNE, steps=n, eval_every=n, checkpoint_every=n)
            meta_here = {**meta, "policy_file": f"../../policy-{m}/policy.zip",
                         "dataset_episodes": len(data)}  # fmt: skip
            train_predictor(data, out, train, meta_here, init=load_model(start)[0])
            rows.append((f"+{use} extra, {n} steps", len(data), n, out))
    print(f"{'predictor':28s} {'episodes':>9s} {'steps':>6s} {'recipe eval':>12s} {'fresh':>8s}")
    for name, episodes, n, out in rows:
        estimator = PredictorEstimator.from_file(out / "predictor.pt", setting.name)
        recipe = evaluate(setting, estimator, args.eval_episodes, config["seed"])
        fresh = evaluate(setting, estimator, args.eval_episodes, args.fresh_seed)
        print(f"{name:28s} {episodes:9d} {n:6d} {recipe.percentage_error:12.2f} "
              f"{fresh.percentage_error:8.2f}", flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
