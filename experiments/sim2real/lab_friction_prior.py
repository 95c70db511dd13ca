"""Does one table friction for the whole lab, learned from its calibration episodes, sort the
lab's other chains better than a friction guessed afresh for each episode?

The tuned density's class posterior (`masspush classify --density`, `sim2real
--tuned-density`) marginalises the table's friction over a grid, uniformly and separately for
each episode. A lab has one table, and its calibration episodes (known masses) say which of
the grid's frictions the density finds there. This prints, per recording and number of
pushes, the accuracy of the class posterior with the uniform grid ("uniform"), with the
calibration's friction posterior as the prior of every episode ("lab": all calibration
episodes' likelihoods multiplied), and with the mean of its episodes' friction posteriors
("mixture", a softer prior). No label of a test recording is used. For
docs/notebook/2026-12-05-lab-tuned-density.md:

    python experiments/sim2real/lab_friction_prior.py --density TUNED.pt \\
        --calibration CALIBRATION.jsonl TEST.jsonl ...
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from masspush.data import read_recording
from masspush.learn import load_push_density
from masspush.real import (
    class_log_likelihoods,
    first_pushes,
    friction_grid,
    labelled_pushes,
    tuned_classes,
)


def friction_table(density, pushes, masses: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """(E, C, F) each episode's log-likelihood under each class at each friction of `grid`."""
    return np.stack(
        [class_log_likelihoods(density, pushes, masses, np.array([f])) for f in grid], axis=2
    )


def normalised(log_weights: np.ndarray) -> np.ndarray:
    return log_weights - np.logaddexp.reduce(log_weights)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recordings", nargs="+", type=Path)
    parser.add_argument("--density", required=True, type=Path, help="a tuned push density")
    parser.add_argument(
        "--calibration", required=True, type=Path,
        help="the lab's labelled episodes on other chains (any policy)",
    )  # fmt: skip
    parser.add_argument(
        "--pushes", default="2,4,16,all",
        help="comma-separated: each episode's first P pushes, or all",
    )  # fmt: skip
    args = parser.parse_args()
    try:
        counts = [None if p == "all" else int(p) for p in args.pushes.split(",")]
    except ValueError:
        parser.error(f"--pushes: integers or 'all', got {args.pushes!r}")
    if any(c is not None and c < 1 for c in counts):
        parser.error("--pushes must be >= 1")
    try:
        density = load_push_density(args.density)
        classes, masses = tuned_classes(density, str(args.density))
        for path in [args.calibration, *args.recordings]:
            if not path.is_file():
                raise ValueError(f"{path}: no such recording")
        recordings = {path: read_recording(path) for path in [args.calibration, *args.recordings]}
        for path, rec in recordings.items():
            unknown = sorted({str(x) for x in rec.labels} - set(classes))
            if unknown:
                raise ValueError(f"{path}: classes {unknown} not among {classes}")
        calibration = recordings[args.calibration]
    except (OSError, ValueError) as err:
        sys.exit(f"error: {err}")
    grid = friction_grid(density, density.meta["tuned"]["config"]["frictions"])
    truth = np.array([classes.index(str(x)) for x in calibration.labels])
    table = friction_table(density, labelled_pushes(calibration), masses, grid)
    own = table[np.arange(len(truth)), truth]  # (E, F) under each episode's true masses
    lab = normalised(own.sum(0))
    per_episode = own - np.logaddexp.reduce(own, axis=1, keepdims=True)
    mixture = normalised(np.log(np.exp(per_episode).mean(0) + 1e-12))
    print("frictions:", " ".join(f"{f:.3f}" for f in grid))
    print("lab prior:", " ".join(f"{p:.3f}" for p in np.exp(lab)))
    print("mixture:  ", " ".join(f"{p:.3f}" for p in np.exp(mixture)))
    print("| recording | pushes | uniform | lab | mixture |")
    print("|---|---|---|---|---|")
    priors = (np.zeros(len(grid)), lab, mixture)
    for path in args.recordings:
        rec = recordings[path]
        right = np.array([classes.index(str(x)) for x in rec.labels])
        pushes = labelled_pushes(rec)
        for count in counts:
            t = friction_table(density, first_pushes(pushes, count), masses, grid)
            acc = [np.mean(np.logaddexp.reduce(t + p, axis=2).argmax(1) == right) for p in priors]
            print(f"| {path} | {count or 'all'} | " + " | ".join(f"{100 * a:.1f} %" for a in acc)
                  + " |")  # fmt: skip


if __name__ == "__main__":
    main()
