"""How far apart are the classes' estimates, and how widely does each scatter?

For each recording of a `masspush sim2real` arm (its `estimates` after every good push, as a
particle-filter arm records them): per class, the mean and standard deviation of the first
link's estimated share of the mass after `--pushes` pushes and after all the episode has;
then, for the paper's two close pairs (shares 0.25 / 0.20 and 0.75 / 0.80, 0.05 apart), the
distance between the pair's means in units of their pooled standard deviation (d'): a
classifier that draws one line between two Gaussian classes sorts Phi(d' / 2) of them.
For docs/notebook/2026-12-05-runs-gap.md:

    python experiments/sim2real/class_estimates.py \\
        results/sim2real-filter-gap-parts/6/none-8runs.jsonl \\
        results/sim2real-filter-gap-parts/6/com_offset-8runs.jsonl
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from masspush.data import read_recording
from masspush.real import PAPER_CLASSES

PAIRS = (("0.064-0.192", "0.064-0.256"), ("0.256-0.064", "0.192-0.064"))
"""The paper's classes whose first link's shares lie 0.05 apart."""


def first_shares(recording, path: Path, pushes: int | None) -> dict[str, np.ndarray]:
    """Per class label, the first link's estimated share after `pushes` pushes (None: all
    the episode has; fewer where it has fewer) of each episode of `recording` (read from
    `path`) with an estimate."""
    shares: dict[str, list[float]] = {}
    for episode in recording.episodes:
        estimates = episode.get("estimates")
        if episode.get("label") is None or estimates is None or len(estimates) == 0:
            continue
        k = len(estimates) if pushes is None else min(pushes, len(estimates))
        shares.setdefault(episode["label"], []).append(float(estimates[k - 1][0]))
    if not shares:
        raise ValueError(f"{path}: no labelled episode with estimates")
    return {label: np.array(v) for label, v in shares.items()}


def rows(path: Path, pushes: int) -> list[str]:
    recording = read_recording(path)
    early, final = first_shares(recording, path, pushes), first_shares(recording, path, None)
    out = [str(path), "", f"| class | true share | after {pushes} pushes | after all |",
           "|---|---|---|---|"]  # fmt: skip
    for label in sorted(final):
        masses = PAPER_CLASSES.get(label)
        true = "-" if masses is None else f"{masses[0] / sum(masses):.2f}"
        out.append(f"| {label} | {true} | {early[label].mean():.3f} +- {early[label].std():.3f} "
                   f"| {final[label].mean():.3f} +- {final[label].std():.3f} |")  # fmt: skip
    out += ["", "| pair | apart after all | d' | one line sorts |", "|---|---|---|---|"]
    for a, b in PAIRS:
        if a in final and b in final:
            gap = final[a].mean() - final[b].mean()
            spread = math.sqrt((final[a].var() + final[b].var()) / 2)
            d = gap / spread if spread > 0 else math.inf
            sorted_share = 0.5 * (1 + math.erf(d / 2 / math.sqrt(2)))
            out.append(f"| {a} / {b} | {gap:+.3f} | {d:.2f} | {100 * sorted_share:.0f} % |")
    return [*out, ""]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recordings", nargs="+", type=Path)
    parser.add_argument("--pushes", type=int, default=2, help="the early reading (default 2)")
    args = parser.parse_args()
    if args.pushes < 1:
        parser.error("--pushes must be >= 1")
    try:
        for path in args.recordings:
            print("\n".join(rows(path, args.pushes)))
    except (OSError, ValueError) as err:
        sys.exit(f"error: {err}")


if __name__ == "__main__":
    main()
