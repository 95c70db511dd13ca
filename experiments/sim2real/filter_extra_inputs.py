"""Do other inputs beside the particle filter's estimate sort its episodes better?

For a filter arm's recording (`masspush sim2real --learned-model bayes`, its `estimates`
after every good push), the protocol's classifier cross-validated on: the filter's final
estimate (what the protocol reads); the shipped TP+ predictor's estimate and LSTM output on
the same pushes (each run of 2 read on its own where the episode has more), alone and
beside the filter's estimate; and the filter's estimates after 2, 4, 8 and 16 pushes
together. For docs/notebook/2026-12-05-governor-fit-size.md:

    python experiments/sim2real/filter_extra_inputs.py \\
        results/sim2real-bayes-placed/lab5/learned.jsonl \\
        results/sim2real-filter-gap-parts/6/none-8runs.jsonl
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from masspush.data import read_recording
from masspush.models import model_and_policy
from masspush.real import ClassifierConfig, classifier_inputs, cross_validate, labelled

SETTING = "real-ur10"
RUN = 2
"""Pushes per run of the policy in the setting's protocol."""


def accuracies(path: Path, predictor) -> dict[str, float]:
    recording = read_recording(path)
    episodes = recording.to_episodes()
    labels, classes = labelled(recording)
    estimates = [np.asarray(e.get("estimates", []), float) for e in recording.episodes]
    if any(len(e) == 0 for e in estimates):
        raise ValueError(f"{path}: an episode has no estimates; is it a filter arm's recording?")

    def after(p: int) -> np.ndarray:
        return np.log([e[min(p, len(e)) - 1] for e in estimates])

    def score(x: np.ndarray, cfg: ClassifierConfig, owner=None) -> float:
        return cross_validate(x.astype(np.float32), labels, len(classes), cfg, owner)["accuracy"]

    base = ClassifierConfig()
    final = after(max(len(e) for e in estimates))
    out = {"filter": score(final, base)}
    segment = RUN if episodes.actions.shape[1] > RUN else 0
    for kind in ("estimate", "lstm"):
        cfg = replace(base, features=kind, segment=segment)
        x, owner = classifier_inputs(predictor, episodes, cfg)
        out[f"TP+ {kind}"] = score(x, cfg, owner)
        out[f"filter + TP+ {kind}"] = score(np.concatenate([x, final[owner]], 1), cfg, owner)
    if episodes.actions.shape[1] >= 16:
        out["filter after 2, 4, 8, 16"] = score(
            np.concatenate([after(p) for p in (2, 4, 8, 16)], 1), base
        )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recordings", nargs="+", type=Path)
    args = parser.parse_args()
    predictor, _, _ = model_and_policy("tp+", SETTING)
    try:
        for path in args.recordings:
            row = ", ".join(f"{k} {100 * v:.1f} %" for k, v in accuracies(path, predictor).items())
            print(f"{path}: {row}", flush=True)
    except (OSError, ValueError) as err:
        sys.exit(f"error: {err}")


if __name__ == "__main__":
    main()
