"""Does another classifier, or another feature, sort a filter arm's episodes better?

Issue 28's protocol classifies each episode from the particle filter's estimate (its log
shares, `masspush sim2real --learned-model bayes`), with the paper's small MLP
cross-validated on the labelled episodes. With two links the estimate is one number, the
first link's share. For a filter arm's recording this compares, after 1, 2, 4 and 16 pushes
(an episode lost earlier read from the pushes it has), the protocol's MLP with class-
conditional Gaussians on the log-share ratio (one variance for all classes, and one per
class), with the Gaussians given the estimate after the first push too, and (with
`--density`) with the filter's class log-posteriors as features: the five classes' masses as
hypotheses, each at 8 frictions, weighed with the density as the class oracle does
(`class_oracle.py`). It prints each class's mean and spread of the estimated share, which
says what any classifier of one number can do.

    python experiments/sim2real/filter_features.py RUN/learned.jsonl [...] \\
        [--density src/masspush/models/real-ur10/push-density.pt]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import masspush.bayes as bayes
from masspush.data import read_recording
from masspush.learn import density_for
from masspush.real import ClassifierConfig, cross_validate, labelled, stratified_folds
from masspush.settings import get_setting

PUSHES = (1, 2, 4, 16)


def gaussian_cv(x: np.ndarray, labels: np.ndarray, k: int, folds: int, pooled: bool) -> float:
    """Cross-validated accuracy of class-conditional Gaussians on the rows of `x` (the
    protocol's folds); `pooled`: one covariance for all classes (linear discriminant)."""
    x = x.reshape(len(x), -1)
    d = x.shape[1]
    guess = np.zeros(len(labels), int)
    for test in stratified_folds(labels, folds, 0):
        train = np.setdiff1d(np.arange(len(labels)), test)
        xs, ys = x[train], labels[train]
        centred = np.vstack([xs[ys == c] - xs[ys == c].mean(0) for c in range(k)])
        shared = np.cov(centred.T).reshape(d, d)
        scores = []
        for c in range(k):
            xc = xs[ys == c]
            cov = shared if pooled else np.cov(xc.T).reshape(d, d) + 1e-6 * np.eye(d)
            diff = x[test] - xc.mean(0)
            maha = np.einsum("ij,jk,ik->i", diff, np.linalg.inv(cov), diff)
            scores.append(-0.5 * maha - 0.5 * np.linalg.slogdet(cov)[1])
        guess[test] = np.argmax(scores, 0)
    return float(np.mean(guess == labels))


def class_log_posteriors(recording, setting, classes, density) -> np.ndarray:
    """Each episode's log posterior of the classes after all its pushes (floored at -30)."""
    hypotheses = bayes.hypothesis_filter(
        setting, classes, bayes.friction_grid(setting, 8), None, density=density
    )
    rows = []
    try:
        for place, episode in enumerate(recording.episodes):
            hypotheses.reset(episode["lengths"], episode=place)
            hypotheses.filter.replay(episode["observations"], episode["actions"])
            rows.append(np.log(np.maximum(hypotheses.weights(), 1e-300)))
    finally:
        hypotheses.close()
    rows = np.array(rows)
    return np.maximum(rows - rows.max(axis=1, keepdims=True), -30)


def first_pushes(recording, pushes: int) -> object:
    """The recording cut to each episode's first `pushes` pushes."""
    for episode in recording.episodes:
        episode["actions"] = episode["actions"][:pushes]
        episode["observations"] = episode["observations"][: pushes + 1]
    return recording


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recordings", nargs="+", help="filter arms' recordings (learned.jsonl)")
    parser.add_argument("--density", help="also score the class log-posteriors under it")
    args = parser.parse_args()
    for path in map(Path, args.recordings):
        if not path.is_file():
            parser.error(f"recording: no such file {path}")
    config = ClassifierConfig()
    for path in map(Path, args.recordings):
        try:
            recording = read_recording(path)
            estimates = [np.asarray(e["estimates"], float) for e in recording.episodes]
        except (KeyError, ValueError) as err:
            parser.error(f"recording {path}: {err} (a filter arm's recording has estimates)")
        labels, names = labelled(recording)
        k = len(names)
        print(f"{path}: {len(labels)} episodes, classes {', '.join(names)}")
        print(
            "| pushes | protocol's MLP | Gaussians, pooled | per class | per class, + 1st push "
            "| class log-posteriors | estimate + log-posteriors | share by class (mean/sd) |"
        )
        print("|---|---|---|---|---|---|---|---|")
        setting = get_setting(recording.setting)
        density = None if args.density is None else density_for(args.density,
                                                                 setting.env_config())  # fmt: skip
        masses = {e["label"]: e["masses"] for e in recording.episodes}
        classes = [np.array(masses[name], float) for name in names]
        for p in PUSHES:
            logs = np.log([r[min(p, len(r)) - 1] for r in estimates])
            ratio = logs[:, 0] - logs[:, 1]
            first = np.log([r[0] for r in estimates])
            both = np.column_stack([ratio, first[:, 0] - first[:, 1]])
            cells = [
                cross_validate(logs, labels, k, config)["accuracy"],
                gaussian_cv(ratio, labels, k, config.folds, pooled=True),
                gaussian_cv(ratio, labels, k, config.folds, pooled=False),
                gaussian_cv(both, labels, k, config.folds, pooled=False),
            ]
            if density is not None:
                posts = class_log_posteriors(first_pushes(read_recording(path), p), setting,
                                             classes, density)  # fmt: skip
                cells.append(cross_validate(posts, labels, k, config)["accuracy"])
                cells.append(cross_validate(np.hstack([logs, posts]), labels, k,
                                            config)["accuracy"])  # fmt: skip
            else:
                cells += [float("nan")] * 2
            share = np.exp(logs[:, 0]) / np.exp(logs).sum(axis=1)
            spread = " ".join(
                f"{share[labels == c].mean():.3f}/{share[labels == c].std():.3f}" for c in range(k)
            )
            text = " | ".join("-" if np.isnan(c) else f"{100 * c:.1f} %" for c in cells)
            print(f"| {p} | {text} | {spread} |")


if __name__ == "__main__":
    main()
