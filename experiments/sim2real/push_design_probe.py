"""Which pushes survive the sim-to-real gap? A probe for issue 6 (docs/notebook, "Sim-to-real").

For each push design (the learned policy, random pushes, or a fixed sequence of actions) it
1. collects episodes of that design in worlds drawn at random (`WorldRanges`, as
   `masspush randomise` does), as the robot sees them;
2. trains a predictor from scratch on them (the recipe's first predictor, fewer steps);
3. runs the paper's protocol in the target world with that design (30 episodes per mass
   class, the seeds `masspush sim2real` uses) and cross-validates the classifier on the
   new predictor's estimate, printing link 1's share per class (mean +- std) and accuracy.

A design whose estimate spreads less within a class in the target world is the pushing a
policy trained in randomised worlds should learn. Work files (episodes, predictors) go to
--work and are reused by a rerun.

    python experiments/sim2real/push_design_probe.py --designs tp+ strong-centres   # ~5 min a
    design
"""

from __future__ import annotations

import argparse
import json
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

from masspush.data import Episodes, RandomPolicy
from masspush.real import PAPER_CLASSES, ClassifierConfig, cross_validate, predictor_features

SETTING = "real-ur10-4push"


def _fixed(a1: float, a2s: tuple[float, ...], sides: tuple[int, ...] = (1, 1, -1, -1)):
    return tuple((s * a1, a2) for s, a2 in zip(sides, a2s, strict=True))


DESIGNS = {
    "gentle-centres": _fixed(0.2, (-0.5, 0.5, -0.5, 0.5)),
    "medium-centres": _fixed(0.4, (-0.5, 0.5, -0.5, 0.5)),
    "strong-centres": _fixed(0.7, (-0.5, 0.5, -0.5, 0.5)),
    "fastest-centres": _fixed(1.0, (-0.5, 0.5, -0.5, 0.5)),
    "strong-link1": _fixed(0.7, (-0.5, -0.5, -0.5, -0.5)),
    "strong-link2": _fixed(0.7, (0.5, 0.5, 0.5, 0.5)),
    "strong-off-centre": _fixed(0.7, (-0.75, 0.75, -0.75, 0.75)),
    "gentle-ends": _fixed(0.2, (-0.9, 0.9, -0.9, 0.9)),
    "gentle-link2": _fixed(0.2, (0.5, 0.5, 0.5, 0.5)),
    "medium-joint": _fixed(0.4, (-0.1, 0.1, -0.1, 0.1)),
}
"""Fixed sequences of the four actions (a1, a2) [ours]: a1's sign alternates the side in
pairs so that the chain stays near where it started."""


class FixedPolicy:
    """The same sequence of actions in every episode (the robot adds its actuation noise)."""

    name = "fixed"

    def __init__(self, actions):
        self.actions = np.asarray(actions, np.float32)

    def reset(self, seeds: np.ndarray) -> None:
        self.n = len(seeds)

    def act(self, observations, actions, step, lengths) -> np.ndarray:
        return np.repeat(self.actions[step][None], self.n, axis=0)


def make_policy(design: str):
    """None: the learned model's own policy."""
    if design == "tp+":
        return None
    if design == "random":
        return RandomPolicy()
    return FixedPolicy(DESIGNS[design])


def _collect_job(args) -> Episodes:
    import torch

    from masspush.models import resolve_model
    from masspush.real import WorldRanges, run_randomised

    torch.set_num_threads(1)
    design, indices, base_seed = args
    return run_randomised(SETTING, resolve_model("tp+", SETTING), WorldRanges(), indices,
                          base_seed, policy=make_policy(design))  # fmt: skip


def collect(design: str, episodes: int, path: Path, workers: int) -> Episodes:
    from masspush.data import read_shard, write_shard

    if path.exists():
        return read_shard(path)
    chunks = np.array_split(np.arange(episodes), 8 * workers)
    with ProcessPoolExecutor(workers) as pool:
        parts = list(pool.map(_collect_job, [(design, c, 70_000_000) for c in chunks]))
    out = Episodes.concatenate(parts)
    write_shard(path, out)
    return out


def target_episodes(design: str, predictor, per_class: int):
    """The paper's protocol in the target world with this design; seeds as `sim2real`."""
    from masspush.models import model_and_policy
    from masspush.real import Sim2RealConfig, record_classes

    policy = make_policy(design) or model_and_policy("tp+", SETTING)[2]
    config = Sim2RealConfig(setting=SETTING, episodes_per_class=per_class)
    recording, _, _ = record_classes(config, predictor, policy, "probe", progress=False)
    labels = np.array([list(PAPER_CLASSES).index(label) for label in recording.labels])
    return recording.to_episodes(), labels


def probe(design: str, args) -> dict:
    from masspush.learn import PREDICTOR, MassPredictor, train_predictor
    from masspush.metrics import percentage_error

    work = Path(args.work) / design
    work.mkdir(parents=True, exist_ok=True)
    data = collect(design, args.episodes, work / "episodes.npz", args.workers)
    predictor, summary = train_predictor(
        data, work / "predictor", replace(PREDICTOR, steps=args.steps, eval_every=1000),
        {"probe": design}, progress=False,
    )  # fmt: skip
    assert isinstance(predictor, MassPredictor)
    episodes, labels = target_episodes(design, predictor, args.per_class)
    features = predictor_features(predictor, episodes, "estimate")
    scores = cross_validate(features, labels, len(PAPER_CLASSES), ClassifierConfig())
    share = np.exp(features[:, 0])
    per_class = [(float(share[labels == c].mean()), float(share[labels == c].std()))
                 for c in range(len(PAPER_CLASSES))]  # fmt: skip
    return {
        "design": design,
        "randomised_validation_error": float(summary["best_validation_error"]),
        "target_error": float(percentage_error(np.exp(features), episodes.mass_distribution)),
        "accuracy": float(scores["accuracy"]),
        "share": per_class,
        "failed_randomised": int((~data.ok).sum()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--designs", nargs="+", default=["tp+", "random", *DESIGNS])
    parser.add_argument("--episodes", type=int, default=3000,
                        help="randomised-world episodes per design")  # fmt: skip
    parser.add_argument("--steps", type=int, default=8000, help="predictor training steps")
    parser.add_argument("--per-class", type=int, default=30)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--work", default="/tmp/push-design-probe")
    parser.add_argument("--out", help="append each design's result to this JSON-lines file")
    args = parser.parse_args()
    classes = list(PAPER_CLASSES)
    print("| design | accuracy | error, target | error, randomised (val.) | "
          + " | ".join(classes) + " |")  # fmt: skip
    print("|---" * (4 + len(classes)) + "|")
    for design in args.designs:
        r = probe(design, args)
        cells = " | ".join(f"{m:.3f} +- {s:.3f}" for m, s in r["share"])
        print(f"| {design} | {100 * r['accuracy']:.1f} % | {r['target_error']:.2f} | "
              f"{r['randomised_validation_error']:.2f} | {cells} |", flush=True)  # fmt: skip
        if args.out:
            with open(args.out, "a") as f:
                f.write(json.dumps(r) + "\n")


if __name__ == "__main__":
    main()
