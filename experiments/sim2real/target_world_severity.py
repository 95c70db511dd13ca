"""How close to the simulation must a lab be? The analysis behind "How close to the
simulation a lab must be" in docs/notebook (sim-to-real).

    python experiments/sim2real/target_world_severity.py [--setting real-ur10-4push] [--model tp+]
        [--rows solver-and-cones,...] [--out results/sim2real-4push-severity/split]

`masspush sim2real --severity S` scales all of the target world's differences at once, but
the solver and the friction cones cannot be scaled: they are the target world's for any
severity above 0. This script separates them: each row is a world between the training
world and the target world, in which the learned arm of the paper's protocol (`sim2real`'s
seeds, 30 episodes per class) is recorded and its classifier cross-validated. Recordings
are kept in `--out` (one per row) and reused when run again.
"""

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

from masspush.real import (
    TRAINING_KNOBS,
    Sim2RealConfig,
    TargetWorld,
    record_arm,
    scaled_world,
    score_arm,
)

UNSCALED = ("solver", "solver_iterations", "cone")
"""The knobs `scaled_world` cannot move by degrees (the iterations go with the solver)."""


def numbers_only(severity: float) -> TargetWorld:
    """Every numeric difference scaled; the training world's solver and cones."""
    return replace(scaled_world(severity), **{k: TRAINING_KNOBS[k] for k in UNSCALED})


TARGET = TargetWorld()
ROWS = {
    "solver-and-cones": replace(scaled_world(0), **{k: getattr(TARGET, k) for k in UNSCALED}),
    "pyramidal-cones": replace(scaled_world(0), cone=TARGET.cone),
    "numbers-0.25": numbers_only(0.25),
    "numbers-0.5": numbers_only(0.5),
    "numbers-1": numbers_only(1.0),
    "target-elliptic-cones": replace(TARGET, cone=TRAINING_KNOBS["cone"]),
}
"""Worlds of the analysis: the differences from training that each row keeps."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--setting", default="real-ur10-4push")
    parser.add_argument("--model", default="tp+")
    parser.add_argument("--rows", default=",".join(ROWS))
    parser.add_argument("--out", default="results/sim2real-4push-severity/split")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    config = Sim2RealConfig(setting=args.setting, models={"random": "rp", "learned": args.model})
    print("| world | accuracy, learned arm | predictor error | failed pushes | s |")
    print("|---|---|---|---|---|")
    for row in args.rows.split(","):
        start = time.perf_counter()
        path = out / f"{row}.jsonl"
        name = f"masspush target world ({row}), {args.model}"
        counts = record_arm(config, "learned", path, target=ROWS[row], robot_name=name)
        scores = score_arm(config, "learned", path)
        print(
            f"| {row} | {100 * scores['estimate']['accuracy']:.1f} % "
            f"| {scores['percentage_error']:.2f} | {json.dumps(counts['failed_pushes'])} "
            f"| {time.perf_counter() - start:.0f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
