"""Does a lab's push density sort its chains better when tuned on more of its own runs?

`masspush tune-density` tunes the particle filter's push density to a lab's labelled
episodes. Given several recordings of the same lab (other chains: other seeds of
`masspush sim2real --lab L --learned-model bayes`), this holds each recording out in turn,
tunes the density on the others (`--calibrate all`, the default) or on each single other
one (`--calibrate one`), and sorts the held-out recording's episodes by the tuned class
posterior after 2 and 16 pushes and after all of them (`--pushes`). With `--reference
TUNED.pt` (a density tuned on a calibration recording apart from all of them) it also sorts
each held-out recording with that, and tests the two on the same episodes (exact McNemar).
The tuned densities are kept in `--cache` and reused. For
docs/notebook/2026-12-06-calibration-runs.md:

    python experiments/sim2real/calibration_runs.py \\
        --reference results/lab-tuned-density/lab6-seed1.pt \\
        results/sim2real-bayes-placed/lab6-seed{0,3,4}-32push-checked-fit16-reach2/learned.jsonl \\
        results/sim2real-bayes-placed/lab6-seed2-32push-checked-fit16-default/learned.jsonl
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path

import numpy as np

from masspush.data import read_recording
from masspush.learn import load_push_density
from masspush.real import TuneConfig, TuneDensityJob, paired_test, posterior_accuracy, tune

PUSH_COUNTS = "2,16,all"
"""After how many pushes each held-out episode is sorted by default (all: every push it has;
`--pushes`)."""


def tuned_on(setting: str, recordings: list[Path], cache: Path, config: TuneConfig) -> Path:
    """The density tuned on `recordings` (their own folds not cross-validated), from the
    cache where it was tuned before on the same contents."""
    key = hashlib.sha1(f"{setting}\n{config.steps}".encode())
    for path in recordings:
        key.update(path.read_bytes())
    out = cache / f"tuned-{key.hexdigest()[:12]}.pt"
    if not out.is_file():
        print(f"tuning on {', '.join(map(str, recordings))} ...", file=sys.stderr)
        job = TuneDensityJob(setting, tuple(map(str, recordings)), out=str(out))
        tune(job, config, progress=False)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recordings", nargs="+", type=Path, help="one lab's, at least two")
    parser.add_argument("--setting", default="real-ur10")
    parser.add_argument(
        "--calibrate", choices=("all", "one"), default="all",
        help="tune on all the other recordings, or on each other one alone",
    )  # fmt: skip
    parser.add_argument("--reference", type=Path, help="a density tuned apart from these")
    parser.add_argument("--cache", type=Path, default=Path("calibration-runs"))
    parser.add_argument("--steps", type=int, default=TuneConfig.steps)
    parser.add_argument(
        "--pushes",
        default=PUSH_COUNTS,
        help="after how many pushes to sort (comma-separated; 'all' is added)",
    )
    args = parser.parse_args()
    try:
        counts = [None if p == "all" else int(p) for p in args.pushes.split(",")]
        if any(p is not None and p < 1 for p in counts):
            raise ValueError
    except ValueError:
        parser.error(f"--pushes: positive integers or 'all', got {args.pushes!r}")
    # each count once (a repeated one would add a column and no total), all of them last
    counts = [*dict.fromkeys(p for p in counts if p is not None), None]
    if len(args.recordings) < 2:
        parser.error("name at least two recordings of the lab")
    for path in [*args.recordings, *([args.reference] if args.reference else [])]:
        if not path.is_file():
            parser.error(f"{path}: no such file")
    if args.cache.exists() and not args.cache.is_dir():
        parser.error(f"--cache {args.cache}: not a directory")
    try:
        config = TuneConfig(steps=args.steps, folds=0)
        args.cache.mkdir(parents=True, exist_ok=True)
        reference = load_push_density(args.reference) if args.reference else None
        recordings = {path: read_recording(path) for path in args.recordings}
    except (OSError, ValueError) as err:
        sys.exit(f"error: {err}")
    columns = " | ".join(f"after {p or 'all'}" for p in counts)
    print(f"| held out | tuned on | {columns} | reference after all | only reference / only "
          "these right, p |")  # fmt: skip
    print("|---" * (len(counts) + 4) + "|")
    right = {p: [0, 0] for p in counts}
    pooled: list[list[np.ndarray]] = [[], [], []]  # truth, these, reference's classes
    for held, recording in recordings.items():
        others = [p for p in recordings if p != held]
        groups = [others] if args.calibrate == "all" else [[p] for p in others]
        for group in groups:
            try:
                density = load_push_density(tuned_on(args.setting, group, args.cache, config))
                scores = {p: posterior_accuracy(density, recording, str(held), p)
                          for p in counts}  # fmt: skip
            except (OSError, ValueError) as err:
                sys.exit(f"error: {err}")
            for p, s in scores.items():
                right[p][0] += round(s["accuracy"] * len(recording.episodes))
                right[p][1] += len(recording.episodes)
            cells = [f"{100 * scores[p]['accuracy']:.1f} %" for p in counts]
            ref_cells = ["-", "-"]
            if reference is not None:
                ref = posterior_accuracy(reference, recording, str(held))
                truth = np.array([ref["classes"].index(label) for label in recording.labels])
                test = paired_test(truth, np.array(scores[None]["predicted"]),
                                   np.array(ref["predicted"]))  # fmt: skip
                ref_cells = [f"{100 * ref['accuracy']:.1f} %",
                             f"{test['only_random']} / {test['only_learned']}, "
                             f"p = {test['p_value']:.2g}"]  # fmt: skip
                for kept, classes in zip(
                    pooled, (truth, scores[None]["predicted"], ref["predicted"]), strict=True
                ):
                    kept.append(np.asarray(classes))
            names = ", ".join(p.parent.name for p in group)
            print(f"| {held.parent.name} | {names} | {' | '.join(cells)} | "
                  f"{' | '.join(ref_cells)} |")  # fmt: skip
    total = " | ".join(f"{100 * r / n:.1f} % of {n}" for r, n in right.values())
    ref_cells = "- | -"
    if pooled[0]:
        truth, ours, ref = (np.concatenate(kept) for kept in pooled)
        test = paired_test(truth, ours, ref)
        # With --calibrate one each episode is sorted once per other recording: the pairs
        # are not independent, and a p-value would overstate.
        p_value = f", p = {test['p_value']:.2g}" if args.calibrate == "all" else ""
        ref_cells = (f"{100 * np.mean(ref == truth):.1f} % | {test['only_random']} / "
                     f"{test['only_learned']}{p_value}")  # fmt: skip
    print(f"| **pooled** | | {total} | {ref_cells} |")


if __name__ == "__main__":
    main()
