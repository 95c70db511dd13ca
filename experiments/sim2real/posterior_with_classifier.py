"""Would the tuned density's class posterior and the protocol's classifier, added together,
sort a lab's chains better than either alone?

Both read the same pushes of a filter-arm recording (`masspush sim2real --learned-model
bayes`): the tuned density (`masspush tune-density`, made on other chains of the lab) gives
each episode's class log-posterior; the protocol's classifier gives class log-probabilities
from the filter's recorded estimate. Where their errors differ, their sum (a product of the
two posteriors, `--weight` on the classifier's) could sort more. The classifier is either

- `DENSITY=RECORDING`: cross-validated on the recording's own labels, as `sim2real` scores
  the protocol (5 folds, out-of-fold log-probabilities);
- `DENSITY=CALIBRATION=RECORDING`: trained on a labelled calibration recording of other
  chains (the density's own, say) and applied to the recording, as a lab would use it.

For each `--pushes` P it prints the three accuracies from each episode's first P pushes and
the exact McNemar test of the sum against the posterior, then each method's accuracy pooled
over the recordings. For docs/notebook/2026-12-07-lab-1.md:

    R=results/sim2real-bayes-placed
    python experiments/sim2real/posterior_with_classifier.py --pushes 2,32 \
        results/lab-tuned-density/lab1-seed1-32push.pt=$R/lab1-seed17-32push-20perclass/learned.jsonl
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from masspush.data import read_recording
from masspush.learn import load_push_density
from masspush.real import (
    ClassifierConfig,
    episode_log_probs,
    fit_classifier,
    labelled,
    out_of_fold_log_probs,
    paired_test,
    posterior_classes,
)


def calibrated_log_probs(
    calibration: np.ndarray, calibration_labels: np.ndarray, estimates: np.ndarray,
    n_classes: int, config: ClassifierConfig,
) -> np.ndarray:  # fmt: skip
    """Class log-probabilities (E, C) of the estimates by a classifier trained on the
    calibration's."""
    model = fit_classifier(np.log(calibration).astype(np.float32), calibration_labels,
                           n_classes, config)  # fmt: skip
    features = np.log(estimates).astype(np.float32)
    return episode_log_probs(model, features, np.arange(len(features)), len(features))


def estimates_after(recording, pushes: int, where: str) -> np.ndarray:
    """Each episode's recorded filter estimate after its first `pushes` pushes (or its last,
    for an episode that ended earlier)."""
    rows = []
    for episode in recording.episodes:
        if len(episode.get("estimates", ())) == 0:
            raise ValueError(f"{where}: episode {episode['id']} has no recorded estimates "
                             "(a filter-arm recording has them)")  # fmt: skip
        recorded = np.asarray(episode["estimates"], float)
        rows.append(recorded[min(pushes, len(recorded)) - 1])
    return np.array(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "pairs", nargs="+", metavar="DENSITY[=CALIBRATION]=RECORDING",
        help="a tuned density, optionally the labelled recording the classifier is trained "
        "on (else it is cross-validated on the recording), and a recording of other chains",
    )  # fmt: skip
    parser.add_argument("--pushes", default="2,32", help="comma-separated counts (default 2,32)")
    parser.add_argument("--weight", type=float, default=1.0,
                        help="the classifier's weight in the sum (default 1)")  # fmt: skip
    parser.add_argument("--seed", type=int, default=0, help="the classifier's folds and weights")
    args = parser.parse_args()
    try:
        counts = [int(p) for p in args.pushes.split(",")]
    except ValueError:
        parser.error(f"--pushes: comma-separated whole numbers, got {args.pushes!r}")
    if min(counts) < 1:
        parser.error("--pushes must all be >= 1")
    if not np.isfinite(args.weight) or args.weight < 0:
        parser.error(f"--weight must be a finite number >= 0, got {args.weight}")
    triples = []
    for pair in args.pairs:
        parts = pair.split("=")
        if len(parts) not in (2, 3) or not all(parts):
            parser.error(f"expected DENSITY=RECORDING or DENSITY=CALIBRATION=RECORDING, "
                         f"got {pair!r}")  # fmt: skip
        for path in parts:
            if not Path(path).is_file():
                parser.error(f"{path}: no such file")
        calibration = Path(parts[1]) if len(parts) == 3 else None
        triples.append((Path(parts[0]), calibration, Path(parts[-1])))
    config = ClassifierConfig(seed=args.seed)
    print("| recording | density | classifier trained on | pushes | episodes | tuned posterior "
          "| classifier | sum | only sum / only posterior right, p |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    # per count of pushes: each episode's truth and the three methods' answers
    pooled: dict[int, list[np.ndarray]] = {p: [] for p in counts}
    for density_path, calibration_path, path in triples:
        try:
            density = load_push_density(density_path)
            recording = read_recording(path)
            labels, classes = labelled(recording)
            calibration = None
            if calibration_path is not None:
                calibration = read_recording(calibration_path)
                calibration_labels, calibration_classes = labelled(calibration)
                if calibration_classes != classes:
                    raise ValueError(f"{calibration_path}: classes {calibration_classes}, "
                                     f"{path}: {classes}")  # fmt: skip
            for pushes in counts:
                order, log_post = posterior_classes(density, recording, str(path), pushes)
                # into the classifier's class order (the sorted labels)
                log_post = log_post[:, [order.index(c) for c in classes]]
                estimates = estimates_after(recording, pushes, str(path))
                if calibration is None:
                    log_probs = out_of_fold_log_probs(
                        np.log(estimates).astype(np.float32), labels, len(classes), config
                    )
                else:
                    log_probs = calibrated_log_probs(
                        estimates_after(calibration, pushes, str(calibration_path)),
                        calibration_labels, estimates, len(classes), config,
                    )  # fmt: skip
                both = (log_post + args.weight * log_probs).argmax(1)
                right = [log_post.argmax(1) == labels, log_probs.argmax(1) == labels,
                         both == labels]  # fmt: skip
                pooled[pushes].append(
                    np.stack([labels, log_post.argmax(1), log_probs.argmax(1), both])
                )
                test = paired_test(labels, both, log_post.argmax(1))
                trained = (
                    "(cross-validated)" if calibration is None else calibration_path.parent.name
                )
                print(f"| {path.parent.name} | {density_path.name} | {trained} | {pushes} "
                      f"| {len(labels)} | {100 * right[0].mean():.1f} % "
                      f"| {100 * right[1].mean():.1f} % | {100 * right[2].mean():.1f} % "
                      f"| {test['only_learned']} / {test['only_random']}, "
                      f"p = {test['p_value']:.2g} |")  # fmt: skip
        except (OSError, ValueError, KeyError) as err:
            sys.exit(f"error: {err}")
    for pushes, rows in pooled.items():
        truth, *answers = np.concatenate(rows, axis=1)
        test = paired_test(truth, answers[2], answers[0])
        post, clf, both = (100 * np.mean(a == truth) for a in answers)
        print(f"pooled, {pushes} pushes, {len(truth)} episodes: tuned posterior {post:.1f} %, "
              f"classifier {clf:.1f} %, sum {both:.1f} % (only sum / only posterior right "
              f"{test['only_learned']} / {test['only_random']}, "
              f"p = {test['p_value']:.2g})")  # fmt: skip


if __name__ == "__main__":
    main()
