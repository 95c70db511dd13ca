"""Does the classifier read the masses, or recognise each class's object? The check behind
"Reading each run on its own" in docs/notebook (sim-to-real).

    python experiments/sim2real/lab_objects_alike.py [--labs 0,1,2,3,4] [--segments 8] [--arms
    learned]
        [--out results/sim2real-4push-lab-alike]

In a lab (`target_world.Lab`) each class's object has centres of mass of its own, up to the
target world's `com_offset` off the links' middles, as five real objects would; a classifier
trained and tested on the same five objects may tell them apart by that alone. Here every
object of a lab gets the same offsets (the lab's draw for its first class), so the objects
differ only in their masses, and the paper's protocol is run as `masspush sim2real --lab L
--segments K` would run it (its seeds; recordings kept in `--out/<lab>/` and reused).
"""

import argparse
import json
from pathlib import Path
from unittest import mock

import numpy as np

from masspush.real import ARMS, PAPER_CLASSES, Lab, Sim2RealConfig, record_arm, score_arm

FIRST_CLASS = next(iter(PAPER_CLASSES.values()))
LAB_OFFSETS = Lab.com_offsets


def alike_offsets(lab: Lab, masses: np.ndarray) -> np.ndarray:
    """The offsets the lab gives its first class's object, whatever the masses."""
    return LAB_OFFSETS(lab, np.asarray(FIRST_CLASS, dtype=float))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--setting", default="real-ur10-4push")
    parser.add_argument("--labs", default="0,1,2,3,4")
    parser.add_argument("--segments", type=int, default=8)
    parser.add_argument("--arms", default="learned", help="comma-separated, of: random, learned")
    parser.add_argument("--out", default="results/sim2real-4push-lab-alike")
    args = parser.parse_args()
    arms = args.arms.split(",")
    if not set(arms) <= set(ARMS):
        parser.error(f"--arms must name some of {list(ARMS)}")
    for lab in (int(x) for x in args.labs.split(",")):
        out = Path(args.out) / str(lab)
        out.mkdir(parents=True, exist_ok=True)
        config = Sim2RealConfig(setting=args.setting, lab=lab, segments=args.segments)
        name = (
            f"masspush target world, lab {lab}, objects alike but for their masses, "
            f"{args.segments} runs of the policy per episode"
        )
        results = {}
        with mock.patch.object(Lab, "com_offsets", alike_offsets):
            for arm in arms:
                path = out / f"{arm}.jsonl"
                record_arm(config, arm, path, robot_name=f"{name}, {config.models[arm]}")
                results[arm] = score_arm(config, arm, path)
        (out / "summary.json").write_text(json.dumps(results, indent=2) + "\n")
        for arm, scores in results.items():
            line = ", ".join(
                f"{kind} {100 * scores[kind]['accuracy']:.1f} %"
                for kind in scores
                if isinstance(scores[kind], dict) and "accuracy" in scores[kind]
            )
            print(f"lab {lab}, {arm}: {line}", flush=True)


if __name__ == "__main__":
    main()
