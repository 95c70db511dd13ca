"""Accuracy against pushes per episode over several `masspush sim2real --segments K` runs
(e.g. one per lab): a figure with each run and the mean, and the table as markdown.

    python scripts/sim2real_labs_figure.py results/sim2real-4push-lab-64push/{0,1,2,3,4} \\
        --out results/sim2real-4push-lab-64push/accuracy-by-pushes.png

Each directory's summary.json must hold `by_runs` (written by sim2real with --segments > 1;
rerunning sim2real on a directory re-scores its kept recordings).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from masspush.sim2real import ARMS, plot_accuracy_by_pushes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="sim2real output directories")
    parser.add_argument("--out", type=Path, required=True, help="the figure (.png)")
    args = parser.parse_args()
    results = {}
    for run in args.runs:
        summary = json.loads((run / "summary.json").read_text())
        if any("by_runs" not in arm for arm in summary["arms"].values()):
            raise SystemExit(f"{run}: no by_runs; rerun masspush sim2real there (segments > 1)")
        lab = summary["config"].get("lab")
        results[f"lab {lab}" if lab is not None else str(run)] = summary
    plot_accuracy_by_pushes(results, args.out)
    pushes = [s["pushes"] for s in next(iter(results.values()))["arms"]["learned"]["by_runs"]]
    print("| run | arm | " + " | ".join(f"{p} pushes" for p in pushes) + " |")
    print("|---" * (len(pushes) + 2) + "|")
    for arm in ARMS:
        rows = []
        for name, summary in results.items():
            acc = [100 * s["accuracy"] for s in summary["arms"][arm]["by_runs"]]
            rows.append(acc)
            print(f"| {name} | {arm} | " + " | ".join(f"{a:.1f} %" for a in acc) + " |")
        mean = np.mean(rows, axis=0)
        print(f"| mean | {arm} | " + " | ".join(f"**{a:.1f} %**" for a in mean) + " |")
    print(f"figure: {args.out}")


if __name__ == "__main__":
    main()
