"""How much memory do `masspush check-episodes` and `masspush classify` take for a large
recording, and does it grow with the file? (issue 26; docs/notebook/2026-12-01-bad-input.md)

Writes a recording of N two-link episodes (simulated pushes of the 2link-1-10 setting,
repeated under new ids, five labels), fine-tunes a classifier on its first 200, then runs
both commands in fresh processes and prints each one's peak resident memory.

    .venv/bin/python experiments/inputs/recording_memory.py --episodes 200000 --out /tmp/recmem

With `--source DIR` the commands run from another checkout's `src` (e.g. a git worktree of
an older commit), for a before/after comparison.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

from masspush.data import RandomPolicy, Recording, write_recording
from masspush.learn import load_model
from masspush.models import resolve_model
from masspush.real import SimRobot, run_estimation

SETTING = "2link-1-10"
LABELS = ("a", "b", "c", "d", "e")


def write_big(path: Path, episodes: int) -> None:
    predictor = load_model(resolve_model("rp+", SETTING), SETTING)[0]
    robot = SimRobot(SETTING, seed=1)
    runs = []
    while len(runs) < 50:
        run = run_estimation(robot, predictor, RandomPolicy(), 2, seed=len(runs))
        if run.failure is None:
            runs.append(run)
    small = [runs[i % 50].recorded(id=f"s{i}", label=LABELS[i % 5]) for i in range(200)]
    write_recording(path.with_name("small.jsonl"), Recording(2, setting=SETTING, episodes=small))
    lines = path.with_name("small.jsonl").read_text().splitlines()
    with open(path, "w") as f:
        f.write(lines[0] + "\n")
        for i in range(episodes):
            episode = json.loads(lines[1 + i % 50])
            episode.update(id=f"e{i}", label=LABELS[i % 5])
            f.write(json.dumps(episode) + "\n")


def peak_mb(argv: list[str], source: str | None) -> tuple[float, int]:
    env = dict(os.environ)
    if source:
        env["PYTHONPATH"] = source
    probe = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:], "
             "stdout=subprocess.DEVNULL); print(r.returncode, "
             "resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")  # fmt: skip
    out = subprocess.run([sys.executable, "-c", probe, *argv], env=env, capture_output=True,
                         text=True, check=True).stdout.split()  # fmt: skip
    return int(out[1]) / 1024, int(out[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=200_000)
    parser.add_argument("--out", default="/tmp/recmem")
    parser.add_argument("--source", help="run the commands from this checkout's src")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    big = out / f"big-{args.episodes}.jsonl"
    if not big.exists():
        write_big(big, args.episodes)
    classifier = out / "classifier.pt"
    masspush = [sys.executable, "-m", "masspush.cli"]
    if not classifier.exists():
        subprocess.run([*masspush, "finetune", "--setting", SETTING, "--model", "rp+",
                        "--episodes", str(out / "small.jsonl"), "--out", str(classifier)],
                       check=True, stdout=subprocess.DEVNULL)  # fmt: skip
    size = big.stat().st_size / 2**20
    print(f"recording: {args.episodes} episodes, {size:.0f} MiB")
    for name, argv in (("check-episodes", ["check-episodes", str(big)]),
                       ("classify", ["classify", "--classifier", str(classifier),
                                     "--episodes", str(big)])):  # fmt: skip
        mb, code = peak_mb([*masspush, *argv], args.source)
        print(f"{name}: peak {mb:.0f} MiB (exit {code})")


if __name__ == "__main__":
    main()
