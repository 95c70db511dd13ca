"""Carry a recipe run across machines: its finished stages' models, small enough for git.

A run directory (`masspush train --out DIR`) resumes stage by stage, but its data and PPO
checkpoints are bulky and stay out of git, so a run that outlives a session's machine is
lost with it. `pack` copies what the stages still to come need (the run's state, each
finished stage's predictor and policy that a later stage or the export reads, with their
metadata) into KIT; `unpack` puts them
back into a run directory, where the same `masspush train` command resumes at the first
unfinished stage (an unfinished stage starts over).

    python experiments/queues/run_kit.py pack runs/3link-0.1-1-kuka-paper results/kits/3link
    python experiments/queues/run_kit.py unpack results/kits/3link runs/3link-0.1-1-kuka-paper
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

KEPT = ("predictor.pt", "config.json", "policy.zip", "policy.json")
"""The files of a finished stage's directory that later stages and the exports read."""


def needed(done: list[str]) -> list[str]:
    """The finished stages whose models the rest of the run reads: the random-push one (RP
    where a setting has none shipped), the first meta-iteration's
    (TP), the latest predictor and policy (the next stages continue from them), and the
    final predictor (TP+); the others' results are in the state's history already."""

    def latest(kind: str) -> list[str]:
        numbered = [s for s in done if s.startswith(kind) and s[len(kind) :].isdigit()]
        return [max(numbered, key=lambda s: int(s[len(kind) :]))] if numbered else []

    keep = {"predictor-0", "predictor-1", "policy-1", "predictor-final", *latest("predictor-"),
            *latest("policy-")}  # fmt: skip
    return [s for s in done if s in keep]


def pack(run: Path, kit: Path) -> list[str]:
    """Copy the run's state and its finished stages' models into `kit`; what was copied."""
    state_path = run / "state.json"
    if not state_path.is_file():
        raise ValueError(f"{run} holds no recipe run (no state.json)")
    done = json.loads(state_path.read_text())["timings"]
    kit.mkdir(parents=True, exist_ok=True)
    shutil.copy2(state_path, kit / "state.json")
    copied = ["state.json"]
    for stage in needed(sorted(done)):
        source = run / stage
        if not source.is_dir():
            continue
        for name in KEPT:
            if (source / name).is_file():
                (kit / stage).mkdir(exist_ok=True)
                shutil.copy2(source / name, kit / stage / name)
                copied.append(f"{stage}/{name}")
    return copied


def unpack(kit: Path, run: Path) -> list[str]:
    """Put a kit's files into the run directory `run` (which must not hold a run yet)."""
    if not (kit / "state.json").is_file():
        raise ValueError(f"{kit} is no run kit (no state.json)")
    if (run / "state.json").exists():
        raise ValueError(f"{run} already holds a run; unpack into a new directory")
    shutil.copytree(kit, run, dirs_exist_ok=True)
    return sorted(str(p.relative_to(run)) for p in run.rglob("*") if p.is_file())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("action", choices=("pack", "unpack"))
    parser.add_argument("source", type=Path, help="the run directory (pack) or the kit (unpack)")
    parser.add_argument("target", type=Path, help="the kit (pack) or the run directory (unpack)")
    args = parser.parse_args(argv)
    try:
        files = (pack if args.action == "pack" else unpack)(args.source, args.target)
    except (OSError, ValueError) as err:
        sys.exit(f"error: {err}")
    print("\n".join(files))
    return 0


if __name__ == "__main__":
    sys.exit(main())
