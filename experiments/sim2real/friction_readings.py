"""How well does a tuned density's reading of the table's friction follow a lab's drift?

For each recording (a lab's days, `masspush sim2real --lab L --day D`), this prints the table
friction that a tuned density (`masspush tune-density`) reads from its episodes
(`masspush.real.read_friction`), with its 90 % interval, and the change from the reading kept
of the density's calibration run; from all episodes or the first K of each class, from each
episode's first P pushes: what a lab needs to push to notice a drift. With `--widen`, a
density tuned before the sorting range was kept is given the current default first (the same
weights); `--calibration REC` reads the calibration from REC instead of the density's kept
reading (none: no change is printed). For docs/notebook/2026-12-07-wider-friction.md:

    python experiments/sim2real/friction_readings.py --per-class 2,all --pushes 8,32 \\
        --density results/lab-tuned-density/lab9-seed1-32push-wide.pt \\
        results/sim2real-bayes-placed/lab9-day5-seed17-32push-15perclass/learned.jsonl
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from masspush.data import Recording, read_recording
from masspush.learn import load_push_density
from masspush.real import TuneConfig, calibration_friction, read_friction, sort_over


def counts(text: str) -> list[int | None]:
    """'2,8,all' -> [2, 8, None]."""
    try:
        values = [None if p == "all" else int(p) for p in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected K,L,... or all, got {text!r}") from None
    if any(v is not None and v < 1 for v in values):
        raise argparse.ArgumentTypeError(f"counts must be >= 1, got {text!r}")
    return values


def first_of_each_class(recording: Recording, k: int | None) -> Recording:
    """The first `k` episodes of each class (all with None)."""
    if k is None:
        return recording
    seen: dict[str, int] = {}
    kept = []
    for episode in recording.episodes:
        label = str(episode.get("label"))
        if seen.get(label, 0) < k:
            kept.append(episode)
            seen[label] = seen.get(label, 0) + 1
    return Recording(recording.n_links, setting=recording.setting, episodes=kept)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recordings", nargs="+", type=Path)
    parser.add_argument("--density", type=Path, required=True, help="a tuned density")
    parser.add_argument(
        "--per-class",
        type=counts,
        default=[None],
        help="each class's first K episodes, K,L,... or all (default: all)",
    )
    parser.add_argument(
        "--pushes",
        type=counts,
        default=[None],
        help="each episode's first P pushes, P,Q,... or all (default: all)",
    )
    parser.add_argument(
        "--widen", action="store_true", help="give an older tuned density the current sorting range"
    )
    parser.add_argument("--calibration", type=Path, default=None,
                        help="the calibration recording to read the change from (default: the "
                        "density's kept reading)")  # fmt: skip
    args = parser.parse_args()
    for path in [*args.recordings, *([args.calibration] if args.calibration else [])]:
        if not path.is_file():
            parser.error(f"{path}: no such recording")
    try:
        density = load_push_density(args.density)
    except (OSError, ValueError) as err:
        parser.error(f"--density {args.density}: {err}")
    if not density.meta.get("tuned"):
        parser.error(f"--density {args.density}: not a tuned density (masspush tune-density)")
    try:
        if args.widen:
            sort_over(density, TuneConfig())
        recordings = {path: read_recording(path) for path in args.recordings}
        reference = calibration_friction(density)
        if args.calibration:
            calibration = read_recording(args.calibration)
            reference = read_friction(density, calibration, str(args.calibration)).as_dict()
        if reference is not None:
            print(f"calibration's reading: {reference['value']:.3f}")
        print("| recording | episodes | pushes | reading (90 % interval) | change |")
        print("|---|---|---|---|---|")
        for path, recording in recordings.items():
            for k in args.per_class:
                part = first_of_each_class(recording, k)
                for p in args.pushes:
                    r = read_friction(density, part, str(path), p)
                    edge = f" at the {r.edge} end" if r.edge else ""
                    change = "-" if reference is None else f"{100 * r.change(reference):+.0f} %"
                    print(f"| {path} | {r.episodes} | {p or 'all'} | {r.value:.3f} "
                          f"({r.low:.3f}-{r.high:.3f}){edge} | {change} |")  # fmt: skip
    except ValueError as err:
        sys.exit(f"error: {str(err).splitlines()[0]}")


if __name__ == "__main__":
    main()
