"""Would moving the dividing line between the paper's close classes sort more chains?

Over runs the particle-filter arm's errors fall within the two close pairs of the paper's
classes (first-link share 0.25 / 0.20 and 0.75 / 0.80;
docs/notebook/2026-12-05-runs-gap.md), and they are not always even: a lab's object may
answer like a lighter or heavier one, so that the tuned posterior takes one class of a pair
for the other more often than the reverse. An estimator told each object's own answer
(effective class masses, a class prior) could only move the line between the two. Under the
equal-variance Gaussian model of signal detection, a pair's two hit rates h1, h2 give its
separation d' = z(h1) + z(h2), whatever the line; the line in the middle sorts Phi(d'/2) of
each class, the most any line can. Given `masspush sim2real` run directories whose
summaries hold the tuned posterior's confusion (`--tuned-density`), this prints per run and
pooled: each pair's errors either way, its d', the errors with the line in the middle, and
the accuracy over all five classes as run and with both lines in the middle. Hit rates are
(hits + 0.5) / (n + 1) (the log-linear correction [Hautus 1995], so that a pair sorted
without error still has a finite d'); on a few dozen chains the model's middle can come out
above the errors counted, which says only that no gain is to be had there.

    python experiments/sim2real/close_pairs.py results/sim2real-bayes-placed/lab6-seed*-32push-*
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from statistics import NormalDist

import numpy as np

from masspush.real import PAPER_CLASSES, read_summary

# The close pairs by class name (link masses, kg): first-link share 0.25 / 0.20, 0.75 / 0.80.
PAIRS = (("0.064-0.192", "0.064-0.256"), ("0.192-0.064", "0.256-0.064"))
NORMAL = NormalDist()


def confusion(run: Path) -> tuple[np.ndarray, list[str], int]:
    """The learned arm's tuned-posterior confusion, its classes and pushes per episode."""
    summary = read_summary(run)
    try:
        posterior = summary["arms"]["learned"]["posterior"]
        pushes = 2 * int(summary["config"]["segments"])
        return np.array(posterior["confusion"], int), list(posterior["classes"]), pushes
    except (KeyError, TypeError):
        raise ValueError(
            f"{run}: no tuned-posterior confusion for the learned arm (run with --tuned-density)"
        ) from None


def pair_row(c: np.ndarray, i: int, j: int) -> tuple[int, int, float, float]:
    """(errors i -> j, errors j -> i, d', errors with the line in the middle) of one pair,
    counted within the pair (episodes sorted to a third class are left as they are)."""
    ni, nj = c[i, i] + c[i, j], c[j, j] + c[j, i]
    hit_i = (c[i, i] + 0.5) / (ni + 1)  # the log-linear correction: no rate of 0 or 1
    hit_j = (c[j, j] + 0.5) / (nj + 1)
    d = NORMAL.inv_cdf(hit_i) + NORMAL.inv_cdf(hit_j)
    middle = (ni + nj) * NORMAL.cdf(-d / 2)
    return int(c[i, j]), int(c[j, i]), d, float(middle)


def rows(name: str, c: np.ndarray, classes: list[str], pushes: int | str) -> str:
    total, right = int(c.sum()), int(np.trace(c))
    cells, gained = [], 0.0
    for a, b in PAIRS:
        i, j = classes.index(a), classes.index(b)
        there, back, d, middle = pair_row(c, i, j)
        cells.append(f"{there} / {back} | {d:.2f} | {middle:.1f}")
        gained += there + back - middle
    return (f"| {name} | {pushes} | {total} | {' | '.join(cells)} | {100 * right / total:.1f} % "
            f"| {100 * (right + gained) / total:.1f} % |")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="sim2real output directories")
    args = parser.parse_args(argv)
    read = []
    for run in args.runs:
        try:
            c, classes, pushes = confusion(run)
        except ValueError as err:
            parser.error(str(err))
        if sorted(classes) != sorted(PAPER_CLASSES) or c.shape != (len(classes),) * 2:
            parser.error(f"{run}: not the paper's five classes")
        read.append((run.name, c, classes, pushes))
    print(
        "| run | pushes | chains | 0.25 -> 0.20 / back | d' | errors, line in the middle "
        "| 0.75 -> 0.80 / back | d' | errors, line in the middle | accuracy | both lines "
        "in the middle |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, c, classes, pushes in read:
        print(rows(name, c, classes, pushes))
    if len(read) > 1:
        order = read[0][2]
        pooled = sum(
            c[np.ix_([cl.index(k) for k in order], [cl.index(k) for k in order])]
            for _, c, cl, _ in read
        )
        lengths = sorted({p for *_, p in read})
        print(rows(f"pooled ({len(read)} runs)", pooled, order, "/".join(map(str, lengths))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
