"""Is the sim-to-real gap the learned predictor's, or any estimator's? The analysis behind
"The particle filter on the same recordings" in docs/notebook (sim-to-real).

    python experiments/sim2real/target_world_filter.py [--recording
    results/sim2real-4push/learned.jsonl]
        [--episodes 30] [--cache results/sim2real-4push/learned.filter.json]

The particle filter (`masspush.bayes.filter`, simulating the UR10 in the training world's physics)
replays each labelled episode of a `masspush sim2real` recording: the pushes the policy
made and the poses the target world's tracker reported. Its posterior median after the
last push is the classifier's feature (its log, as for TP+'s "estimate" features), and the
classifier is cross-validated on it exactly as `masspush sim2real` does on TP+'s estimate
of the same episodes. Prints per class the mean +- std of link 1's share under both, and
the classifier's accuracy on each estimate and on the two side by side. Each episode's
posterior is cached, so a stopped run resumes.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

import masspush.bayes as bayes
from masspush.data import read_recording
from masspush.learn import load_model
from masspush.models import resolve_model
from masspush.real import ClassifierConfig, cross_validate, labelled, predictor_features
from masspush.settings import get_setting


def filter_shares(recording, setting, cache: Path) -> dict[str, list[float]]:
    """Episode id -> the filter's posterior median after the episode's last seen push."""
    done = json.loads(cache.read_text()) if cache.exists() else {}
    filt = bayes.filter_for(setting, seed=0)
    try:
        for i, episode in enumerate(tqdm(recording.episodes, desc="filter on the recording")):
            if episode["id"] in done:
                continue
            # A stream per episode: a resumed run gives what an uninterrupted one does.
            filt.rng = np.random.default_rng([31, i])
            filt.reset(np.array(episode["lengths"], float))
            posterior = filt.replay(episode["observations"], episode["actions"])
            done[episode["id"]] = posterior.median.tolist()
            cache.write_text(json.dumps(done))
    finally:
        filt.close()
    return done


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--recording", default="results/sim2real-4push/learned.jsonl")
    parser.add_argument("--model", default="tp+", help="the learned model beside the filter")
    parser.add_argument("--episodes", type=int, default=30, help="per class, the first ones")
    parser.add_argument("--cache", help="default: the recording's name with .filter.json")
    args = parser.parse_args()

    path = Path(args.recording)
    recording = read_recording(path)
    setting = get_setting(recording.setting)
    counts: dict[str, int] = {}
    kept = []
    for episode in recording.episodes:
        counts[episode["label"]] = counts.get(episode["label"], 0) + 1
        if counts[episode["label"]] <= args.episodes:
            kept.append(episode)
    recording.episodes = kept
    cache = Path(args.cache) if args.cache else path.with_suffix(".filter.json")
    start = time.perf_counter()
    shares = filter_shares(recording, setting, cache)
    seconds = time.perf_counter() - start

    labels, classes = labelled(recording)
    predictor, _ = load_model(resolve_model(args.model, setting.name), setting.name)
    learned = predictor_features(predictor, recording.to_episodes(), "estimate")
    filtered = np.log(np.maximum([shares[e["id"]] for e in recording.episodes], 1e-6))
    config = ClassifierConfig(features="estimate")
    print(f"{path}: {len(kept)} episodes, filter {seconds:.0f} s (cached ones not timed)")
    print("| class | filter: link 1's share | " + args.model + ": link 1's share |")
    print("|---|---|---|")
    for c, name in enumerate(classes):
        f, m = np.exp(filtered[labels == c, 0]), np.exp(learned[labels == c, 0])
        print(f"| {name} | {f.mean():.3f} +- {f.std():.3f} | {m.mean():.3f} +- {m.std():.3f} |")
    truth = np.array([e["masses"][0] / sum(e["masses"]) for e in recording.episodes])
    r = np.corrcoef(np.exp(filtered[:, 0]) - truth, np.exp(learned[:, 0]) - truth)[0, 1]
    print(f"correlation of the two estimates' errors in link 1's share: {r:.2f}")
    both = np.hstack([filtered, learned])
    for name, features in (("filter", filtered), (args.model, learned), ("both", both)):
        result = cross_validate(features.astype(np.float32), labels, len(classes), config)
        print(f"classifier on {name} estimates: {100 * result['accuracy']:.1f} %")


if __name__ == "__main__":
    main()
