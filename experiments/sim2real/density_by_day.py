"""Do a lab's tuned push densities still sort its chains on another day?

A lab tunes the particle filter's push density to one day's calibration run (`masspush
tune-density`); on a later day its table's friction, its robot's speed gain and its
tracker's calibration have drifted (`masspush sim2real --lab L --day D`). For each
recording (any days, any arms), this prints the accuracy of sorting its episodes by each
named density's class posterior, after each number of pushes asked, and the exact McNemar
test of each density against the first on the same episodes (the episodes only the first /
only the other sorted right). Recordings of the same chains as the first recording (runs of
the same `--seed`, as its `summary.json` says, e.g. on another day) are also compared with
it on the chains both have, each sorted by the first density. For
docs/notebook/2026-12-07-another-day.md:

    python experiments/sim2real/density_by_day.py --pushes 2,32 \\
        --density day0=results/lab-tuned-density/lab9-seed1-32push.pt \\
        --density topped-up=results/lab-tuned-density/lab9-day2-topup-10perclass.pt \\
        results/sim2real-bayes-placed/lab9-day2-seed17-32push-checked-fit16-default/learned.jsonl
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from masspush.data import read_recording
from masspush.learn import load_push_density
from masspush.real import TuneConfig, paired_test, posterior_accuracy, sort_over


def chains_seed(path: Path) -> int | None:
    """The `sim2real --seed` of the run a recording is from (read from the `summary.json`
    beside it; None without one): episode ids name a class and a number, not the chains, so
    runs of one seed share chains and runs of two seeds none."""
    summary = path.parent / "summary.json"
    if not summary.is_file():
        return None
    return json.loads(summary.read_text()).get("config", {}).get("seed")


def named_density(text: str) -> tuple[str, Path]:
    name, sep, path = text.partition("=")
    if not sep or not name or not path:
        raise argparse.ArgumentTypeError(f"expected NAME=FILE, got {text!r}")
    return name, Path(path)


def pushes_list(text: str) -> list[int]:
    try:
        values = [int(p) for p in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected P,Q,..., got {text!r}") from None
    if min(values) < 1:
        raise argparse.ArgumentTypeError(f"pushes must be >= 1, got {text!r}")
    return values


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recordings", nargs="+", type=Path)
    parser.add_argument("--density", action="append", required=True, type=named_density,
                        help="NAME=FILE, a tuned density (repeatable; the first is compared "
                        "with each other)")  # fmt: skip
    parser.add_argument("--widened", action="append", default=[], type=named_density,
                        help="NAME=FILE, a tuned density sorting over the current default "
                        "friction range (tune-density --sort-range), its weights unchanged "
                        "(repeatable; after the --density ones)")  # fmt: skip
    parser.add_argument("--pushes", type=pushes_list, default=[2, 32],
                        help="each episode's first P pushes, P,Q,... (default: 2,32)")  # fmt: skip
    args = parser.parse_args()
    densities = {}
    for option, named in (("--density", args.density), ("--widened", args.widened)):
        for name, path in named:
            if name in densities:
                parser.error(f"{option} {name}={path}: the name {name} is taken")
            try:
                densities[name] = load_push_density(path)
            except (OSError, ValueError) as err:
                parser.error(f"{option} {name}={path}: {err}")
            if not densities[name].meta.get("tuned"):
                parser.error(f"{option} {name}={path}: not a tuned density (tune-density)")
            if option == "--widened":
                sort_over(densities[name], TuneConfig())
    for path in args.recordings:
        if not path.is_file():
            parser.error(f"{path}: no such recording")
    first, *others = densities
    head = " | ".join(densities) + "".join(f" | {first} / {o} only right, p" for o in others)
    print(f"| recording | episodes | pushes | {head} | first recording / this only right, p |")
    print("|---" * (4 + len(densities) + len(others)) + "|")
    reference: dict[int, dict[str, bool]] = {}  # the first recording's, by pushes
    first_seed = chains_seed(args.recordings[0])
    for path in args.recordings:
        try:
            recording = read_recording(path)
            same_chains = first_seed is not None and chains_seed(path) == first_seed
            for pushes in args.pushes:
                sorted_by = {
                    name: posterior_accuracy(density, recording, str(path), pushes)
                    for name, density in densities.items()
                }
                base = sorted_by[first]
                truth = np.array([base["classes"].index(label) for label in recording.labels])
                cells = [f"{100 * s['accuracy']:.1f} %" for s in sorted_by.values()]
                for other in others:
                    if sorted_by[other]["classes"] != base["classes"]:
                        raise ValueError(f"{other} is tuned for other classes than {first}")
                    # paired_test's "learned" is the first density here, its "random" the other
                    test = paired_test(truth, np.array(base["predicted"]),
                                       np.array(sorted_by[other]["predicted"]))  # fmt: skip
                    cells.append(f"{test['only_learned']} / {test['only_random']}, "
                                 f"p = {test['p_value']:.2g}")  # fmt: skip
                right = dict(zip((e["id"] for e in recording.episodes),
                                 np.array(base["predicted"]) == truth, strict=True))  # fmt: skip
                if pushes not in reference:
                    reference[pushes] = right
                    cells.append("-")
                elif not same_chains:
                    cells.append("other chains")
                elif shared := sorted(right.keys() & reference[pushes].keys()):
                    # the same chains (same seed and episode id): a paired comparison on them
                    was = np.array([reference[pushes][i] for i in shared], float)
                    now = np.array([right[i] for i in shared], float)
                    test = paired_test(np.ones(len(shared)), was, now)
                    first_right = f"{100 * was.mean():.1f} %"
                    cells.append(f"{test['only_learned']} / {test['only_random']}, "
                                 f"p = {test['p_value']:.2g} (first: {first_right} of "
                                 f"these {len(shared)})")  # fmt: skip
                else:
                    cells.append("other chains")
                print(f"| {path} | {len(recording.episodes)} | {pushes} | {' | '.join(cells)} |")
        except ValueError as err:
            sys.exit(f"error: {err}")


if __name__ == "__main__":
    main()
