"""Commands on data: collecting datasets, checking recordings."""

from __future__ import annotations

import argparse
import sys

from masspush.cli.command import Command
from masspush.cli.options import add_fields, build

GROUP = "data"


def _collect_options(p: argparse.ArgumentParser) -> None:
    from masspush.data.dataset import CollectConfig

    add_fields(p, CollectConfig)


def _collect(args: argparse.Namespace) -> int:
    from masspush.data.dataset import CollectConfig, collect_dataset

    config = build(CollectConfig, args)
    m = collect_dataset(config)
    print(
        f"{config.out}: {m.episodes} episodes of {m.setting['name']} ({m.pusher} pusher, "
        f"{m.policy} policy) in {m.shards} shards"
    )
    return 0


def _check_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", help="the recording (JSON Lines; docs/real-robot.md)")


def _check(args: argparse.Namespace) -> int:
    from masspush.data.recording import check_report

    good, lines = check_report(args.file)
    print("\n".join(lines))  # the report: every problem with its line and field
    if not good:
        print(f"masspush check-episodes: error: {args.file}: {len(lines)} problem(s), listed "
              "above", file=sys.stderr)  # fmt: skip
    return 0 if good else 1


COMMANDS = [
    Command("collect", GROUP, "rollout episodes into a dataset (resumable)",
            _collect_options, _collect),
    Command("check-episodes", GROUP, "validate a recording: every problem with its line",
            _check_options, _check),
]  # fmt: skip
