"""How far apart are the frictions under a chain's two links in the target world's labs, and
would a class posterior that lets the friction vary from push to push sort more?

The target world's table friction varies over the table (`TargetWorld.friction_variation`,
`friction_wavelength`); a link on stickier table than its neighbour answers a push as if it
were heavier. Part 1 reads each lab's field under the two link centres of its chain, laid
straight at a random heading, on the marked spot (+-2 cm) and over +-0.2 m, and prints the
|log ratio| of the two frictions (median and 90th percentile). Part 2, for each recording
given (labelled episodes of the filter arm, e.g. `filter_gap_parts.py`'s), sorts the
episodes by the five classes' posterior under the push density (untuned), each push's
likelihood marginalised over a friction spread around the episode's (a Gaussian in log
friction of relative width `--spreads`; 0: one friction per episode, as the filter and
`tune-density` read it), on a grid of 33 frictions in 0.3-1.2, after 2 and 16 pushes.
docs/notebook/2026-12-08-friction-field.md.

    python experiments/sim2real/friction_field.py [RECORDING ...] [--labs 1,5,6,8,9,12]
        [--spreads 0,0.05,0.1,0.15,0.2,0.3] [--density FILE]
"""

import argparse
from pathlib import Path

import numpy as np

from masspush.data import Recording, read_recording
from masspush.learn import load_push_density
from masspush.models import shipped_density
from masspush.real import (
    Lab,
    LabelledPush,
    TargetWorld,
    class_masses,
    first_pushes,
    friction_grid,
    joint_log_likelihoods,
    labelled,
    labelled_pushes,
)
from masspush.settings import get_setting

SETTING = "real-ur10"
PLACEMENTS = 4000


def link_ratios(lab: Lab, gap: float, spread: float, rng: np.random.Generator) -> np.ndarray:
    """|log(mu2 / mu1)| under the two link centres of `lab`'s chain (hinge gap `gap`, m),
    laid straight from a root within +-`spread` m of the origin at a random heading."""
    reach = lab.lengths[0] / 2 + gap + lab.lengths[1] / 2
    out = np.empty(PLACEMENTS)
    for i in range(PLACEMENTS):
        root = rng.uniform(-spread, spread, 2)
        yaw = rng.uniform(-np.pi, np.pi)
        mu = lab.field(np.stack([root, root + reach * np.array([np.cos(yaw), np.sin(yaw)])]))
        out[i] = abs(np.log(mu[1] / mu[0]))
    return out


def per_push(pushes: list[LabelledPush]) -> tuple[list[LabelledPush], np.ndarray]:
    """Every push as an episode of its own, and the episode each came from."""
    single, episode = [], []
    for e, p in enumerate(pushes):
        for k in range(len(p.actions)):
            single.append(LabelledPush(p.starts[k : k + 1], p.actions[k : k + 1],
                                       p.outputs[k : k + 1], p.lengths))  # fmt: skip
            episode.append(e)
    return single, np.array(episode, int)


def spread_kernel(grid: np.ndarray, spread: float) -> np.ndarray:
    """(F, F) log weights of a Gaussian in log friction of width `spread` around each grid
    friction, over the grid's frictions (uniform in friction, so weighted by 1/mu)."""
    log_mu = np.log(grid)
    w = -0.5 * ((log_mu[None] - log_mu[:, None]) / spread) ** 2 - log_mu[None]
    return w - np.logaddexp.reduce(w, axis=1, keepdims=True)


def sorted_right(
    recording: Recording, density, grid: np.ndarray, spreads: list[float], count: int
) -> list[float]:
    """The share of `recording`'s episodes sorted right from their first `count` pushes,
    with each of `spreads`."""
    labels, classes = labelled(recording)
    masses = class_masses(recording, classes)
    pushes = first_pushes(labelled_pushes(recording), count)
    single, episode = per_push(pushes)
    lp = joint_log_likelihoods(density, single, masses, grid)  # (P, C, F)
    out = []
    for spread in spreads:
        if spread:
            lp_s = np.logaddexp.reduce(lp[:, :, None, :] + spread_kernel(grid, spread), axis=3)
        else:
            lp_s = lp
        joint = np.zeros((len(pushes), len(classes), len(grid)))
        np.add.at(joint, episode, lp_s)
        guess = np.logaddexp.reduce(joint, axis=2).argmax(1)
        out.append(float(np.mean(guess == labels)))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recordings", nargs="*", help="labelled recordings of the filter arm")
    parser.add_argument("--labs", default="1,5,6,8,9,12")
    parser.add_argument("--spreads", default="0,0.05,0.1,0.15,0.2,0.3")
    parser.add_argument("--density", default=None, help="push density (default: shipped)")
    args = parser.parse_args()
    try:
        labs = [int(v) for v in args.labs.split(",") if v]
        spreads = [float(v) for v in args.spreads.split(",")]
    except ValueError as err:
        parser.error(f"--labs / --spreads: {err}")
    if any(lab < 0 for lab in labs):
        parser.error("--labs: each >= 0")
    if not all(0 <= s <= 2 for s in spreads):  # also refuses nan
        parser.error(f"--spreads: each in [0, 2], got {args.spreads}")
    recordings = {}
    for path in args.recordings:  # all read and checked before any work
        if not Path(path).is_file():
            parser.error(f"{path}: no such recording")
        try:
            recordings[path] = read_recording(path)
            class_masses(recordings[path], labelled(recordings[path])[1])
        except ValueError as err:  # the recording's error names the file
            parser.error(str(err).splitlines()[0])
        if recordings[path].n_links != 2:  # the density's chain
            parser.error(f"{path}: {recordings[path].n_links} links, not 2")
    try:
        density = load_push_density(args.density or shipped_density(SETTING))
    except ValueError as err:
        parser.error(str(err))

    world = TargetWorld()
    physics = world.physics(get_setting(SETTING).physics())
    rng = np.random.default_rng(0)
    print("| lab | mean friction | |log ratio| on the spot: median / 90 % | over +-0.2 m |")
    print("|---|---|---|---|")
    for number in labs:
        lab = Lab(number, world, physics)
        gap = physics.joint_gap
        spot, wide = link_ratios(lab, gap, 0.02, rng), link_ratios(lab, gap, 0.2, rng)
        print(f"| {number} | {lab.friction:.2f} | {np.median(spot):.2f} / "
              f"{np.quantile(spot, 0.9):.2f} | {np.median(wide):.2f} / "
              f"{np.quantile(wide, 0.9):.2f} |")  # fmt: skip

    grid = friction_grid(density, 33, (0.3, 1.2))
    if args.recordings:
        print("\n| recording | pushes | " + " | ".join(f"spread {s:g}" for s in spreads) + " |")
        print("|---" * (len(spreads) + 2) + "|")
    for path, recording in recordings.items():
        for count in (2, 16):
            hits = sorted_right(recording, density, grid, spreads, count)
            print(f"| {Path(path).name} | {count} | "
                  + " | ".join(f"{100 * h:.1f} %" for h in hits) + " |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
