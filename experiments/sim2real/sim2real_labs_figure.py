"""Accuracy against pushes per episode over several `masspush sim2real --segments K` runs
(e.g. one per lab): a figure with each run and the mean, the table as markdown, and the
arms compared on the same chains, pooled (exact McNemar test).

    python experiments/sim2real/sim2real_labs_figure.py
    results/sim2real-4push-lab-64push/{0,1,2,3,4} \\
        --out results/sim2real-4push-lab-64push/accuracy-by-pushes.png

Each directory's summary.json must hold `by_runs` (written by sim2real with --segments > 1;
rerunning sim2real on a directory re-scores its kept recordings).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from masspush.real import (
    ARMS,
    FEATURE_KINDS,
    FEATURE_NAMES,
    paired_test,
    plot_accuracy_by_pushes,
    read_summary,
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="sim2real output directories")
    parser.add_argument("--out", type=Path, required=True, help="the figure (.png)")
    args = parser.parse_args()
    results = {}
    for run in args.runs:
        try:
            summary = read_summary(run)
        except ValueError as err:
            parser.error(str(err))
        if any("by_runs" not in arm for arm in summary["arms"].values()):
            raise SystemExit(f"{run}: no by_runs; rerun masspush sim2real there (segments > 1)")
        lab = summary["config"].get("lab")
        results[f"lab {lab}" if lab is not None else str(run)] = summary
    plot_accuracy_by_pushes(results, args.out)
    pushes = [s["pushes"] for s in next(iter(results.values()))["arms"]["learned"]["by_runs"]]
    print("| run | arm | features | " + " | ".join(f"{p} pushes" for p in pushes) + " |")
    print("|---" * (len(pushes) + 3) + "|")
    for arm in ARMS:
        for kind in FEATURE_KINDS:
            rows = []
            for name, summary in results.items():
                acc = [100 * s[kind] for s in summary["arms"][arm]["by_runs"]]
                rows.append(acc)
                print(f"| {name} | {arm} | {FEATURE_NAMES[kind]} | "
                      + " | ".join(f"{a:.1f} %" for a in acc) + " |")  # fmt: skip
            mean = np.mean(rows, axis=0)
            print(f"| mean | {arm} | {FEATURE_NAMES[kind]} | "
                  + " | ".join(f"**{a:.1f} %**" for a in mean) + " |")  # fmt: skip
    # The arms on the same chains, pooled over the runs, for every pairing of feature kinds
    # (each arm may be read best by another kind).
    print("\n| learned arm's features | random arm's features | only learned right | "
          "only random right | exact McNemar p, pooled |")  # fmt: skip
    print("|---|---|---|---|---|")
    for mine in FEATURE_KINDS:
        for theirs in FEATURE_KINDS:
            arms = [s["arms"] for s in results.values()]
            if any(a["learned"]["ids"] != a["random"]["ids"] for a in arms):
                raise SystemExit("the arms did not push the same chains; no paired comparison")
            p = paired_test(
                np.concatenate([a["learned"]["labels"] for a in arms]),
                np.concatenate([a["learned"][mine]["predicted"] for a in arms]),
                np.concatenate([a["random"][theirs]["predicted"] for a in arms]),
            )
            print(f"| {FEATURE_NAMES[mine]} | {FEATURE_NAMES[theirs]} | {p['only_learned']} | "
                  f"{p['only_random']} | {p['p_value']:.2g} |")  # fmt: skip
    print(f"figure: {args.out}")


if __name__ == "__main__":
    main()
