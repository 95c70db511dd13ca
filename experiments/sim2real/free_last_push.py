"""Does the last push of an episode, which no later push needs room after, say more when the
stationary robot's speed governor lets it go as fast as the arm can?

The governor (`masspush.sim.ReachGovernor`) slows every push so that the chain comes to rest
where the next push can still be made. After the last push of an episode no push follows:
the chain only has to come to rest where the camera sees it, and the lab puts it back on the
marked spot for the next episode. This probe runs the particle-filter arm of `masspush
sim2real --learned-model bayes --check-reach --read-speeds` on the same chains twice, the
last push governed as now (`governed.jsonl`) and free (`free.jsonl`: neither the filter's
candidates nor the push is slowed, and a chain that comes to rest out of the reach after it
is observed there instead of counted lost), then sorts both by the class posterior of each
lab-tuned push density given (`--sort-with`), paired by chain (exact McNemar test). An
arm whose recording exists is reused. For docs/notebook/2026-12-06-free-last-push.md:

    python experiments/sim2real/free_last_push.py --lab 5 --seed 11 --per-class 40 \\
        --governor-fit results/sim2real-bayes-placed/lab5-seed0-16push-checked-fit/random.jsonl \\
        --sort-with results/lab-tuned-density/lab5-seed1-32push.pt \\
        --out results/free-last-push/lab5-seed11
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from masspush.data import Recording, read_recording, write_recording
from masspush.learn import load_push_density
from masspush.real import (
    PAPER_CLASSES,
    FilterArm,
    PushReport,
    TargetWorld,
    class_robot,
    episode_id,
    fit_governor,
    paired_test,
    posterior_accuracy,
    run_segments,
    speed_reader,
)
from masspush.settings import get_setting
from masspush.sim import ReachCheck, reach_governor


class LastPushFree:
    """A target-world robot whose governor, where `free`, lets the `pushes`-th push of each
    episode go unslowed, and which observes the chain wherever that push leaves it."""

    def __init__(self, robot, governor, pushes: int, free: bool):
        self.robot, self.base, self.pushes, self.free = robot, governor, pushes, free
        self.n_links, self.k = robot.n_links, 0

    def last(self) -> bool:
        """Whether the push about to be made is a free last push."""
        return self.free and self.k == self.pushes - 1

    @property
    def seed(self) -> int:
        return self.robot.seed

    @property
    def truth(self) -> dict:
        return self.robot.truth

    def governor(self, action, config, lengths) -> np.ndarray:
        if self.last():
            return np.asarray(action, np.float32)
        return self.base(action, config, lengths)

    def start(self):
        self.k = 0
        return self.robot.start()

    def push(self, action) -> PushReport:
        last = self.last()
        report = self.robot.push(action)
        self.k += 1
        if report.failure == "left_workspace" and last:
            # No push follows: the chain at rest out of reach is seen all the same.
            details = {**report.details, "outside": True}
            report = PushReport(self.robot.observe(), None, details, report.speed)
        return report

    def close(self) -> None:
        self.robot.close()


def run_arm(args, setting, governor, free: bool, path: Path) -> dict:
    read = speed_reader(setting.pusher, setting.physics())
    recording = Recording(n_links=setting.n_links, robot=f"lab {args.lab}, free={free}",
                          setting=setting.name)  # fmt: skip
    tally = {"attempted": 0, "lost": 0, "outside_after_last": 0, "speeds": []}
    bar = tqdm(total=len(PAPER_CLASSES) * args.per_class, desc=path.stem)
    for c, label in enumerate(PAPER_CLASSES):
        base = class_robot(setting, c, args.seed, TargetWorld(), args.lab, args.pushes)
        robot = LastPushFree(base, governor, args.pushes, free)
        arm = FilterArm.load("bayes", setting, args.seed, args.density)
        arm.governor = robot.governor
        arm.reach_check = ReachCheck(setting.pusher, setting.physics())
        for i in range(args.per_class):
            episode = run_segments(robot, arm, arm, args.pushes, 1, seed=robot.seed,
                                   read_speed=read)  # fmt: skip
            tally["attempted"] += 1
            tally["lost"] += episode.failure is not None
            tally["outside_after_last"] += any(r.details.get("outside") for r in episode.reports)
            tally["speeds"].append([r.speed for r in episode.reports])
            if episode.estimates:
                recording.episodes.append(episode.recorded(
                    id=episode_id(c, i), label=label, masses=robot.truth["masses"]
                ))  # fmt: skip
            bar.update()
        arm.close()
        robot.close()
    bar.close()
    write_recording(path, recording)
    speeds = np.array([s + [np.nan] * (args.pushes - len(s)) for s in tally["speeds"]], float)
    tally["mean_speed_by_push"] = np.nanmean(speeds, axis=0).round(3).tolist()
    del tally["speeds"]
    return tally


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--lab", type=int, required=True)
    parser.add_argument("--seed", type=int, required=True)
    parser.add_argument("--per-class", type=int, default=20)
    parser.add_argument("--pushes", type=int, default=2)
    parser.add_argument("--start-range", type=float, default=0.02)
    parser.add_argument("--governor-fit", type=Path, required=True)
    parser.add_argument("--density", default=None, help="the filter's push density (shipped)")
    parser.add_argument(
        "--sort-with",
        type=Path,
        nargs="*",
        default=[],
        help="lab-tuned push densities to sort the episodes with",
    )
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    torch.set_num_threads(1)  # the filter's small network calls only wait on a pool
    if args.per_class < 1 or args.pushes < 1:
        parser.error("--per-class and --pushes must be >= 1")
    if not args.governor_fit.is_file():
        parser.error(f"--governor-fit: no such recording {args.governor_fit}")
    for density in args.sort_with:
        if not density.is_file():
            parser.error(f"--sort-with: no such push density {density}")
    setting = get_setting("real-ur10")
    overrides = {**setting.overrides, "root_xy_range": args.start_range}
    setting = dataclasses.replace(setting, overrides=overrides)
    try:
        governor = fit_governor(
            reach_governor(setting.pusher, setting.physics()), args.governor_fit
        )
    except ValueError as err:
        parser.error(f"--governor-fit: {str(err).splitlines()[0]}")
    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        parser.error(f"--out: {err}")
    summary = {"args": {k: str(v) for k, v in vars(args).items()}}
    probe = args.out / "probe.json"
    done = json.loads(probe.read_text()) if probe.is_file() else {}
    for name in ("governed", "free"):
        path = args.out / f"{name}.jsonl"
        summary[name] = (
            done[name]
            if name in done and path.is_file()
            else run_arm(args, setting, governor, name == "free", path)
        )
        print(name, json.dumps(summary[name]))
    probe.write_text(json.dumps(summary, indent=1) + "\n")
    for density in args.sort_with:
        sort_both(args.out, density, args.pushes)


def sort_both(out: Path, density: Path, pushes: int) -> None:
    """Print both arms' accuracy under `density`'s class posterior and the paired test."""
    tuned = load_push_density(density)
    right = {}
    for name in ("governed", "free"):
        recording = read_recording(out / f"{name}.jsonl")
        result = posterior_accuracy(tuned, recording, name, pushes)
        truth = np.array([result["classes"].index(label) for label in recording.labels])
        right[name] = (truth, np.array(result["predicted"]))
    (truth, governed), (_, free) = right["governed"], right["free"]
    test = paired_test(truth, free, governed)
    print(
        f"{density.name}: governed {np.mean(governed == truth):.1%}, free "
        f"{np.mean(free == truth):.1%} of {len(truth)}; only free right "
        f"{test['only_learned']}, only governed {test['only_random']}, p = {test['p_value']:.3f}"
    )


if __name__ == "__main__":
    main()
