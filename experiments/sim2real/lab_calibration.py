"""Does calibrating the learned push density to a lab let it sort the paper's classes there?

A lab's robot pushes every episode with the same speed gain and the same bias of the contact
point along the link (`masspush.real.target_world.Lab`), constants a density trained in
simulation does not know. With the labelled episodes of the protocol (the classes' masses
are known), a lab can estimate them: replay each episode's pushes (recorded by
`class_seeking.py --lab L`) through the density as if the commanded speed had been scaled by
a gain g and the contact point moved by b (in action units), for a grid of (g, b); weigh the
five classes (each over a friction grid) by the replayed pushes; and keep the (g, b) under
which the labelled episodes' true classes are most probable. Cross-validated as the
protocol's classifier is (5 stratified folds): (g, b) are chosen on four folds and the fifth
is sorted by the class of highest posterior.

    python experiments/sim2real/lab_calibration.py /tmp/seek-lab5.json \
        --density runs/density/real-ur10-placed.pt [--pushes 2]

Prints the accuracy without calibration (g = 1, b = 0), calibrated (cross-validated), and
the (g, b) chosen on all episodes.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

import masspush.bayes as bayes
from masspush.learn import density_for
from masspush.real import PAPER_CLASSES, stratified_folds
from masspush.settings import get_setting


def logsumexp(x: np.ndarray, axis: int, keepdims: bool = False) -> np.ndarray:
    top = np.max(x, axis=axis, keepdims=True)
    out = top + np.log(np.sum(np.exp(x - top), axis=axis, keepdims=True))
    return out if keepdims else np.squeeze(out, axis=axis)


def class_log_likelihoods(
    density, episodes: list[dict], gain: float, bias: float, frictions: np.ndarray, pushes: int
) -> np.ndarray:
    """(E, C) each episode's log-likelihood of each class, marginal over the friction grid,
    from its first `pushes` pushes replayed with the speed scaled by `gain` and the contact
    point moved by `bias`."""
    classes = np.array(list(PAPER_CLASSES.values()), float)
    masses = np.repeat(classes, len(frictions), axis=0)
    friction = np.tile(frictions, len(classes))
    out = np.zeros((len(episodes), len(classes)))
    for e, episode in enumerate(episodes):
        poses = np.asarray(episode["poses"], float)
        total = np.zeros(len(masses))
        for k, action in enumerate(episode["actions"][:pushes]):
            a = np.array([np.clip(action[0] * gain, -1, 1), np.clip(action[1] + bias, -1, 1)])
            total += density.log_prob(poses[k], a, poses[k + 1], masses, friction,
                                      np.asarray(episode["lengths"], float))  # fmt: skip
        out[e] = logsumexp(total.reshape(len(classes), -1), axis=1)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("episodes", help="a class_seeking.py output with poses (--lab L)")
    parser.add_argument("--density", required=True, help="the push density (train-density)")
    parser.add_argument("--pushes", type=int, default=None, help="the first pushes only")
    parser.add_argument("--frictions", type=int, default=8, help="friction grid per class")
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0, help="the folds' shuffle")
    args = parser.parse_args()
    if args.frictions < 1 or (args.pushes is not None and args.pushes < 1):
        parser.error("--frictions and --pushes must be at least 1")
    if args.folds < 2:
        parser.error("--folds must be at least 2")
    path = Path(args.episodes)
    try:
        episodes = list(json.loads(path.read_text())["episodes"].values())
        if not episodes or "poses" not in episodes[0]:
            raise ValueError("no episodes with poses (made before poses were kept?)")
    except (OSError, ValueError, KeyError) as err:
        parser.error(f"episodes: cannot use {path} ({getattr(err, 'strerror', None) or err})")
    setting = get_setting("real-ur10")
    try:
        density = density_for(args.density, setting.env_config())
    except ValueError as err:
        parser.error(f"--density: {err}")
    pushes = args.pushes or max(len(e["actions"]) for e in episodes)
    kept = [e for e in episodes if e["actions"]]
    labels = np.array([e["label"] for e in kept])
    frictions = bayes.friction_grid(setting, args.frictions)
    gains, biases = np.linspace(0.8, 1.2, 9), np.linspace(-0.09, 0.09, 7)
    grid = [(g, b) for g in gains for b in biases]
    loglik = {gb: class_log_likelihoods(density, kept, *gb, frictions, pushes) for gb in grid}

    def fit(rows: np.ndarray) -> tuple[float, float]:
        """The (g, b) under which the rows' true classes are most probable."""

        def score(gb):
            post = loglik[gb][rows] - logsumexp(loglik[gb][rows], axis=1, keepdims=True)
            return post[np.arange(len(rows)), labels[rows]].sum()

        return max(grid, key=score)

    plain = np.mean(loglik[(1.0, 0.0)].argmax(1) == labels)
    right = np.zeros(len(kept), bool)
    for test in stratified_folds(labels, args.folds, args.seed):
        train = np.setdiff1d(np.arange(len(kept)), test)
        gb = fit(train)
        right[test] = loglik[gb][test].argmax(1) == labels[test]
    g, b = fit(np.arange(len(kept)))
    print(f"{path}: {len(kept)} episodes with a push, {pushes} pushes each at most")
    print(f"uncalibrated: {100 * plain:.1f} %; calibrated ({args.folds}-fold): "
          f"{100 * right.mean():.1f} %; on all episodes g = {g:.2f}, b = {b:+.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
