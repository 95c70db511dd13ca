"""Does a push density tuned on only the first pushes of a lab's calibration episodes sort
that lab's other chains better after those pushes than one tuned on the whole episodes?

The chain is put down on the same marked spot every episode, so an episode's first pushes
always meet the same patch of the lab's table, and the later ones meet the rest of it. This
tunes the density (as `masspush tune-density`, 100 steps, every episode) on each
calibration episode's first `--pushes` pushes only, then sorts every test recording from
its episodes' first `--pushes` pushes by the class posterior of that density and of
`--compare` (e.g. the density `tune-density` made from the whole episodes), paired by
episode (exact McNemar). For docs/notebook/2026-12-06-free-last-push.md:

    R=results/sim2real-bayes-placed
    python experiments/sim2real/first_pushes_calibration.py --pushes 2 \\
        --calibration $R/lab6-seed1-32push-checked-fit16-default/learned.jsonl ... \\
        --compare results/lab-tuned-density/lab6-seed0-4-32push.pt \\
        --tests $R/lab6-seed5-32push-10perclass-newseeds/learned.jsonl ...
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from masspush.data import Recording, read_recording
from masspush.learn import load_push_density
from masspush.models import shipped_density
from masspush.real import (
    TuneConfig,
    class_masses,
    first_pushes,
    labelled,
    labelled_pushes,
    paired_test,
    posterior_accuracy,
    record_tuning,
    tune_density,
    tuned_classes,
)


def tuned_on_first(merged: Recording, pushes: int, density):
    """`density` tuned on the calibration episodes' first `pushes` pushes."""
    labels, classes = labelled(merged)
    masses = class_masses(merged, classes)
    cut = first_pushes(labelled_pushes(merged), pushes)
    config = TuneConfig(folds=0)
    tuned = tune_density(density, cut, masses[labels], config)
    record_tuning(tuned, classes, masses, config, cut)
    print(f"tuned on the first {pushes} pushes of {len(labels)} calibration episodes")
    return tuned


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--calibration", type=Path, nargs="+", required=True)
    parser.add_argument("--tests", type=Path, nargs="+", required=True)
    parser.add_argument("--compare", type=Path, required=True, help="a tuned density")
    parser.add_argument("--pushes", type=int, default=2)
    parser.add_argument("--density", type=Path, default=None, help="to tune (shipped)")
    args = parser.parse_args()
    if args.pushes < 1:
        parser.error("--pushes must be >= 1")
    for path in [*args.calibration, *args.tests, args.compare]:
        if not path.is_file():
            parser.error(f"no such file: {path}")
    try:  # every input read and checked before the tuning
        calibration = [read_recording(path) for path in args.calibration]
        tests = [read_recording(path) for path in args.tests]
        whole = load_push_density(args.compare)
        classes, _ = tuned_classes(whole, str(args.compare))
        start = load_push_density(args.density or shipped_density("real-ur10"))
    except (OSError, ValueError) as err:
        parser.error(str(err).splitlines()[0])
    merged = Recording(calibration[0].n_links, setting=calibration[0].setting)
    for part in calibration:
        merged.episodes += part.episodes
    for path, recording in zip(args.tests, tests, strict=True):
        unknown = sorted({str(label) for label in recording.labels} - set(classes))
        if unknown:
            parser.error(f"{path}: classes {unknown} are not {args.compare}'s {classes}")
    first = tuned_on_first(merged, args.pushes, start)
    truth_all, first_all, whole_all = [], [], []
    print(f"| test recording | episodes | first {args.pushes} pushes tuned | {args.compare.name} |")
    print("|---|---|---|---|")
    for path, recording in zip(args.tests, tests, strict=True):
        a = posterior_accuracy(first, recording, str(path), args.pushes)
        b = posterior_accuracy(whole, recording, str(path), args.pushes)
        truth = np.array([a["classes"].index(label) for label in recording.labels])
        order = [b["classes"].index(c) for c in a["classes"]]  # the same class indices
        whole_guess = np.array([order.index(g) for g in b["predicted"]])
        truth_all.append(truth)
        first_all.append(np.array(a["predicted"]))
        whole_all.append(whole_guess)
        print(f"| {path} | {len(truth)} | {a['accuracy']:.1%} | {b['accuracy']:.1%} |")
    truth, first_guess, whole_guess = map(np.concatenate, (truth_all, first_all, whole_all))
    test = paired_test(truth, first_guess, whole_guess)
    print(
        f"all {len(truth)}: first-pushes density {np.mean(first_guess == truth):.1%}, "
        f"{args.compare.name} {np.mean(whole_guess == truth):.1%}; only the first-pushes one "
        f"right {test['only_learned']}, only the other {test['only_random']}, "
        f"p = {test['p_value']:.3f}"
    )


if __name__ == "__main__":
    main()
