"""Does a push density tuned to a lab on one set of labelled episodes sort that lab's other
chains better than the protocol's classifier?

`masspush tune-density` tunes the particle filter's push density to a lab's labelled
episodes (a calibration recording). For each further recording of the same lab (other chains,
other seeds of `masspush sim2real --lab L --learned-model bayes`), this prints the accuracy
of sorting its episodes by the tuned density's class posterior (no label of that recording
used), by the untuned density's, and, where the recording's `summary.json` lies beside it,
by the protocol's classifier on the filter's estimates (cross-validated on that recording's
own labels), with the exact McNemar test of the posterior against the classifier on the same
episodes. `--pushes P`: from each episode's first P pushes (the classifier's figure is then
its `by_runs` entry for P pushes, where the summary has one). For
docs/notebook/2026-12-05-lab-tuned-density.md:

    python experiments/sim2real/tuned_density_transfer.py --density TUNED.pt \\
        results/sim2real-bayes-placed/lab5-seed2-16push-checked-fit16/learned.jsonl ...
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from masspush.data import read_recording
from masspush.learn import load_push_density
from masspush.models import shipped_density
from masspush.real import paired_test, posterior_accuracy


def classifier_result(path: Path, pushes: int | None) -> tuple[float, list[int]] | None:
    """The protocol's accuracy on the recording and each episode's predicted class index
    (None where the summary is not beside it, has no arm named as the file, `random.jsonl`
    or `learned.jsonl`, or has no figure for `pushes`)."""
    summary = path.parent / "summary.json"
    if not summary.is_file():
        return None
    arm = json.loads(summary.read_text())["arms"].get(path.stem)
    if arm is None:
        return None
    if pushes is None:
        return arm["estimate"]["accuracy"], arm["estimate"]["predicted"]
    step = next((s for s in arm.get("by_runs", []) if s["pushes"] == pushes), None)
    return None if step is None else (step["estimate"], [])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recordings", nargs="+", type=Path)
    parser.add_argument("--density", required=True, type=Path, help="a tuned push density")
    parser.add_argument("--pushes", type=int, default=None, help="each episode's first P")
    parser.add_argument(
        "--untuned", type=Path, help="the density it was tuned from (default: shipped)"
    )
    args = parser.parse_args()
    if args.pushes is not None and args.pushes < 1:
        parser.error("--pushes must be >= 1")
    try:
        tuned = load_push_density(args.density)
        if not tuned.meta.get("tuned"):
            raise ValueError(f"{args.density}: not a tuned density (masspush tune-density)")
        # The density it was tuned from (its file path may be another machine's): the
        # setting's shipped one unless --untuned names it; its digest must match.
        untuned = load_push_density(args.untuned or shipped_density(tuned.meta["setting"]))
        if untuned.digest() != tuned.meta["tuned"]["from_digest"]:
            raise ValueError(
                f"{args.density} was not tuned from {args.untuned or 'the shipped density'}"
                " (--untuned FILE: the one it was)"
            )
        untuned.meta["tuned"] = tuned.meta["tuned"]  # its classes and grid, its own weights
        for path in args.recordings:
            if not path.is_file():
                raise ValueError(f"{path}: no such recording")
    except (OSError, ValueError) as err:
        sys.exit(f"error: {err}")
    print(f"tuned on {tuned.meta['tuned']['episodes']}; pushes: {args.pushes or 'all'}")
    print("| recording | episodes | untuned posterior | tuned posterior | protocol's classifier "
          "| only classifier / only posterior right, p |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    for path in args.recordings:
        try:
            recording = read_recording(path)
            ours = posterior_accuracy(tuned, recording, str(path), args.pushes)
            plain = posterior_accuracy(untuned, recording, str(path), args.pushes)
        except ValueError as err:
            sys.exit(f"error: {err}")
        classifier = classifier_result(path, args.pushes)
        cells = ["-", "-"]
        if classifier is not None:
            cells[0] = f"{100 * classifier[0]:.1f} %"
            if classifier[1]:
                # the summary's class order is the sorted labels, as the density's
                truth = np.array([ours["classes"].index(label) for label in recording.labels])
                test = paired_test(truth, np.array(ours["predicted"]), np.array(classifier[1]))
                cells[1] = (f"{test['only_random']} / {test['only_learned']}, "
                            f"p = {test['p_value']:.2g}")  # fmt: skip
        print(f"| {path} | {len(recording.episodes)} | {100 * plain['accuracy']:.1f} % "
              f"| {100 * ours['accuracy']:.1f} % | {cells[0]} | {cells[1]} |")  # fmt: skip


if __name__ == "__main__":
    main()
