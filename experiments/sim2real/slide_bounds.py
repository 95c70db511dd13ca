"""How far a push carries the chain: the slides of random pushes by speed, and the speed
governor's bounds fitted to them (`masspush.sim.workspace.fit_slides`).

    python experiments/sim2real/slide_bounds.py SOURCE [--setting real-ur10] [--quantile 0.99]

SOURCE: a recording (`.jsonl`, e.g. random pushes recorded on your own table with `masspush
run --record`) or a dataset directory of `masspush collect` / the recipe (`runs/.../data-0`).
Prints the slides along and across the push per band of commanded speed and the bounds to
give the governor: `dataclasses.replace(workspace, **bounds)` (docs/real-robot.md).
"""

import argparse
from pathlib import Path

import numpy as np

from masspush.data import load_dataset
from masspush.real import episode_pushes, recording_pushes
from masspush.settings import get_setting
from masspush.sim import fit_slides, push_slides


def pushes_of(source: Path):
    """(before, after, actions, lengths) of every push with a rest pose after it."""
    if source.is_dir():
        return episode_pushes(load_dataset(source)[1])
    return recording_pushes(source)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("source", type=Path)
    parser.add_argument("--setting", default="real-ur10")
    parser.add_argument("--quantile", type=float, default=0.99)
    args = parser.parse_args()
    try:
        physics = get_setting(args.setting).physics()
        speed, along, across = push_slides(*pushes_of(args.source), physics)
        bounds = fit_slides(speed, along, across, args.quantile)
    except (ValueError, OSError) as err:
        parser.error(str(err))
    print(f"{len(speed)} pushes with a rest pose after them")
    print("| speed (m/s) | pushes | along, q | along, max | across, q |\n|---|---|---|---|---|")
    for lo in np.arange(0.0, 5.0, 0.5):
        band = (speed >= lo) & (speed < lo + 0.5)
        if band.sum() >= 10:
            q = args.quantile
            print(f"| {lo:.1f}-{lo + 0.5:.1f} | {band.sum()} | {np.quantile(along[band], q):.3f} | "
                  f"{along[band].max():.3f} | {np.quantile(across[band], q):.3f} |")  # fmt: skip
    print("bounds:", {k: round(v, 3) for k, v in bounds.items()})


if __name__ == "__main__":
    main()
