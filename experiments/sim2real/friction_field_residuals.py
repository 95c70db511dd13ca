"""Does the lab's uneven table friction explain how a filter arm's estimates scatter?

In a lab of the target world the table's friction varies over the plane
(`masspush.real.target_world.FrictionField`, a std of 15 % over wavelengths of 0.15-0.6 m),
so a chain's two links can rest on frictions that differ by more than 10 %: which one the
estimator takes for the heavier then depends partly on where on the table the chain was
pushed. For each recording of a `masspush sim2real --lab L` arm (2-link chains) and each
class: the first link's estimated share after all of an episode's pushes, minus the class's
mean (the residual); and the log-ratio of the friction under link 1 to that under link 2,
averaged over the episode's observed rest poses (the friction field is the lab's own, as
`Lab(L)` draws it), minus its class mean. Printed: their correlation over all classes, the
least-squares slope, and the residuals' standard deviation before and after taking out that
slope. Only episodes with every push (`--pushes`, default 16) are read, so that each
residual is after the same number of pushes. A recording made in another lab (its robot line
names the lab) is refused: its table is not `--lab`'s. For docs/notebook/2026-12-05-headroom.md:

    python experiments/sim2real/friction_field_residuals.py --lab 5 \\
        results/sim2real-bayes-placed/lab5-seed1-16push-checked-fit16/learned.jsonl
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from masspush.data import read_recording
from masspush.real import Lab, TargetWorld
from masspush.settings import get_setting
from masspush.sim import link_poses


def residuals(path: Path, lab_seed: int, pushes: int) -> tuple[np.ndarray, np.ndarray]:
    """(estimate residuals, friction log-ratio residuals) of the recording's full episodes."""
    recording = read_recording(path)
    if f"lab {lab_seed}," not in (recording.robot or ""):  # another lab's table
        raise ValueError(f"{path}: not recorded in lab {lab_seed} ({recording.robot!r})")
    if recording.n_links != 2:
        raise ValueError(f"{path}: {recording.n_links}-link chains; this reads 2-link ones")
    setting = get_setting(recording.setting or "real-ur10")
    world = TargetWorld()
    physics = world.physics(setting.physics())
    field = Lab(lab_seed, world, physics).field
    by_class: dict[str, list[tuple[float, float]]] = {}
    for episode in recording.episodes:
        estimates = episode.get("estimates")
        if episode.get("label") is None or estimates is None or len(estimates) < pushes:
            continue
        poses = np.asarray(episode["observations"], float)
        centres, _ = link_poses(poses, episode["lengths"], physics.joint_gap)
        mu = field(centres.reshape(-1, 2)).reshape(len(poses), 2)
        ratio = float(np.mean(np.log(mu[:, 0] / mu[:, 1])))
        by_class.setdefault(episode["label"], []).append((float(estimates[pushes - 1][0]), ratio))
    if not by_class:
        raise ValueError(f"{path}: no labelled episode with {pushes} estimates")
    res, ratios = [], []
    for pairs in by_class.values():
        values = np.array(pairs)
        res += list(values[:, 0] - values[:, 0].mean())
        ratios += list(values[:, 1] - values[:, 1].mean())
    return np.array(res), np.array(ratios)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recordings", nargs="+", type=Path)
    parser.add_argument("--lab", type=int, required=True, help="the lab the recordings ran in")
    parser.add_argument("--pushes", type=int, default=16, help="episodes with this many")
    args = parser.parse_args()
    if args.pushes < 1:
        parser.error("--pushes must be >= 1")
    if args.lab < 0:
        parser.error("--lab must be >= 0 (a lab's seed)")
    lines = []
    try:
        for path in args.recordings:
            if not path.is_file():
                raise ValueError(f"{path}: no such recording")
            res, ratio = residuals(path, args.lab, args.pushes)
            if len(res) < 3 or ratio.std() == 0:
                raise ValueError(f"{path}: too few episodes to correlate ({len(res)})")
            slope = float(np.polyfit(ratio, res, 1)[0])
            lines.append(f"| {path} | {len(res)} | {np.corrcoef(res, ratio)[0, 1]:.2f} "
                         f"| {slope:.3f} | {res.std():.3f} | {(res - slope * ratio).std():.3f} "
                         f"| {ratio.std():.3f} |")  # fmt: skip
    except (OSError, ValueError) as err:
        sys.exit(f"error: {err}")
    print("| recording | episodes | correlation | slope | residual sd | after the slope | "
          "friction log-ratio sd |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
