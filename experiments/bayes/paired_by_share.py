"""Where two models differ on the same episodes: their mean absolute error and mean signed
error (bias) of link 1's share, in bins of its true value, from two `masspush evaluate
--json` records with per-episode estimates (the filter's always have them; a learned
model's with --per-episode or --paired-with).

    python experiments/bayes/paired_by_share.py results/paired/2link-0.1-1-bayes-300.json \\
        results/paired/2link-0.1-1-tp+-300.json
"""

from __future__ import annotations

import argparse
import itertools
import json

import numpy as np

from masspush.metrics import paired_rows

EDGES = (0.0, 0.2, 0.35, 0.5, 0.65, 0.8, 1.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("first")
    parser.add_argument("second")
    args = parser.parse_args()
    records = [json.load(open(path)) for path in (args.first, args.second)]
    a, b = (r["model"] for r in records)
    est_a, est_b, truth = paired_rows(*(r["per_episode"] for r in records))
    share, err_a, err_b = truth[:, 0], est_a[:, 0] - truth[:, 0], est_b[:, 0] - truth[:, 0]
    print(f"{records[0]['setting']}: {len(share)} episodes both scored")
    print(f"| true share of link 1 | episodes | MAE {a} | MAE {b} | bias {a} | bias {b} |")
    print("|---|---|---|---|---|---|")
    for lo, hi in itertools.pairwise(EDGES):
        m = (share >= lo) & (share < hi)
        if m.any():
            print(f"| {lo:.2f}-{hi:.2f} | {m.sum()} | {np.abs(err_a[m]).mean():.4f} "
                  f"| {np.abs(err_b[m]).mean():.4f} | {err_a[m].mean():+.4f} "
                  f"| {err_b[m].mean():+.4f} |")  # fmt: skip
    print(f"| all | {len(share)} | {np.abs(err_a).mean():.4f} | {np.abs(err_b).mean():.4f} "
          f"| {err_a.mean():+.4f} | {err_b.mean():+.4f} |")  # fmt: skip


if __name__ == "__main__":
    main()
