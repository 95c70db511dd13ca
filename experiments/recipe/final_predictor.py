"""How TP+'s predictor is trained on a run's data-final: from scratch or from predictor-M, at
which learning rate, and whether a wider network than the paper's does better.

Holds out the same 5 % of data-final as the recipe's predictor-final (`TrainConfig`'s
split, seed 0), so its validation figures compare with the recipe's; prints the error on
them and on 6,000 training episodes every `--every` steps. Adam, batches of 256, the
learning rate halved at 1/4, 1/2 and 3/4 of the steps (as `TrainConfig`).

    python experiments/recipe/final_predictor.py --run runs/3link-0.1-1-kuka-train \
        --steps 40000 --lr 3e-3 [--init 6] [--extra 5,6] [--wide 256] [--seeds 0,1,2]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import torch

from masspush.data import load_dataset
from masspush.learn import (
    LOSSES,
    MassPredictor,
    TrainConfig,
    load_model,
    step_inputs,
    validation_split,
)
from masspush.metrics import percentage_error


def inputs(directory: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    _, episodes = load_dataset(directory)
    good = episodes.select(episodes.ok)
    q0, steps = step_inputs(good, "relative")
    return q0, steps, good.mass_distribution.astype(np.float32)


def fit(
    args: argparse.Namespace, init: Path | None, data: tuple, split: tuple, seed: int
) -> np.ndarray:
    """Train one predictor; print its errors as it goes; return its held-out predictions
    at its best checkpoint (as the recipe keeps the best)."""
    q0, steps, target = data
    val, train = split
    schedule = TrainConfig(optimizer="adam", steps=args.steps, batch_size=256, lr=args.lr,
                           loss=args.loss, width=args.wide or None)  # fmt: skip
    torch.manual_seed(seed)
    n_links, q0_dim, step_dim = target.shape[1], q0.shape[1], steps.shape[2]
    model = MassPredictor(n_links, q0_dim, step_dim, "relative", schedule.width)
    if init is not None:
        model.load_state_dict(load_model(init)[0].state_dict())
    else:
        model.set_normaliser(q0[train].numpy(), steps[train].numpy())
    print(
        f"seed {seed}: {len(train)} training episodes, {len(val)} held out; "
        f"{sum(x.numel() for x in model.parameters()):,} parameters"
    )
    optimiser = torch.optim.Adam(model.parameters(), lr=args.lr)
    rng = np.random.default_rng(seed + 1)
    held, seen = torch.as_tensor(val), torch.as_tensor(train[:6000])
    best, best_pred = np.inf, None
    started = time.perf_counter()
    for step in range(1, args.steps + 1):
        for group in optimiser.param_groups:
            group["lr"] = schedule.lr_at(step - 1)
        batch = torch.as_tensor(rng.choice(train, size=schedule.batch_size))
        loss = LOSSES[schedule.loss](model(q0[batch], steps[batch]) - target[batch, None, :]).mean()
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        if step % args.every == 0 or step == args.steps:
            model.eval()
            with torch.no_grad():
                pred = model(q0[held], steps[held])[:, -1].numpy()
                fitted = model(q0[seen], steps[seen])[:, -1].numpy()
            model.train()
            error = percentage_error(pred, target[held].numpy())
            if error < best:
                best, best_pred = error, pred
            print(
                f"step {step:>6}  {time.perf_counter() - started:5.0f} s  held out "
                f"{error:.2f}  training {percentage_error(fitted, target[seen].numpy()):.2f}",
                flush=True,
            )
    return best_pred


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--run", type=Path, required=True, help="a recipe's run directory")
    p.add_argument("--steps", type=int, default=20_000)
    p.add_argument("--lr", type=float, default=3e-3)
    p.add_argument("--init", help="start from predictor-<INIT> of the run (default: scratch)")
    p.add_argument("--extra", default="", help="data-<i> to train on as well, e.g. 5,6")
    p.add_argument(
        "--wide",
        type=int,
        default=0,
        help="a predictor this wide (TrainConfig.width; 0: the paper's)",
    )
    p.add_argument("--every", type=int, default=5_000)
    p.add_argument("--loss", choices=tuple(LOSSES), default="mse", help="the training loss")
    p.add_argument(
        "--seeds", default="0", help="train one predictor per seed; with several, also "
        "score the mean of their held-out estimates (an ensemble)"
    )  # fmt: skip
    args = p.parse_args()
    extra = [s for s in args.extra.split(",") if s]
    dirs = [args.run / "data-final", *(args.run / f"data-{i}" for i in extra)]
    for d in dirs:
        if not (d / "manifest.json").exists():
            sys.exit(f"no dataset at {d}")
    init = args.run / f"predictor-{args.init}" / "predictor.pt" if args.init else None
    if init is not None and not init.exists():
        sys.exit(f"no predictor at {init}")
    if args.init and args.wide:
        sys.exit("--init starts from a recipe's predictor, which is not wide")
    if args.steps < 1 or args.every < 1 or not 0 < args.lr < 1:
        sys.exit("--steps and --every must be >= 1, --lr in (0, 1)")
    try:  # the width's bounds are TrainConfig's; checked before the episodes load
        TrainConfig(width=args.wide or None)
    except ValueError as err:
        sys.exit(f"--wide: {err}")
    try:
        seeds = [int(s) for s in args.seeds.split(",")]
    except ValueError:
        sys.exit(f"--seeds must be integers separated by commas, got {args.seeds!r}")

    parts = [inputs(d) for d in dirs]
    n_final = len(parts[0][0])
    val, train = validation_split(n_final, TrainConfig())  # the recipe's predictor-final's
    train = np.concatenate([train, np.arange(n_final, sum(len(q) for q, _, _ in parts))])
    data = tuple(torch.as_tensor(np.concatenate(x)) for x in zip(*parts, strict=True))
    truth = data[2][torch.as_tensor(val)].numpy()
    preds: list[np.ndarray] = []
    for seed in seeds:
        preds.append(fit(args, init, data, (val, train), seed))
        if len(preds) > 1:  # every prefix, so one run says what each further member buys
            singles = ", ".join(f"{percentage_error(x, truth):.2f}" for x in preds)
            print(
                f"ensemble of {len(preds)}: held out "
                f"{percentage_error(np.mean(preds, 0), truth):.2f} (each at its best: {singles})",
                flush=True,
            )


if __name__ == "__main__":
    main()
