"""A classifier trained on one lab's episodes, applied to another lab's: does it read the
masses, or that lab and its five objects? The table in docs/notebook ("Reading each run
on its own").

    python experiments/sim2real/sim2real_cross_lab.py results/sim2real-4push-lab-32push/{0,1,2,3,4}
    \\
        [--arm learned] [--features lstm] [--runs each]

Each directory is a `masspush sim2real --lab L --segments K` output. The classifier is
trained on all of one directory's episodes of `--arm` (as `masspush finetune` would) and
applied to every directory's (as `masspush classify` would); on the diagonal it has seen the
episodes, so read the diagonal from the sim2real summaries (cross-validated) instead.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from masspush.data import read_recording
from masspush.learn import load_model
from masspush.models import resolve_model
from masspush.real import (
    ClassifierConfig,
    classifier_inputs,
    episode_log_probs,
    fit_classifier,
    labelled,
    read_summary,
)
from masspush.settings import get_setting


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="sim2real output directories")
    parser.add_argument("--arm", default="learned", choices=("learned", "random"))
    parser.add_argument("--features", default="lstm", choices=("estimate", "lstm"))
    parser.add_argument("--runs", dest="reading", default="each", choices=("each", "average"))
    args = parser.parse_args()
    try:
        summaries = [read_summary(run) for run in args.runs]
    except ValueError as err:
        parser.error(str(err))
    setting = {s["config"]["setting"] for s in summaries}
    if len(setting) != 1:
        raise SystemExit(f"the directories hold different settings: {sorted(setting)}")
    setting = setting.pop()
    model = summaries[0]["arms"][args.arm]["model"]
    predictor = load_model(resolve_model(model, setting), setting)[0]
    config = ClassifierConfig(
        features=args.features,
        segment=get_setting(setting).env_config().pushes,
        runs=args.reading,
    )
    data = []
    for run in args.runs:
        recording = read_recording(run / f"{args.arm}.jsonl")
        labels, classes = labelled(recording)
        data.append((*classifier_inputs(predictor, recording.to_episodes(), config), labels))
    names = [f"lab {s['config']['lab']}" for s in summaries]
    print(f"{args.arm} arm, {args.features} features, runs read: {args.reading}; rows: trained "
          "on, columns: applied to")  # fmt: skip
    print("| trained on \\ applied to | " + " | ".join(names) + " |")
    print("|---" * (len(names) + 1) + "|")
    for name, (features, owner, labels) in zip(names, data, strict=True):
        classifier = fit_classifier(features, labels[owner], len(classes), config)
        cells = []
        for other, (f, o, y) in zip(names, data, strict=True):
            guess = episode_log_probs(classifier, f, o, len(y)).argmax(1)
            cell = f"{100 * np.mean(guess == y):.1f} %"
            cells.append(f"({cell})" if other == name else cell)
        print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
