"""Can the tuned density's class posterior be sharpened further with labels the protocol has?

A density tuned to a lab (`masspush tune-density`) sorts the lab's other chains by class
posterior. Its mistakes sit in the close pairs and lean one way (in lab 5 the heavier-link
class is taken for its lighter twin more often than the reverse), which suggests two cheap
mends, both measured here on recordings the density was not tuned on:

- **offsets**: a log-prior per class, fitted (cross-entropy) on the calibration recording's
  out-of-fold posteriors (the density tuned on the other folds, each episode's first P
  pushes), then added to every test episode's posterior: no label of the test recording used;
- **stacking**: the protocol's classifier (cross-validated on the test recording's own labels,
  as `sim2real` does) given the filter's last estimate and the five log-posteriors together.

For docs/notebook/2026-12-05-lab-tuned-density.md (lab 5, calibration seed 1):

    python experiments/sim2real/posterior_recalibration.py --pushes 2 \\
        --calibration results/sim2real-bayes-placed/lab5-seed1-16push-checked-fit16/learned.jsonl \\
        --density results/lab-tuned-density/lab5-seed1.pt \\
        results/lab-tuned-density/lab5-seed0-2push/learned.jsonl ...
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import torch

from masspush.data import read_recording
from masspush.learn import load_push_density
from masspush.models import shipped_density
from masspush.real import (
    ClassifierConfig,
    TuneConfig,
    cross_validate,
    cross_validate_tuning,
    labelled_pushes,
    posterior_classes,
    tuned_classes,
)


def out_of_fold(density, calibration: Path, untuned_path: Path, pushes: int | None) -> tuple:
    """The calibration episodes' class log-likelihoods (E, C) from their first `pushes`
    pushes, each under the density tuned (as the tuned file was) on the other folds."""
    classes, masses = tuned_classes(density, str(calibration))
    recording = read_recording(calibration)
    labels = np.array([classes.index(str(label)) for label in recording.labels])
    scores = cross_validate_tuning(
        load_push_density(untuned_path), labelled_pushes(recording), labels, masses,
        TuneConfig(**density.meta["tuned"]["config"]), progress=False, count=pushes,
    )  # fmt: skip
    return np.array(scores["log_likelihoods"]), labels


def fit_offsets(log_lik: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Per-class log-prior offsets minimising the cross-entropy of the posterior."""
    x = torch.as_tensor(log_lik - np.logaddexp.reduce(log_lik, axis=1, keepdims=True))
    offsets = torch.zeros(x.shape[1], dtype=x.dtype, requires_grad=True)
    optimiser = torch.optim.LBFGS([offsets], max_iter=200)

    def closure() -> torch.Tensor:
        optimiser.zero_grad()
        loss = torch.nn.functional.cross_entropy(x + offsets, torch.as_tensor(labels))
        loss.backward()
        return loss

    optimiser.step(closure)
    return offsets.detach().numpy()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recordings", nargs="+", type=Path, help="test recordings (filter arm)")
    parser.add_argument("--density", required=True, type=Path, help="the tuned density")
    parser.add_argument("--calibration", required=True, type=Path,
                        help="the recording it was tuned on")  # fmt: skip
    parser.add_argument("--pushes", type=int, default=None, help="each episode's first P")
    args = parser.parse_args()
    if args.pushes is not None and args.pushes < 1:
        parser.error("--pushes must be >= 1")
    try:
        density = load_push_density(args.density)
        tuned_classes(density, str(args.density))
        for path in [args.calibration, *args.recordings]:
            if not path.is_file():
                raise ValueError(f"{path}: no such recording")
        for path in args.recordings:  # validated before the minutes of tuning
            if not all(len(e.get("estimates", ())) for e in read_recording(path).episodes):
                raise ValueError(f"{path}: not every episode has the filter's estimates")
        untuned_path = shipped_density(density.meta["setting"])
        if load_push_density(untuned_path).digest() != density.meta["tuned"]["from_digest"]:
            raise ValueError(f"{args.density} was not tuned from the shipped density")
    except (OSError, ValueError) as err:
        sys.exit(f"error: {err}")
    log_lik, labels = out_of_fold(density, args.calibration, untuned_path, args.pushes)
    offsets = fit_offsets(log_lik, labels)
    print(f"calibration out of fold: {100 * np.mean(log_lik.argmax(1) == labels):.1f} %; "
          f"offsets {np.round(offsets, 2).tolist()}")  # fmt: skip
    print("| recording | tuned posterior | + offsets | classifier on the estimate "
          "| classifier on estimate and posterior |")  # fmt: skip
    print("|---|---|---|---|---|")
    config = ClassifierConfig()
    for path in args.recordings:
        recording = read_recording(path)
        classes, log_post = posterior_classes(density, recording, str(path), args.pushes)
        truth = np.array([classes.index(str(label)) for label in recording.labels])
        estimate = np.log(np.array([np.asarray(e["estimates"])[: args.pushes][-1]
                                    for e in recording.episodes]))  # fmt: skip
        alone = cross_validate(estimate.astype(np.float32), truth, len(classes), config)
        both = np.hstack([estimate, log_post]).astype(np.float32)
        stacked = cross_validate(both, truth, len(classes), config)
        print(
            f"| {path} | {100 * np.mean(log_post.argmax(1) == truth):.1f} % "
            f"| {100 * np.mean((log_post + offsets).argmax(1) == truth):.1f} % "
            f"| {100 * alone['accuracy']:.1f} % | {100 * stacked['accuracy']:.1f} % |"
        )


if __name__ == "__main__":
    main()
