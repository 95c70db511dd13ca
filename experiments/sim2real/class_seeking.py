"""Would pushes chosen to tell the paper's five classes apart lift the class oracle's ceiling?

Issue 28's goals (81.4 % at 2 pushes) stand above what the class oracle
(`class_oracle.py`) reaches with the stationary UR10's learned pushes (66.7 % in the
training world). This probe chooses each push for the classes instead: the particle filter
holds exactly the five classes, each at a grid of table frictions (as the oracle does), and
each push is the candidate (uniform over the action space, passed through the robot's speed
governor, as any push of the stationary robot is) that leaves the smallest expected Gini
impurity of the class posterior (`ParticleFilter.expected_variance` with one-hot class
values). The same filter's final posterior names the class. The chains are those of
`masspush sim2real --setting real-ur10 --world training` (the same seeds, class by class),
so the answers pair with the oracle's on that recording's learned and random pushes.

    python experiments/sim2real/class_seeking.py --episodes 10 [--candidates 8] \
        [--pushes 2] [--out results/class-seeking.json]

An upper bound's probe, not a policy to ship: it knows the classes and the training world's
physics. Each finished episode is kept in --out, so a stopped run resumes.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

import masspush.bayes as bayes
from masspush.learn import density_for
from masspush.real import (
    PAPER_CLASSES,
    ClassifierConfig,
    class_episodes,
    cross_validate,
)
from masspush.settings import get_setting
from masspush.sim import reach_governor


def class_filter(setting, frictions: int, lookahead: int, density=None) -> bayes.HypothesisFilter:
    """The filter whose particles are the five classes x `frictions` table frictions,
    weighing pushes by simulating the robot, or with a learned push `density`."""
    classes = list(PAPER_CLASSES.values())
    grid = bayes.friction_grid(setting, frictions)
    return bayes.hypothesis_filter(setting, classes, grid, lookahead=lookahead, density=density)


def run_config(args) -> dict:
    """What the episodes kept in --out depend on: a rerun resumes only with the same."""
    keys = ("policy", "candidates", "lookahead", "frictions", "pushes", "seed", "density", "lab",
            "chains", "start_range")  # fmt: skip
    return {k: getattr(args, k) for k in keys}


def run(args, density=None) -> dict:
    """The episodes asked for (`--episodes` per class) by id, measured or kept in --out."""
    setting = get_setting("real-ur10")
    if (
        args.start_range is not None
    ):  # the chain put down on the lab's spot (`sim2real --start-range`)
        setting = replace(
            setting, overrides={**setting.overrides, "root_xy_range": args.start_range}
        )
    governor = reach_governor(setting.pusher, setting.physics())
    classes = class_filter(setting, args.frictions, args.lookahead, density)
    filt, onehot = classes.filter, classes.onehot
    n = len(PAPER_CLASSES)
    out, config = Path(args.out), run_config(args)
    done = json.loads(out.read_text())["episodes"] if out.exists() else {}
    bar, asked = tqdm(total=n * args.episodes, desc=args.policy), []
    try:
        # The chains of `masspush sim2real --world training --seed CHAINS` (or --lab L)
        chains = class_episodes(setting, args.episodes, args.chains, args.lab, args.pushes)
        for c, i, key, robot, pose in chains:
            asked.append(key)
            if key in done:
                bar.update()
                continue
            t0 = time.perf_counter()
            classes.reset(pose.lengths, episode=c * 1000 + i)
            rng = np.random.default_rng([args.seed, c, i])
            start, actions, lost = np.asarray(pose.config, float), [], None
            poses = [start.tolist()]
            for _ in range(args.pushes):
                cand = rng.uniform(-1, 1, (args.candidates, 2))
                cand = np.array([governor(a, start, pose.lengths) for a in cand], float)
                if args.policy == "random":  # the first candidate: a governed random push
                    action = cand[0]
                else:
                    scores = filt.expected_variance(start, cand, values=onehot)
                    action = cand[int(np.argmin(scores))]
                report = robot.push(action)
                if report.failure is not None:
                    lost = report.failure
                    break
                observed = np.asarray(report.config, float)
                with warnings.catch_warnings():  # tempered quietly, as `replay` does
                    warnings.simplefilter("ignore", bayes.UnexplainedObservationWarning)
                    filt.update(start, action, observed)
                actions.append(action.tolist())
                poses.append(observed.tolist())
                start = observed
            done[key] = {
                "label": c, "posterior": classes.weights().tolist(), "actions": actions,
                "poses": poses, "lengths": np.asarray(pose.lengths, float).tolist(),
                "failure": lost, "seconds": time.perf_counter() - t0,
            }  # fmt: skip
            out.write_text(json.dumps({"config": config, "episodes": done}))
            bar.update()
    finally:
        bar.close()
        classes.close()
    return {key: done[key] for key in asked}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=10, help="per class")
    parser.add_argument("--candidates", type=int, default=8, help="candidate pushes per push")
    parser.add_argument(
        "--policy", choices=("class-seeking", "random"), default="class-seeking",
        help="random: uniform random pushes through the governor, weighed by the same oracle",
    )  # fmt: skip
    parser.add_argument("--lookahead", type=int, default=20, help="lookahead particles")
    parser.add_argument("--frictions", type=int, default=8, help="friction grid per class")
    parser.add_argument("--pushes", type=int, default=2)
    parser.add_argument(
        "--lab", type=int, help="push in this lab of the target world (`masspush sim2real "
        "--lab`) instead of the training world",
    )  # fmt: skip
    parser.add_argument("--seed", type=int, default=0, help="the candidates' randomness")
    parser.add_argument(
        "--chains", type=int, default=0, help="the chains' seed (`masspush sim2real --seed`)"
    )
    parser.add_argument(
        "--start-range", type=float, default=None,
        help="put each chain down within this many m of the origin (`masspush sim2real "
        "--start-range`)",
    )  # fmt: skip
    parser.add_argument("--out", default="results/class-seeking.json")
    parser.add_argument(
        "--density", help="weigh pushes with this learned push density (`masspush "
        "train-density`) instead of simulating the robot for each hypothesis",
    )  # fmt: skip
    args = parser.parse_args()
    # The filter holds 5 classes x --frictions particles and needs 8 at least, and 4
    # lookahead particles: said here, before --out is written.
    least = {"episodes": 1, "candidates": 1, "lookahead": 4, "frictions": 2, "pushes": 1}
    for name, low in least.items():
        if getattr(args, name) < low:
            parser.error(f"--{name} must be at least {low}")
    if args.start_range is not None and not 0 <= args.start_range <= 1:
        parser.error("--start-range must be in [0, 1] m")
    for name in ("lab", "chains", "seed"):  # seeds of worlds and chains
        if (getattr(args, name) or 0) < 0:
            parser.error(f"--{name} must be at least 0")
    density, setting = None, get_setting("real-ur10")
    if args.density is not None:
        try:
            density = density_for(args.density, setting.env_config())
        except ValueError as err:
            parser.error(f"--density: {err}")
    out = Path(args.out)
    try:  # before any episode: a file that cannot be read or written loses them all
        if out.exists():
            kept = {
                "density": None,
                "lab": None,
                "chains": 0,
                "start_range": None,
                **json.loads(out.read_text())["config"],
            }
            if kept != run_config(args):
                parser.error(f"--out: {out} holds episodes made with {kept}; use another file")
        else:
            out.write_text(json.dumps({"config": run_config(args), "episodes": {}}))
        with out.open("a"):
            pass
    except (OSError, ValueError, KeyError, TypeError) as err:
        parser.error(f"--out: cannot use {out} ({getattr(err, 'strerror', None) or err})")
    done = run(args, density)
    labels = np.array([e["label"] for e in done.values()])
    guess = np.array([int(np.argmax(e["posterior"])) for e in done.values()])
    lost = sum(e["failure"] is not None for e in done.values())
    names = list(PAPER_CLASSES)
    print("| class | answers (by class) | right |")
    print("|---|---|---|")
    for c, name in enumerate(names):
        answers = np.bincount(guess[labels == c], minlength=len(names))
        print(f"| {name} | {' '.join(map(str, answers))} | "
              f"{100 * answers[c] / max(1, (labels == c).sum()):.0f} % |")  # fmt: skip
    seconds = np.mean([e["seconds"] for e in done.values()])
    accuracy = 100 * np.mean(guess == labels)
    print(f"{args.policy} pushes, class oracle: {accuracy:.1f} % of {len(labels)} episodes, "
          f"{lost} lost, {seconds:.1f} s an episode")  # fmt: skip
    # The protocol's classifier (5-fold cross-validated) on the filter's class log-posteriors:
    # where the oracle's likelihood is off (another world), the labels re-map it.
    logs = np.log(np.maximum([e["posterior"] for e in done.values()], 1e-300))
    if min(np.bincount(labels, minlength=len(names))) >= ClassifierConfig().folds:
        scored = cross_validate(logs, labels, len(names), ClassifierConfig())
        print(f"classifier on the class log-posteriors: {100 * scored['accuracy']:.1f} %")


if __name__ == "__main__":
    main()
