"""Does reading the speed the robot reports protect the models from a robot slower or faster
than theirs? The paper's protocol (2 pushes, 150 chains, `real-ur10`) in one lab of the
target world whose robot pushes at `gain` times the commanded speed (the target world draws
U(0.85, 1.15) per lab; here it is fixed), each model reading the pushes at the reported
speeds and as commanded (`Sim2RealConfig.read_speeds`). Same chains and seeds in every row;
only the learned arm is run; a learned predictor's recording is made once and read both
ways, the particle filter reads during the episode and is recorded for each.

    python experiments/sim2real/speed_gain_reading.py [--lab 5] [--gains 0.6,1.0]
        [--models bayes,tp+] [--out results/sim2real-speed-gain-reading]

Recordings are kept in `--out/<lab>/` and reused; prints one row per gain and model.
"""

import argparse
import json
from pathlib import Path

from masspush.bayes import BAYES_MODELS
from masspush.models import resolve_model
from masspush.real import Sim2RealConfig, TargetWorld, record_arm, score_arm

SETTING = "real-ur10"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--lab", type=int, default=5)
    parser.add_argument("--gains", default="0.6,1.0")
    parser.add_argument("--models", default="bayes,tp+")
    parser.add_argument("--out", default="results/sim2real-speed-gain-reading")
    args = parser.parse_args()
    try:
        gains = [float(g) for g in args.gains.split(",")]
    except ValueError:
        parser.error(f"--gains: comma-separated numbers, got {args.gains!r}")
    if any(not 0.1 <= g <= 2.0 for g in gains):
        parser.error("--gains must lie in [0.1, 2]")
    if args.lab < 0:
        parser.error("--lab must be >= 0")
    models = args.models.split(",")
    for model in models:
        if model not in BAYES_MODELS:
            try:
                resolve_model(model, SETTING)
            except ValueError as err:
                parser.error(f"--models: {err}")
    out = Path(args.out) / str(args.lab)
    try:  # before any episode: a bad --out is said at once
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        parser.error(f"--out: cannot make {out}: {err.strerror}")
    print("| lab | speed gain | model | read as commanded | read at the reported speed |")
    print("|---|---|---|---|---|")
    for gain in gains:
        world = TargetWorld(speed_gain=(gain, gain))
        for model in models:
            row = {}
            for read in (False, True):
                config = Sim2RealConfig(setting=SETTING, lab=args.lab, read_speeds=read,
                                        models={"random": "rp", "learned": model})  # fmt: skip
                filtered = model in BAYES_MODELS
                reading = "read" if read else "commanded"
                stem = f"{model}-gain{gain:g}"
                name = f"masspush target world, lab {args.lab}, speed gain {gain:g}, {model}"
                if filtered:  # the filter's recorded estimates depend on the reading
                    stem += f"-{reading}"
                    name += ", speeds read" if read else ", speeds not read"
                path = out / f"{stem}.jsonl"
                kept = record_arm(config, "learned", path, progress=False, target=world,
                                  robot_name=name)  # fmt: skip
                row[read] = score_arm(config, "learned", path)
                (out / f"{model}-gain{gain:g}-{reading}.json").write_text(
                    json.dumps({"kept": kept, "scores": row[read]}) + "\n"
                )
            cells = [f"{100 * row[r]['estimate']['accuracy']:.1f} %" for r in (False, True)]
            print(f"| {args.lab} | {gain:g} | {model} | {cells[0]} | {cells[1]} |", flush=True)


if __name__ == "__main__":
    main()
