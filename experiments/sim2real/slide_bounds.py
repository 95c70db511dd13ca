"""How far a push carries the chain: the slides of random pushes by speed, and the speed
governor's bounds fitted to them (`masspush.sim.workspace.fit_slides`).

    python experiments/sim2real/slide_bounds.py SOURCE [SOURCE ...] [--setting real-ur10] \
        [--quantile 0.99] [--resample 300,600,1200,2400]

SOURCE: a recording (`.jsonl`, e.g. random pushes recorded on your own table with `masspush
run --record`) or a dataset directory of `masspush collect` / the recipe (`runs/.../data-0`).
Prints the slides along and across the push per band of commanded speed and the bounds to
give the governor: `dataclasses.replace(workspace, **bounds)` (docs/real-robot.md). Several
sources are pooled. `--resample N,...`: how much the bounds fitted to N of these pushes
scatter (200 draws without replacement, seeded), which says how many random pushes a lab
should record before it trusts a fit.
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
    parser.add_argument("source", type=Path, nargs="+")
    parser.add_argument("--setting", default="real-ur10")
    parser.add_argument("--quantile", type=float, default=0.99)
    parser.add_argument("--resample", default="", help="push counts, e.g. 300,600,1200")
    args = parser.parse_args()
    try:
        sizes = [int(n) for n in args.resample.split(",") if n.strip()]
    except ValueError:
        parser.error(f"--resample: push counts separated by commas, got {args.resample!r}")
    try:
        physics = get_setting(args.setting).physics()
        parts = []
        for source in args.source:
            pushes = pushes_of(source)
            links = np.asarray(pushes[3]).shape[-1]
            if len(pushes[3]) and links != physics.n_links:  # read with the wrong chain
                raise ValueError(f"{source}: {links}-link chains; --setting {args.setting} "
                                 f"has {physics.n_links}")  # fmt: skip
            parts.append(push_slides(*pushes, physics))
        speed, along, across = (np.concatenate(v) for v in zip(*parts, strict=True))
        bounds = fit_slides(speed, along, across, args.quantile)
    except (ValueError, OSError) as err:
        parser.error(str(err))
    if any(not 50 <= n <= len(speed) for n in sizes):
        parser.error(f"--resample: each count must be 50-{len(speed)} (the pushes read)")
    print(f"{len(speed)} pushes with a rest pose after them")
    print("| speed (m/s) | pushes | along, q | along, max | across, q |\n|---|---|---|---|---|")
    for lo in np.arange(0.0, 5.0, 0.5):
        band = (speed >= lo) & (speed < lo + 0.5)
        if band.sum() >= 10:
            q = args.quantile
            print(f"| {lo:.1f}-{lo + 0.5:.1f} | {band.sum()} | {np.quantile(along[band], q):.3f} | "
                  f"{along[band].max():.3f} | {np.quantile(across[band], q):.3f} |")  # fmt: skip
    print("bounds:", {k: round(v, 3) for k, v in bounds.items()})
    if sizes:
        print("\n| pushes fitted | fits | bound | median | 5-95 % of fits |\n|---|---|---|---|---|")
    rng = np.random.default_rng(0)
    for n in sizes:
        fits = []
        for _ in range(RESAMPLES):
            i = rng.choice(len(speed), n, replace=False)
            try:
                fits.append(fit_slides(speed[i], along[i], across[i], args.quantile))
            except ValueError:  # too few slow pushes in this draw
                continue
        for key in bounds if fits else ():
            v = np.array([f[key] for f in fits])
            low, high = np.quantile(v, [0.05, 0.95])
            print(f"| {n} | {len(fits)} | {key} | {np.median(v):.3f} | {low:.3f}-{high:.3f} |")


RESAMPLES = 200
"""Draws per push count of `--resample`."""


if __name__ == "__main__":
    main()
