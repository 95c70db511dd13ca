"""How well could any estimator tell the paper's five classes apart from these pushes?

The ceiling behind issue 28's accuracy goals (81.4 % at 2 pushes, 90 % with runs). For each
labelled episode of a `masspush sim2real` recording, the particle filter
(`masspush.bayes.filter`, simulating the setting's robot in the training world's physics)
is given exactly the five classes' masses as its hypotheses, each at a grid of table
frictions over the setting's range (the one unknown besides the class), and weighs them by
the episode's pushes as recorded (the pushes the robot was told to make, the poses it saw).
The class with the most posterior mass is the oracle's answer: it knows the classes, the
physics and the noise model, so a classifier trained on 30 episodes per class should not
beat it. Run on a training-world recording it measures what the pushes carry; on a target
world's, what survives the gap.

    python experiments/sim2real/class_oracle.py \
        results/sim2real-governed-training/learned.jsonl [--episodes 15] [--frictions 6]

Each episode's class log-posterior is cached beside the recording (.oracle.json), so a
stopped run resumes. Each episode's filter is seeded by the episode's place in the
recording, so the answer for an episode does not depend on `--episodes` (caches from
before, seeded by the place among the episodes kept, are measured again).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from tqdm import tqdm

import masspush.bayes as bayes
from masspush.data import read_recording
from masspush.learn import density_for
from masspush.real import labelled
from masspush.settings import get_setting

CACHE_VERSION = 2
"""Version 2: each episode's filter seeded by its place in the recording."""


def read_cache(cache: Path, density: str | None = None) -> dict[str, list[float]]:
    """The cached log posteriors by episode id; none from a cache of another version or
    made with another likelihood (`density`: the learned one's digest, None the
    simulator's)."""
    stored = json.loads(cache.read_text()) if cache.exists() else {}
    same = stored.get("version") == CACHE_VERSION and stored.get("density") == density
    return stored.get("episodes", {}) if same else {}


def class_log_posteriors(
    recording, setting, pusher: str | None, classes: list[np.ndarray], frictions: np.ndarray,
    cache: Path, places: dict[str, int], density=None,
) -> dict[str, list[float]]:  # fmt: skip
    """Episode id -> log posterior of each class after the episode's pushes; `places`:
    each episode's place in the recording, its filter's seed; `density`: a learned push
    density to weigh the pushes with instead of simulating the robot."""
    digest = None if density is None else density.digest()
    done = read_cache(cache, digest)
    hypotheses = bayes.hypothesis_filter(setting, classes, frictions, pusher, density=density)
    try:
        for episode in tqdm(recording.episodes, desc="class oracle"):
            if episode["id"] in done:
                continue
            hypotheses.reset(episode["lengths"], episode=places[episode["id"]])
            hypotheses.filter.replay(episode["observations"], episode["actions"])
            w = hypotheses.weights()
            done[episode["id"]] = np.log(np.maximum(w, 1e-300)).tolist()
            cache.write_text(
                json.dumps({"version": CACHE_VERSION, "density": digest, "episodes": done})
            )
    finally:
        hypotheses.close()
    return done


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recording", help="a sim2real arm's recording (learned.jsonl, ...)")
    parser.add_argument("--episodes", type=int, default=15, help="per class, the first ones")
    parser.add_argument("--frictions", type=int, default=6, help="friction grid per class")
    parser.add_argument(
        "--cache", help="default: the recording's name with .oracle.json (.oracle-learned.json "
        "with --density)",
    )  # fmt: skip
    parser.add_argument(
        "--density", help="weigh pushes with this learned push density (`masspush "
        "train-density`) instead of simulating the robot for each hypothesis",
    )  # fmt: skip
    parser.add_argument(
        "--pusher",
        help="the robot the recording was made with, where not the setting's (e.g. ur10 for "
        "a recording made before the real settings' robot stood still)",
    )
    args = parser.parse_args()

    if args.episodes < 1:
        parser.error("--episodes must be at least 1")
    if args.frictions < 2:  # the filter holds 5 classes x frictions and needs 8 at least
        parser.error("--frictions must be at least 2")
    path = Path(args.recording)
    if not path.is_file():
        parser.error(f"recording: no such file {path}")
    try:
        recording = read_recording(path)
        setting = get_setting(recording.setting)
    except (KeyError, ValueError) as err:  # a RecordingError is a ValueError
        parser.error(f"recording {path}: {err}")
    counts: dict[str, int] = {}
    kept = []
    places = {episode["id"]: place for place, episode in enumerate(recording.episodes)}
    for episode in recording.episodes:
        counts[episode["label"]] = counts.get(episode["label"], 0) + 1
        if counts[episode["label"]] <= args.episodes:
            kept.append(episode)
    recording.episodes = kept
    labels, names = labelled(recording)
    by_label = {e["label"]: e["masses"] for e in kept}
    classes = [np.array(by_label[name], float) for name in names]
    frictions = bayes.friction_grid(setting, args.frictions)
    density = None
    if args.density is not None:
        try:
            density = density_for(args.density, setting.env_config(args.pusher))
        except ValueError as err:
            parser.error(f"--density: {err}")
    suffix = ".oracle.json" if density is None else ".oracle-learned.json"
    cache = Path(args.cache) if args.cache else path.with_suffix(suffix)
    try:  # before any episode is weighed: a cache that cannot be written loses them all
        if not cache.exists():
            cache.write_text(json.dumps({"version": CACHE_VERSION, "episodes": {}}))
        with cache.open("a"):
            pass
    except OSError as err:
        parser.error(f"cache: cannot write {cache} ({err.strerror})")
    posts = class_log_posteriors(
        recording, setting, args.pusher, classes, frictions, cache, places, density
    )

    guess = np.array([int(np.argmax(posts[e["id"]])) for e in kept])
    print(f"{path}: {len(kept)} episodes, {len(names)} classes x {args.frictions} frictions")
    print("| class | oracle's answers (by class) | right |")
    print("|---|---|---|")
    for c, name in enumerate(names):
        answers = np.bincount(guess[labels == c], minlength=len(names))
        right = answers[c] / max(1, (labels == c).sum())
        print(f"| {name} | {' '.join(map(str, answers))} | {100 * right:.0f} % |")
    print(
        f"oracle accuracy: {100 * np.mean(guess == labels):.1f} % (chance {100 / len(names):.0f} %)"
    )


if __name__ == "__main__":
    main()
