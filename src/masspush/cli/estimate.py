"""Commands that estimate: the demo, an evaluation, episodes through a robot."""

from __future__ import annotations

import argparse
import dataclasses
import json

from masspush.cli.command import Command
from masspush.cli.options import add_bayes_option, add_fields, build

GROUP = "estimate"


def _demo_options(p: argparse.ArgumentParser) -> None:
    from masspush.reports.demonstration import DemoConfig

    add_fields(p, DemoConfig)


def _demo(args: argparse.Namespace) -> int:
    from masspush.reports.demonstration import DemoConfig, demo

    picture, *video = demo(build(DemoConfig, args))
    print(f"wrote {picture}  (rest poses, pushes and estimates)")
    for path in video:
        print(f"wrote {path} (replaying the same episode)")
    return 0


def _evaluate_options(p: argparse.ArgumentParser) -> None:
    from masspush.evaluate import EvaluateConfig

    add_fields(p, EvaluateConfig, required=("setting", "model"))
    p.add_argument(
        "--bayes", action="append", metavar="KEY=VALUE", default=None,
        help="change a BayesConfig field of the particle filter (repeatable), "
        "e.g. --bayes likelihood_power=0.6",
    )  # fmt: skip
    p.add_argument("--json", action="store_true", help="print one JSON object")


def _evaluate(args: argparse.Namespace) -> int:
    from masspush.bayes.filter import bayes_overrides
    from masspush.evaluate import EvaluateConfig
    from masspush.models import evaluate_model

    config = build(EvaluateConfig, args)
    result = evaluate_model(config, bayes_overrides(args.bayes), progress=not args.json)
    out = result.to_dict()
    if args.json:
        print(json.dumps(out))
        return 0
    for key, value in out.items():
        if key != "per_episode":  # one line per episode: for --json only
            print(f"{key:34s} {value}")
    return 0


def _run_options(p: argparse.ArgumentParser) -> None:
    from masspush.real.session import SessionConfig

    fields = [f.name for f in dataclasses.fields(SessionConfig) if f.name != "bayes"]
    add_fields(p, SessionConfig, only=fields, required=("robot", "setting"))
    add_bayes_option(p)


def _run(args: argparse.Namespace) -> int:
    from masspush.bayes.filter import bayes_overrides
    from masspush.real.session import SessionConfig, run_session

    run_session(build(SessionConfig, args, bayes=bayes_overrides(args.bayes)))
    return 0


COMMANDS = [
    Command("demo", GROUP, "a trained policy pushes a random chain; the estimate after each push",
            _demo_options, _demo),
    Command("evaluate", GROUP, "a model or the particle filter on fresh simulated episodes",
            _evaluate_options, _evaluate),
    Command("run", GROUP, "estimation episodes through a robot: simulated, replayed or your own",
            _run_options, _run),
]  # fmt: skip
