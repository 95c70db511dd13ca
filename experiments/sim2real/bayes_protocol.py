"""The paper's real-robot protocol with the particle filter in place of the learned policy and
predictor: does it sort the five classes better than the shipped `real-ur10` models?

For each class (the paper's five mass pairs, 30 episodes by default) the stationary UR10
pushes the chain with the filter's information-seeking pushes (each candidate passed through
the robot's speed governor, as any push of this robot is), the filter weighing every push
with the learned push density (`masspush train-density` on the stationary UR10's own
episodes). The filter knows nothing of the classes: it estimates the mass distribution, as
the learned predictor does. Its estimate (the log of the posterior median, the protocol's
"estimate" features) after 1, 2, 4, ... pushes feeds the protocol's classifier, 5-fold
cross-validated (`masspush.real.cross_validate`); every episode with at least one good push
is kept and classified from the pushes it has; lost chains are counted, and the start-pose
control classifier is reported beside it. The chains are those of `masspush sim2real` (the
same seeds, class by class) in the training world or in one lab of the target world.

    python experiments/sim2real/bayes_protocol.py --density runs/density/real-ur10-placed.pt \
        --pushes 16 [--lab 5 [--governor-fit RANDOM.jsonl]] [--episodes 30] \
        [--out results/bayes-protocol.json]

Each finished episode is kept in --out, so a stopped run resumes. The same protocol is now an
arm of `masspush sim2real` (`--learned-model bayes [--density FILE]`), with its recordings and
summary; this script stays to rerun the numbers of 2026-12-04's notebook.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from tqdm import tqdm

import masspush.bayes as bayes
from masspush.learn import density_for
from masspush.real import (
    PAPER_CLASSES,
    ClassifierConfig,
    class_episodes,
    cross_validate,
    fit_governor,
    start_pose_features,
)
from masspush.settings import get_setting
from masspush.sim import reach_governor

SETTING = "real-ur10"


def run_config(args) -> dict:
    """What the episodes kept in --out depend on: a rerun resumes only with the same."""
    keys = ("density", "pushes", "lab", "chains", "seed", "governor_fit")
    return {k: getattr(args, k) for k in keys}


def run(args, density) -> dict:
    """The episodes asked for (`--episodes` per class) by id, measured or kept in --out."""
    setting = get_setting(SETTING)
    governor = reach_governor(setting.pusher, setting.physics())
    if args.governor_fit is not None:  # its slide bounds fitted to the lab's random pushes
        governor = fit_governor(governor, args.governor_fit)
    config = bayes.default_config(setting, likelihood="learned")
    filt = bayes.filter_for(setting, config=config, seed=args.seed, density=density)
    policy = bayes.InfoSeekingPolicy(filt, args.seed, governor)
    out = Path(args.out)
    done = json.loads(out.read_text())["episodes"] if out.exists() else {}
    bar, asked = tqdm(total=len(PAPER_CLASSES) * args.episodes, desc="filter"), []
    try:
        # The chains of `masspush sim2real --world training --seed CHAINS` (or --lab L)
        chains = class_episodes(setting, args.episodes, args.chains, args.lab, args.pushes)
        for c, i, key, robot, pose in chains:
            asked.append(key)
            if key in done:
                bar.update()
                continue
            t0 = time.perf_counter()
            filt.reset(np.asarray(pose.lengths, float), episode=c * 1000 + i)
            policy.reset(c * 1000 + i)
            start = np.asarray(pose.config, float)
            estimates, lost = [], None
            for _ in range(args.pushes):
                action = policy.act(start)
                report = robot.push(action)
                if report.failure is not None:
                    lost = report.failure
                    break
                observed = np.asarray(report.config, float)
                estimates.append(filt.update(start, action, observed).estimate.tolist())
                start = observed
            done[key] = {
                "label": c, "estimates": estimates, "failure": lost,
                "start": np.asarray(pose.config, float).tolist(),
                "lengths": np.asarray(pose.lengths, float).tolist(),
                "seconds": time.perf_counter() - t0,
            }  # fmt: skip
            out.write_text(json.dumps({"config": run_config(args), "episodes": done}))
            bar.update()
    finally:
        bar.close()
        filt.close()
    return {key: done[key] for key in asked}


def report(done: dict, pushes: int) -> None:
    """Accuracy after 1, 2, 4, ... pushes, the losses and the start-pose control."""
    kept = [e for e in done.values() if e["estimates"]]
    labels = np.array([e["label"] for e in kept])
    n = len(PAPER_CLASSES)
    config = ClassifierConfig()
    lost = sum(e["failure"] is not None for e in done.values())
    at = sorted(len(e["estimates"]) + 1 for e in done.values() if e["failure"])
    print(f"{len(done)} episodes, {len(kept)} with a good push, {lost} lost the chain "
          f"(at push {at})")  # fmt: skip
    if np.bincount(labels, minlength=n).min() < config.folds:
        print("too few kept episodes per class to cross-validate")
        return
    k = 1
    while k <= pushes:
        # An episode lost before push k is classified from the pushes it has.
        features = np.log([e["estimates"][min(k, len(e["estimates"])) - 1] for e in kept])
        scored = cross_validate(features, labels, n, config)
        print(f"after {k} pushes: {100 * scored['accuracy']:.1f} % (estimate features)")
        k *= 2
    # The protocol's control: the same classifier on each episode's start pose alone.
    starts = SimpleNamespace(observations=np.array([[e["start"]] for e in kept]),
                             lengths=np.array([e["lengths"] for e in kept]))  # fmt: skip
    scored = cross_validate(start_pose_features(starts), labels, n, config)
    print(f"start-pose control: {100 * scored['accuracy']:.1f} %")
    seconds = np.mean([e["seconds"] for e in done.values()])
    print(f"{seconds:.1f} s an episode")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--density", required=True, help="the stationary UR10's push density")
    parser.add_argument("--episodes", type=int, default=30, help="per class")
    parser.add_argument("--pushes", type=int, default=2)
    parser.add_argument("--lab", type=int, help="one lab of the target world (sim2real --lab)")
    parser.add_argument("--chains", type=int, default=0, help="the chains' seed (sim2real --seed)")
    parser.add_argument("--seed", type=int, default=0, help="the filter's and policy's seed")
    parser.add_argument(
        "--governor-fit", help="a recording of random pushes in the same world (e.g. a "
        "`masspush sim2real` run's random.jsonl): the governor's bounds fitted to it",
    )  # fmt: skip
    parser.add_argument("--out", default="results/bayes-protocol.json")
    args = parser.parse_args()
    for name in ("episodes", "pushes"):
        if getattr(args, name) < 1:
            parser.error(f"--{name} must be at least 1")
    for name in ("lab", "chains", "seed"):  # seeds of worlds and chains
        if (getattr(args, name) or 0) < 0:
            parser.error(f"--{name} must be at least 0")
    setting = get_setting(SETTING)
    try:
        density = density_for(args.density, setting.env_config())
    except ValueError as err:
        parser.error(f"--density: {err}")
    if args.governor_fit is not None:
        try:
            fit_governor(reach_governor(setting.pusher, setting.physics()), args.governor_fit)
        except ValueError as err:
            parser.error(f"--governor-fit: {err}")
    out = Path(args.out)
    try:  # before any episode: a file that cannot be read or written loses them all
        if out.exists():
            kept = {"governor_fit": None, **json.loads(out.read_text())["config"]}
            if kept != run_config(args):
                parser.error(f"--out: {out} holds episodes made with {kept}; use another file")
        else:
            out.write_text(json.dumps({"config": run_config(args), "episodes": {}}))
        with out.open("a"):
            pass
    except (OSError, ValueError, KeyError, TypeError) as err:
        parser.error(f"--out: cannot use {out} ({getattr(err, 'strerror', None) or err})")
    report(run(args, density), args.pushes)


if __name__ == "__main__":
    main()
