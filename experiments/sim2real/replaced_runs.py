"""What re-placing the chain between runs could give (issue 28): each run a first run.

If a lab put the chain back at a fresh start pose between runs of the policy, every run
would be a first run, the run the policy does best. A recording of single runs in one lab
(`masspush sim2real --lab L`: every episode of a class is the same object, placed anew)
already holds such runs: this classifies each episode out of fold (the protocol's
classifier, 5 folds), then adds the log-probabilities of R episodes of the same class drawn
at random, as the protocol adds those of an episode's runs, and reports the accuracy for
R = 1, 2, 4, 8.

    cd results/sim2real-governed-fit-lab/5
    python ../../../experiments/sim2real/replaced_runs.py learned.jsonl tp+
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from masspush.real import (
    ClassifierConfig,
    episode_log_probs,
    fit_classifier,
    labelled,
    predictor_features,
    read_with_predictor,
    stratified_folds,
)


def out_of_fold_log_probs(features, labels, n_classes, config) -> np.ndarray:
    """Each episode's class log-probabilities from a classifier that never saw it (the
    protocol's folds, `stratified_folds`)."""
    out = np.zeros((len(labels), n_classes))
    for test in stratified_folds(labels, config.folds, config.seed):
        train = np.ones(len(labels), bool)
        train[test] = False
        model = fit_classifier(features[train], labels[train], n_classes, config)
        out[test] = episode_log_probs(model, features[test], np.arange(len(test)), len(test))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "recording", help="a sim2real arm's recording (learned.jsonl, random.jsonl)"
    )
    parser.add_argument("model", help="the predictor it was recorded with (tp+, rp or a file)")
    parser.add_argument("--setting", default="real-ur10")
    parser.add_argument(
        "--allow-mismatch",
        action="store_true",
        help="read a recording of another setting (same links)",
    )
    parser.add_argument("--draws", type=int, default=200, help="random groups per class and R")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if args.draws < 1:
        sys.exit("error: --draws must be at least 1")
    try:
        recording, predictor, _, _ = read_with_predictor(
            args.recording, args.model, args.setting, args.allow_mismatch
        )
        labels, classes = labelled(recording)
    except (OSError, ValueError) as err:
        sys.exit(f"error: {' '.join(str(err).split())}")
    episodes = recording.to_episodes()
    rng = np.random.default_rng(args.seed)
    for kind in ("estimate", "lstm"):
        config = ClassifierConfig(features=kind)
        features = predictor_features(predictor, episodes, kind)
        log_probs = out_of_fold_log_probs(features, labels, len(classes), config)
        cells = []
        for runs in (1, 2, 4, 8):
            hits = [
                log_probs[rng.choice(np.flatnonzero(labels == c), runs, replace=False)]
                .sum(0)
                .argmax()
                == c
                for _ in range(args.draws)
                for c in range(len(classes))
                if (labels == c).sum() >= runs
            ]
            cells.append(f"{runs} runs: {100 * np.mean(hits):.1f} %")
        print(f"{kind} features: " + ", ".join(cells))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
