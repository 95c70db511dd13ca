"""Does the push's response tell the classes of a pair apart (issue 28)?

The learned policy's mistakes are within the pairs of classes whose light link differs by
0.05 of the mass; the two classes of a pair also differ in total mass (0.256 against
0.320 kg), which a force-limited arm could feel. Beside the predictor's features, this
gives the protocol's classifier (5-fold cross-validation) each push's response: the speed
the arm reached against the speed commanded, the speed itself, how far the chain's root
slid, and that slide per m/s.

    cd results/sim2real-governed-training
    python ../../experiments/sim2real/response_features.py learned.jsonl tp+
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from masspush.real import (
    ClassifierConfig,
    cross_validate,
    labelled,
    predictor_features,
    read_with_predictor,
)

PUSHES = 2
"""Pushes read per episode (the paper's protocol)."""


def responses(recording) -> np.ndarray:
    """(E, 4 x PUSHES): per push, reached / commanded speed, reached speed, the root's
    slide (m) and slide per m/s; zeros for pushes the episode does not have."""
    rows = []
    for episode in recording.episodes:
        obs = np.asarray(episode["observations"], float)
        actions = np.asarray(episode["actions"], float)
        speeds = np.asarray(episode.get("speeds", [np.nan] * len(actions)), float)
        row = []
        for t in range(PUSHES):
            if t >= len(actions):
                row += [0.0] * 4
                continue
            commanded = 5.0 * abs(actions[t, 0])
            slide = float(np.linalg.norm(obs[t + 1, :2] - obs[t, :2]))
            row += [speeds[t] / max(commanded, 1e-3), speeds[t], slide,
                    slide / max(speeds[t], 1e-3)]  # fmt: skip
        rows.append(row)
    return np.nan_to_num(np.array(rows, np.float32))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("recording", help="a sim2real arm's recording (learned.jsonl)")
    parser.add_argument("model", help="the predictor it was recorded with (tp+, rp or a file)")
    parser.add_argument("--setting", default="real-ur10")
    parser.add_argument(
        "--allow-mismatch",
        action="store_true",
        help="read a recording of another setting (same links)",
    )
    args = parser.parse_args(argv)
    try:
        recording, predictor, _, _ = read_with_predictor(
            args.recording, args.model, args.setting, args.allow_mismatch
        )
        labels, classes = labelled(recording)
    except (OSError, ValueError) as err:
        sys.exit(f"error: {' '.join(str(err).split())}")
    if not any("speeds" in e for e in recording.episodes):
        sys.exit(f"error: {args.recording} records no reached speeds ('speeds')")
    episodes = recording.to_episodes()
    response = responses(recording)
    config = ClassifierConfig()
    for kind in ("estimate", "lstm"):
        features = predictor_features(predictor, episodes, kind).astype(np.float32)
        for name, x in ((kind, features), (f"{kind} + response", np.hstack([features, response]))):
            score = cross_validate(x, labels, len(classes), config)
            print(f"{name}: {100 * score['accuracy']:.1f} %")
    score = cross_validate(response, labels, len(classes), config)
    print(f"response alone: {100 * score['accuracy']:.1f} % (chance {100 / len(classes):.0f} %)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
