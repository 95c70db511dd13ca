"""The particle filter arm's recorded pushes replayed through the filter twice, reading each
push as commanded and at the speed the robot reported (`masspush.real.speed_reader`): how
the reading alone changes the protocol's accuracy, the pushes held fixed (a live run with
another reading also chooses other pushes from its second push on).

    python experiments/sim2real/replay_speed_reading.py RECORDING [--pushes 2,4,16]
        [--fold-seeds 5]

RECORDING: a filter arm's `learned.jsonl` from `masspush sim2real --learned-model bayes`
(its episodes keep their speeds). Prints the protocol classifier's accuracy on the filter's
estimate after each number of pushes, averaged over `--fold-seeds` seeds of the folds.
"""

import argparse
import warnings
from pathlib import Path

import numpy as np
from tqdm import tqdm

from masspush.bayes import UnexplainedObservationWarning
from masspush.data import read_recording
from masspush.real import ClassifierConfig, FilterArm, cross_validate, labelled, speed_reader
from masspush.settings import get_setting


def replayed_estimates(recording, read: bool, seed: int = 0) -> list[np.ndarray]:
    """Each episode's filter estimates after each of its recorded pushes."""
    setting = get_setting(recording.setting)
    reader = speed_reader(setting.pusher, setting.physics()) if read else None
    actions = recording.to_episodes(reader).actions  # as the protocol's models read them
    arm = FilterArm.load("bayes", setting, seed)
    out = []
    try:
        for i, episode in enumerate(
            tqdm(recording.episodes, desc="read" if read else "as commanded")
        ):
            arm.filter.reset(np.asarray(episode["lengths"], float), episode=i)
            poses = np.asarray(episode["observations"], float)
            row = []
            with warnings.catch_warnings():  # a lab's outlier is weighed all the same
                warnings.simplefilter("ignore", UnexplainedObservationWarning)
                for k in range(len(episode["actions"])):
                    action = np.asarray(actions[i, k], float)
                    posterior = arm.filter.update(poses[k], action, poses[k + 1])
                    row.append(posterior.estimate)
            out.append(np.array(row))
    finally:
        arm.close()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recording", help="a filter arm's learned.jsonl")
    parser.add_argument("--pushes", default="2,4,16")
    parser.add_argument("--fold-seeds", type=int, default=5)
    args = parser.parse_args()
    try:
        pushes = [int(p) for p in args.pushes.split(",")]
    except ValueError:
        parser.error(f"--pushes: comma-separated whole numbers, got {args.pushes!r}")
    if min(pushes) < 1 or args.fold_seeds < 1:
        parser.error("--pushes and --fold-seeds must be at least 1")
    path = Path(args.recording)
    try:
        recording = read_recording(path)
    except (OSError, ValueError) as err:
        parser.error(f"recording: {'; '.join(str(err).splitlines()[:2])}")
    if not all(e.get("speeds") is not None and len(e["actions"]) for e in recording.episodes):
        parser.error(f"recording: {path} has episodes without pushes or speeds")
    labels, names = labelled(recording)
    print(f"| {path} | " + " | ".join(f"{p} pushes" for p in pushes) + " |")
    print("|---|" + "---|" * len(pushes))
    for read in (False, True):
        estimates = replayed_estimates(recording, read)
        cells = []
        for p in pushes:
            features = np.log([e[min(p, len(e)) - 1] for e in estimates])
            accuracy = [
                cross_validate(features, labels, len(names), ClassifierConfig(seed=s))["accuracy"]
                for s in range(args.fold_seeds)
            ]
            cells.append(f"{100 * np.mean(accuracy):.1f} %")
        reading = "at the reported speeds" if read else "as commanded"
        print(f"| read {reading} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
