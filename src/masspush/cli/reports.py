"""Commands that report: the Bayes table, videos, benchmarks."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from dataclasses import asdict

from masspush.cli.command import Command
from masspush.cli.options import add_fields, build

GROUP = "report"


def _bayes_table_options(p: argparse.ArgumentParser) -> None:
    from masspush.reports.bayes_report import BayesTableConfig

    add_fields(p, BayesTableConfig)


def _bayes_table(args: argparse.Namespace) -> int:
    from masspush.reports.bayes_report import BayesTableConfig, bayes_table_run

    print(bayes_table_run(build(BayesTableConfig, args)), end="")
    print("wrote results/bayes.md")
    return 0


def _render_options(p: argparse.ArgumentParser) -> None:
    from masspush.reports.render import RenderConfig

    add_fields(p, RenderConfig)


def _render(args: argparse.Namespace) -> int:
    from masspush.reports.render import RenderConfig, render

    result = render(build(RenderConfig, args))
    print(f"wrote {result.video} ({result.frames} frames)")
    for path in result.stills:
        print(f"wrote {path}")
    if any(result.failures):
        print(f"failed pushes: {result.failures}")
    return 0


def _json_flag(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")


def _bench(
    config_name: str, json_flag: bool = False, pairs: tuple[str, ...] = ()
) -> Callable[[argparse.ArgumentParser], None]:
    def options(p: argparse.ArgumentParser) -> None:
        from masspush.reports import bench

        add_fields(p, getattr(bench, config_name), pairs=pairs)
        if json_flag:
            _json_flag(p)

    return options


def _bench_sim(args: argparse.Namespace) -> int:
    from masspush.reports.bench import SimBench, bench_sim

    result = bench_sim(build(SimBench, args), progress=not args.json)
    print(json.dumps(result.as_dict()) if args.json else result.table())
    return 0


def _bench_pushers(args: argparse.Namespace) -> int:
    from masspush.reports.bench import PushersBench, bench_pushers, pushers_table

    results = bench_pushers(build(PushersBench, args), progress=not args.json)
    print(json.dumps([asdict(r) for r in results]) if args.json else pushers_table(results))
    return 0


def _bench_arm(args: argparse.Namespace) -> int:
    from masspush.reports.bench import ArmBench, bench_arm

    result = bench_arm(build(ArmBench, args))
    if not args.json:
        print(
            f"{result['arm']}, {result['links']} links: {result['arm_pushes_per_s']:.0f} pushes/s "
            f"against the stiff pusher's {result['stiff_pushes_per_s']:.0f} (ratio "
            f"{result['ratio']:.2f}, goal {result['goal']}); steps per push "
            f"{result['arm_steps_per_push']:.0f} / {result['stiff_steps_per_push']:.0f}; "
            f"compiled law identical to the reference: {result['identical']}"
        )
    print(json.dumps(result))
    return 0


def _bench_data(args: argparse.Namespace) -> int:
    from masspush.reports.bench import DataBench, bench_data

    print(json.dumps(bench_data(build(DataBench, args))))
    return 0


def _bench_ray_options(p: argparse.ArgumentParser) -> None:
    from masspush.reports.bench_cluster import ClusterBench

    add_fields(p, ClusterBench)


def _bench_ray(args: argparse.Namespace) -> int:
    from masspush.cluster.pool import check_address
    from masspush.reports.bench_cluster import ClusterBench, bench_cluster

    check_address("local", "bench ray")  # Ray installed, before any work
    print(json.dumps(bench_cluster(build(ClusterBench, args))))
    return 0


def _bench_train(args: argparse.Namespace) -> int:
    from masspush.reports.bench import TrainBench, bench_train

    for row in bench_train(build(TrainBench, args)):
        print(json.dumps(row))
    return 0


def _bench_ppo(args: argparse.Namespace) -> int:
    from masspush.reports.bench import PPOBench, bench_ppo

    for row in bench_ppo(build(PPOBench, args)):
        print(json.dumps(row))
    return 0


def _bench_motion(args: argparse.Namespace) -> int:
    from masspush.reports.bench import MotionBench, bench_motion

    print(json.dumps(bench_motion(build(MotionBench, args))))
    return 0


def _bench_physics(args: argparse.Namespace) -> int:
    from masspush.reports.bench import PhysicsBench, bench_physics
    from masspush.sim.convergence import format_table

    rows = bench_physics(build(PhysicsBench, args), progress=not args.json)
    print(json.dumps([asdict(r) for r in rows]) if args.json else format_table(rows))
    return 0


def _motion_options(p: argparse.ArgumentParser) -> None:
    from masspush.reports.bench import MotionBench

    add_fields(p, MotionBench, required=("data",))


COMMANDS = [
    Command("bayes-table", GROUP, "the Bayesian estimator and learned uncertainty beside Table 1",
            _bayes_table_options, _bayes_table),
    Command("render", GROUP, "an episode as a video (MP4 or GIF)", _render_options, _render),
    Command("bench sim", GROUP, "pushes per second: environment, batch, ceiling",
            _bench("SimBench", True, pairs=("mass_range",)), _bench_sim),
    Command("bench pushers", GROUP, "pushes per second of each pusher, and what x10 masses change",
            _bench("PushersBench", True), _bench_pushers),
    Command("bench arm", GROUP, "an arm's pushes per second against the stiff pusher's",
            _bench("ArmBench", True), _bench_arm),
    Command("bench data", GROUP, "collection speed, episodes per second", _bench("DataBench"),
            _bench_data),
    Command("bench ray", GROUP, "collection on this machine against --ray local (1, 2 CPUs)",
            _bench_ray_options, _bench_ray),
    Command("bench train", GROUP, "predictor training speed, samples per second",
            _bench("TrainBench"), _bench_train),
    Command("bench ppo", GROUP, "PPO training speed, pushes per second", _bench("PPOBench"),
            _bench_ppo),
    Command("bench motion", GROUP, "how far a dataset's chains moved per push", _motion_options,
            _bench_motion),
    Command("bench physics", GROUP, "rest-pose convergence in the time step, chaotic sensitivity",
            _bench("PhysicsBench", True, pairs=("mass_range",)), _bench_physics),
]  # fmt: skip
