"""Do two ways of running `masspush sim2real` differ on the same chains, arm by arm?

Two runs with the same setting, seed and classes push the same chains (paired by episode id)
however they differ otherwise (e.g. `--start-range`, which moves each chain but keeps its
masses, lengths and angles). Given pairs of run directories A B [A B ...], for each pair and
each arm in both: accuracy over the episodes attempted, the exact McNemar test on the
episodes both kept, and the mean speed the robot reported for each push (from the
recordings, where present); then every pair's episodes pooled, arm by arm. For
docs/notebook/2026-12-05-chain-placement.md:

    python experiments/sim2real/paired_runs.py results/sim2real-bayes-placed/training-spread \\
        results/sim2real-bayes-placed/training
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from masspush.data import read_recording
from masspush.real import paired_answers, paired_test, read_summary


def push_speeds(recording: Path) -> str:
    """Mean reported speed of each push (m/s), or a dash without the recording."""
    if not recording.is_file():
        return "-"
    episodes = read_recording(recording).episodes
    by_push: dict[int, list[float]] = {}
    for episode in episodes:
        speeds = episode.get("speeds")
        for k, speed in enumerate([] if speeds is None else speeds):
            by_push.setdefault(k, []).append(float(speed))
    return " / ".join(f"{np.mean(v):.2f}" for _, v in sorted(by_push.items())) or "-"


HEADER = ["| arm | model | A | B | only A right | only B right | McNemar p | push speeds A (m/s) "
          "| B |", "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip


def compare(a: Path, b: Path, pooled: dict[str, list]) -> list[str]:
    """One pair's rows; each arm's paired answers are added to `pooled`."""
    first, second = read_summary(a), read_summary(b)
    # What draws the chains: the same values, the same chains (episode by episode id).
    for key in ("setting", "seed", "episodes_per_class", "world", "lab", "severity"):
        if first["config"].get(key) != second["config"].get(key):
            raise ValueError(f"{a} and {b} differ in {key}: not the same chains")
    rows = [f"{a} (A) against {b} (B)", "", *HEADER]
    for arm in sorted(set(first["arms"]) & set(second["arms"])):
        ra, rb = first["arms"][arm], second["arms"][arm]
        answers = paired_answers(ra, rb)
        pooled.setdefault(arm, []).append((answers, ra, rb))
        test = paired_test(*answers)
        rows.append(
            f"| {arm} | {ra['model']} / {rb['model']} "
            f"| {100 * ra['estimate']['accuracy_attempted']:.1f} % "
            f"| {100 * rb['estimate']['accuracy_attempted']:.1f} % "
            f"| {test['only_learned']} | {test['only_random']} | {test['p_value']:.2g} "
            f"| {push_speeds(a / f'{arm}.jsonl')} | {push_speeds(b / f'{arm}.jsonl')} |"
        )
    return rows


def pooled_rows(pooled: dict[str, list]) -> list[str]:
    """Every pair's episodes together, arm by arm."""
    rows = ["All pairs pooled", "", *HEADER]
    for arm, pairs in sorted(pooled.items()):
        truth, in_a, in_b = (np.concatenate([p[0][k] for p in pairs]) for k in range(3))
        test = paired_test(truth, in_a, in_b)
        # Both runs of a pair attempted the same episodes (same classes, episodes per class).
        attempted = sum(ra["episodes"] for _, ra, _ in pairs)
        right_a = sum(ra["estimate"]["accuracy_attempted"] * ra["episodes"] for _, ra, _ in pairs)
        right_b = sum(rb["estimate"]["accuracy_attempted"] * rb["episodes"] for _, _, rb in pairs)
        rows.append(
            f"| {arm} | | {100 * right_a / attempted:.1f} % | {100 * right_b / attempted:.1f} % "
            f"| {test['only_learned']} | {test['only_random']} | {test['p_value']:.2g} | | |"
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "runs", type=Path, nargs="+", help="`masspush sim2real` run directories: A B [A B ...]"
    )
    args = parser.parse_args(argv)
    try:
        if len(args.runs) % 2:
            raise ValueError(f"give run directories in pairs (A B), got {len(args.runs)}")
        rows, pooled = [], {}
        for a, b in zip(args.runs[::2], args.runs[1::2], strict=True):
            rows += [*compare(a, b, pooled), ""]
        if len(args.runs) > 2:
            rows += pooled_rows(pooled)
        print("\n".join(rows))
    except (OSError, ValueError) as err:
        sys.exit(f"error: {' '.join(str(err).split())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
