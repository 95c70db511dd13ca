"""The `masspush` command line."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

import numpy as np


def _format(values: np.ndarray, digits: int = 3) -> str:
    return "[" + ", ".join(f"{v:+.{digits}f}" for v in np.asarray(values, dtype=float)) + "]"


def _shipped_estimator(n_links: int, mass_range, pusher: str):
    """The shipped RP+ predictor for this chain and pusher, if there is one: (model, name)."""
    from masspush.evaluate import resolve_model
    from masspush.predictor import load_model
    from masspush.settings import SETTINGS

    for setting in SETTINGS.values():
        if setting.n_links == n_links and setting.mass_range == tuple(mass_range):
            try:
                model, _ = load_model(resolve_model("rp+", setting.name), setting.name, pusher)
            except ValueError:
                return None
            return model, f"rp+ ({setting.name}, {pusher})"
    return None


def cmd_demo(args: argparse.Namespace) -> int:
    """Random pushes on a random chain: each push, the rest pose, and (where a trained
    predictor ships for this setting) the estimate of the mass distribution after it."""
    from masspush.env import ChainEnv
    from masspush.rollout import Episodes
    from masspush.settings import PAPER_PUSHER

    pusher = args.pusher or PAPER_PUSHER
    env = ChainEnv(
        n_links=args.links, mass_range=tuple(args.mass_range), pushes=args.pushes, pusher=pusher
    )
    obs, info = env.reset(seed=args.seed)
    env.action_space.seed(args.seed)  # the whole demo is reproducible from its seed
    n, k_max = args.links, env.config.pushes
    estimator = _shipped_estimator(n, args.mass_range, pusher)
    d = env.physics.obs_dim
    history = np.full((1, k_max + 1, d), np.nan, np.float32)
    actions = np.full((1, k_max, 2), np.nan, np.float32)
    history[0, 0] = obs[:d]
    truth = info["mass_distribution"]
    print(f"A {n}-link chain on a table (seed {args.seed}), pushed by the {pusher} pusher;")
    print("the robot may only push it and look at where it comes to rest.")
    print(f"  true masses        {_format(info['masses'])} kg")
    print(f"  mass distribution  {_format(truth)}   <- what is to be estimated")
    print(f"  table friction     {info['friction']:.3f}")
    print(f"  link lengths       {_format(info['lengths'])} m")
    print(f"  rest pose q0       {_format(obs[:d])}  (x, y, yaw, joint angles; noisy)")
    terminated = False
    k = 0
    while not terminated:
        action = env.action_space.sample()
        obs, _, terminated, _, info = env.step(action)
        actions[0, k], history[0, k + 1] = action, obs[:d]
        k += 1
        p = info["push"]
        side = "from the right" if p["side"] > 0 else "from the left"
        print(
            f"push {k}: a={_format(action, 2)} -> link {p['link']} {side}, "
            f"{p['offset'] * 100:+.1f} cm from its centre, at {p['speed']:.2f} m/s"
        )
        if info["failure"]:
            print(f"  push failed: {info['failure']}")
            break
        print(f"  at rest after {info['settle_time']:.2f} s: q{k} = {_format(obs[:d])}")
        if estimator is not None:
            so_far = Episodes(
                index=np.zeros(1, np.int64),
                seed=np.zeros(1, np.uint64),
                observations=history[:, : k + 1],
                configs=history[:, : k + 1],
                actions=actions[:, :k],
                executed=actions[:, :k],
                failure=np.zeros((1, k), np.int8),
                masses=info["masses"][None].astype(np.float32),
                friction=np.array([info["friction"]], np.float32),
                lengths=info["lengths"][None].astype(np.float32),
            )
            estimate = estimator[0].predict(so_far)[0, -1]
            error = np.abs(estimate - truth).mean()
            print(f"  estimate           {_format(estimate)}   (mean absolute error {error:.3f})")
    if estimator is None:
        print("No trained predictor ships for this setting and pusher yet.")
    else:
        print(
            f"Estimates from the shipped {estimator[1]} predictor (random pushes, as it was "
            "trained); the learned pushing policy comes with a later version."
        )
    return 0


def cmd_bench_sim(args: argparse.Namespace) -> int:
    from masspush.bench import bench_sim

    result = bench_sim(
        n_links=args.links,
        mass_range=tuple(args.mass_range),
        env_pushes=args.env_pushes,
        batch_chains=args.chains,
        threads=args.threads,
        seed=args.seed,
        progress=not args.json,
    )
    print(json.dumps(result.as_dict()) if args.json else result.table())
    return 0


def cmd_bench_pushers(args: argparse.Namespace) -> int:
    from dataclasses import asdict

    from masspush.bench import bench_pushers, pushers_table

    pushers = tuple(args.pushers.split(","))
    results = bench_pushers(
        n_links=args.links,
        pushes=args.pushes,
        pairs=args.pairs,
        pushers=pushers,
        seed=args.seed,
        progress=not args.json,
    )
    print(json.dumps([asdict(r) for r in results]) if args.json else pushers_table(results))
    return 0


def cmd_bench_data(args: argparse.Namespace) -> int:
    from masspush.bench import bench_data

    print(json.dumps(bench_data(args.setting, args.pusher, args.episodes, args.workers)))
    return 0


def cmd_bench_train(args: argparse.Namespace) -> int:
    from masspush.bench import bench_train

    for row in bench_train(args.setting, args.episodes, args.steps):
        print(json.dumps(row))
    return 0


def cmd_bench_ppo(args: argparse.Namespace) -> int:
    from masspush.bench import bench_ppo

    rows = bench_ppo(
        args.setting,
        args.pusher,
        tuple(args.algos.split(",")),
        args.steps,
        tuple(int(e) for e in args.envs.split(",")),
    )
    for row in rows:
        print(json.dumps(row))
    return 0


def cmd_bench_motion(args: argparse.Namespace) -> int:
    """How far the chains of a dataset moved per push (is there anything to observe?)."""
    from masspush.dataset import load_dataset

    manifest, eps = load_dataset(args.data, limit=args.episodes)
    eps = eps.select(eps.ok)
    c = eps.configs.astype(float)
    moved = 1000 * np.linalg.norm(c[:, 1:, :2] - c[:, :-1, :2], axis=-1).ravel()
    joint = np.abs(c[:, 1:, 3] - c[:, :-1, 3]).ravel()
    print(
        json.dumps(
            {
                "dataset": str(args.data),
                "setting": manifest.setting["name"],
                "pusher": manifest.pusher,
                "pushes": int(moved.size),
                "root_moved_mm_median": float(np.median(moved)),
                "root_moved_mm_p90": float(np.percentile(moved, 90)),
                "share_moved_under_2mm": float(np.mean(moved < 2)),
                "first_joint_change_rad_median": float(np.median(joint)),
            }
        )
    )
    return 0


def cmd_bench_physics(args: argparse.Namespace) -> int:
    from dataclasses import asdict

    from masspush.validate import format_table, validate_physics

    rows = validate_physics(
        n_links=args.links,
        mass_range=tuple(args.mass_range),
        pushes=args.pushes,
        seed=args.seed,
        progress=not args.json,
    )
    print(json.dumps([asdict(r) for r in rows]) if args.json else format_table(rows))
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    from masspush.render import render_episode

    result = render_episode(
        args.setting,
        pusher=args.pusher,
        out=args.out,
        seed=args.seed,
        width=args.width,
        height=args.height,
        stills=args.png,
    )
    print(f"wrote {result.video} ({result.frames} frames)")
    for path in result.stills:
        print(f"wrote {path}")
    if any(result.failures):
        print(f"failed pushes: {result.failures}")
    return 0


def cmd_collect(args: argparse.Namespace) -> int:
    from masspush.dataset import collect
    from masspush.settings import get_setting

    setting = get_setting(args.setting, args.settings_file)
    args.pusher = args.pusher or setting.pusher
    manifest = collect(
        setting,
        args.out,
        episodes=args.episodes,
        pusher=args.pusher,
        policy=args.policy,
        base_seed=args.seed,
        shard_size=args.shard_size,
        workers=args.workers,
    )
    print(
        f"{args.out}: {manifest.episodes} episodes of {setting.name} ({manifest.pusher} pusher, "
        f"{manifest.policy} policy) in {manifest.shards} shards"
    )
    return 0


def cmd_train_predictor(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from masspush.dataset import code_version, load_dataset
    from masspush.predictor import FAST, TrainConfig, train_predictor

    manifest, episodes = load_dataset(args.data, limit=args.episodes)
    if manifest.setting["name"] != args.setting:
        raise ValueError(
            f"{args.data} holds setting {manifest.setting['name']!r}, not {args.setting!r}"
        )
    config = FAST if args.fast else TrainConfig()
    overrides = {
        k: v
        for k, v in (
            ("steps", args.steps),
            ("batch_size", args.batch_size),
            ("lr", args.lr),
            ("optimizer", args.optimizer),
            ("features", args.features),
            ("seed", args.seed),
        )
        if v is not None
    }
    config = replace(config, **overrides)
    meta = {
        "setting": manifest.setting,
        "pusher": manifest.pusher,
        "policy": manifest.policy,
        "dataset": str(args.data),
        "dataset_episodes": len(episodes),
        "code_version": code_version(),
    }
    out = args.out or f"runs/predictor-{args.setting}-{len(episodes)}"
    _, summary = train_predictor(episodes, out, config, meta)
    print(
        f"wrote {out}/predictor.pt: best validation percentage error "
        f"{summary['best_validation_error']:.2f} at step {summary['best_step']} "
        f"({summary['samples_per_s']:.0f} samples/s)"
    )
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    from masspush.evaluate import evaluate

    result = evaluate(
        args.setting,
        args.model,
        episodes=args.episodes,
        seed=args.seed,
        pusher=args.pusher,
        settings_file=args.settings_file,
        workers=args.workers,
    )
    if args.json:
        print(json.dumps(result))
    else:
        for key, value in result.items():
            print(f"{key:34s} {value}")
    return 0


def cmd_baselines(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from masspush.baselines import run_baselines, ship
    from masspush.predictor import FAST, TrainConfig
    from masspush.settings import get_setting

    if args.table:
        from masspush.baselines import baselines_table

        print(baselines_table(args.pusher))
        return 0
    if args.setting is None:
        raise ValueError("--setting is required (unless --table)")
    pusher = args.pusher or get_setting(args.setting).pusher
    if args.ship_only:
        for path in ship(args.setting, pusher):
            print(f"shipped {path}")
        return 0
    train = FAST if args.fast else TrainConfig()
    if args.features:
        train = replace(train, features=args.features)
    episodes = tuple(args.episodes) if args.episodes else None
    results = run_baselines(
        args.setting, pusher, train, eval_episodes=args.eval_episodes, episodes=episodes
    )
    for name, r in results["models"].items():
        print(
            f"{name:4s} percentage error {r['percentage_error']:6.2f}  relative "
            f"{r['relative_error']:6.2f}  (constant floor {r['constant_floor']:.2f}, "
            f"evaluated on {r['episodes']} episodes, {r['failures']} failed)"
        )
    print(f"timings: {results['timings']}")
    if args.ship:
        for path in ship(args.setting, pusher):
            print(f"shipped {path}")
    return 0


def _recipe_config(args: argparse.Namespace):
    from masspush.policy import PolicyConfig
    from masspush.train import RecipeConfig

    policy = PolicyConfig(algo=args.algo, n_envs=args.envs, steps=args.ppo_steps)
    return RecipeConfig(
        meta_iterations=args.meta_iterations,
        first_episodes=args.first_episodes,
        iteration_episodes=args.iteration_episodes,
        final_episodes=args.final_episodes,
        policy=policy,
        eval_episodes=args.eval_episodes,
        seed=args.seed,
    )


def cmd_train(args: argparse.Namespace) -> int:
    from masspush.evaluate import SHIPPED_DIR
    from masspush.reproduce import train_dir
    from masspush.settings import get_setting
    from masspush.train import Recipe

    setting = get_setting(args.setting, args.settings_file)
    pusher = args.pusher or setting.pusher
    out = args.out or train_dir(setting.name, pusher)
    state = Recipe(setting, pusher, out, _recipe_config(args)).run()
    for h in state["history"]:
        print(
            f"{h['stage']:16s} percentage error {h['percentage_error']:6.2f}  "
            f"(constant floor {h['constant_floor']:.2f}, {h['episodes']} episodes)"
        )
    print(f"wall clock per stage (s): {state['timings']}")
    if args.ship:
        for path in Recipe(setting, pusher, out, _recipe_config(args)).ship(
            SHIPPED_DIR / setting.name
        ):
            print(f"shipped {path}")
    return 0


def cmd_reproduce(args: argparse.Namespace) -> int:
    from masspush.baselines import PAPER_TABLE, run_baselines, ship
    from masspush.evaluate import SHIPPED_DIR
    from masspush.predictor import FAST
    from masspush.reproduce import train_dir, write_outputs
    from masspush.settings import get_setting
    from masspush.train import Recipe

    names = list(PAPER_TABLE) if args.settings == "all" else args.settings.split(",")
    settings = [get_setting(name) for name in names]
    pushers = {s.name: args.pusher or s.pusher for s in settings}
    if not args.table_only:
        from dataclasses import replace

        for s in settings:
            run_baselines(s.name, pushers[s.name], replace(FAST, features="relative"))
            recipe = Recipe(
                s, pushers[s.name], train_dir(s.name, pushers[s.name]), _recipe_config(args)
            )
            recipe.run()
            if args.ship:
                ship(s.name, pushers[s.name])
                recipe.ship(SHIPPED_DIR / s.name)
    for path in write_outputs(names, pushers):
        print(f"wrote {path}")
    return 0


def _recipe_args(p: argparse.ArgumentParser) -> None:
    from masspush.policy import ALGOS

    p.add_argument("--pusher", default=None, help="default: the setting's pusher")
    p.add_argument(
        "--algo",
        default="recurrent",
        choices=ALGOS,
        help="recurrent: RecurrentPPO, the paper's LSTM policy; mlp: PPO over the "
        "padded push history",
    )
    p.add_argument("--meta-iterations", type=int, default=6)
    p.add_argument("--ppo-steps", type=int, default=75_000, help="per meta-iteration")
    p.add_argument("--envs", type=int, default=16, help="parallel environments")
    p.add_argument(
        "--first-episodes",
        type=int,
        default=None,
        help="random episodes for the first predictor (default 16k / 32k)",
    )
    p.add_argument("--iteration-episodes", type=int, default=None)
    p.add_argument("--final-episodes", type=int, default=None)
    p.add_argument("--eval-episodes", type=int, default=800)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--ship", action="store_true", help="copy TP and TP+ into the package")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="masspush",
        description="Estimate mass distributions of articulated chains by pushing them.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    def chain_args(p: argparse.ArgumentParser) -> None:
        p.add_argument("--links", type=int, default=2, help="number of links (default 2)")
        p.add_argument(
            "--mass-range",
            type=float,
            nargs=2,
            default=[0.1, 1.0],
            metavar=("LOW", "HIGH"),
            help="link mass range in kg (default 0.1 1.0)",
        )
        p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")

    demo = sub.add_parser("demo", help="push a random chain and print what happens")
    chain_args(demo)
    demo.add_argument("--pushes", type=int, default=None, help="pushes (default: one per link)")
    demo.add_argument("--pusher", default=None, help="stiff, kuka or ur10 (default: kuka)")
    demo.set_defaults(func=cmd_demo)

    col = sub.add_parser("collect", help="collect rollout episodes into a dataset (resumable)")
    col.add_argument("--setting", required=True, help="named setting, e.g. 2link-0.1-1")
    col.add_argument("--settings-file", default=None, help="TOML file with custom settings")
    col.add_argument("--policy", default="random", help="random (more with trained policies)")
    col.add_argument("--episodes", type=int, required=True)
    col.add_argument("--out", required=True, help="dataset directory (resumes if it exists)")
    col.add_argument(
        "--pusher", default=None, help="stiff, kuka or ur10 (default: the setting's pusher)"
    )
    col.add_argument("--seed", type=int, default=0, help="base seed of the episodes")
    col.add_argument("--shard-size", type=int, default=1000)
    col.add_argument("--workers", type=int, default=None, help="processes for arm pushers")
    col.set_defaults(func=cmd_collect)

    tp = sub.add_parser("train-predictor", help="train the LSTM predictor on a dataset")
    tp.add_argument("--setting", required=True)
    tp.add_argument("--data", required=True, help="dataset directory from masspush collect")
    tp.add_argument("--episodes", type=int, default=None, help="use the first N episodes")
    tp.add_argument("--out", default=None, help="run directory (resumes if it exists)")
    tp.add_argument("--fast", action="store_true", help="Adam, batch 256, 20k steps")
    tp.add_argument("--features", default=None, help="paper or relative")
    tp.add_argument("--optimizer", default=None, help="sgd (paper) or adam")
    tp.add_argument("--steps", type=int, default=None)
    tp.add_argument("--batch-size", type=int, default=None)
    tp.add_argument("--lr", type=float, default=None)
    tp.add_argument("--seed", type=int, default=None)
    tp.set_defaults(func=cmd_train_predictor)

    ev = sub.add_parser("evaluate", help="evaluate a model on fresh simulated episodes")
    ev.add_argument("--setting", required=True)
    ev.add_argument("--settings-file", default=None)
    ev.add_argument("--model", required=True, help="a model file, or rp, rp+, tp, tp+")
    ev.add_argument("--episodes", type=int, default=800)
    ev.add_argument("--seed", type=int, default=0)
    ev.add_argument("--pusher", default=None, help="default: the one the model was trained with")
    ev.add_argument("--workers", type=int, default=None)
    ev.add_argument("--json", action="store_true", help="print one JSON object")
    ev.set_defaults(func=cmd_evaluate)

    bl = sub.add_parser("baselines", help="the paper's RP and RP+ for a setting (resumable)")
    bl.add_argument("--setting", default=None)
    bl.add_argument("--table", action="store_true", help="print the results table and stop")
    bl.add_argument(
        "--pusher",
        default=None,
        help="default: the setting's (kuka, the paper's arm; stiff for 10 kg links)",
    )
    bl.add_argument("--fast", action="store_true", help="train with the fast option")
    bl.add_argument("--features", default=None, help="paper or relative")
    bl.add_argument(
        "--episodes",
        type=int,
        nargs=2,
        default=None,
        metavar=("RP", "RP_PLUS"),
        help="episodes for RP and RP+ (default: the paper's)",
    )
    bl.add_argument("--eval-episodes", type=int, default=800)
    bl.add_argument("--ship", action="store_true", help="copy the models into the package")
    bl.add_argument("--ship-only", action="store_true", help="only copy finished models")
    bl.set_defaults(func=cmd_baselines)

    tr = sub.add_parser(
        "train", help="the alternating recipe: predictor, then policy / predictor rounds"
    )
    tr.add_argument("--setting", required=True)
    tr.add_argument("--settings-file", default=None, help="TOML file with custom settings")
    tr.add_argument("--out", default=None, help="run directory (resumes if it exists)")
    _recipe_args(tr)
    tr.set_defaults(func=cmd_train)

    rep = sub.add_parser("reproduce", help="the paper's Table 1 and figures (resumable)")
    rep.add_argument("--settings", default="all", help="all, or a comma-separated list")
    rep.add_argument("--table-only", action="store_true", help="only write table and figures")
    _recipe_args(rep)
    rep.set_defaults(func=cmd_reproduce)

    render = sub.add_parser("render", help="render an episode to a video (MP4 or GIF)")
    render.add_argument("--setting", default="2link-0.1-1", help="named setting")
    render.add_argument("--pusher", default="stiff", help="stiff, kuka or ur10")
    render.add_argument("--out", default="episode.mp4", help="output .mp4 or .gif")
    render.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    render.add_argument("--width", type=int, default=640)
    render.add_argument("--height", type=int, default=480)
    render.add_argument("--png", action="store_true", help="also write one still per rest pose")
    render.set_defaults(func=cmd_render)

    bench = sub.add_parser("bench", help="benchmarks")
    bench_sub = bench.add_subparsers(dest="what", required=True)
    sim = bench_sub.add_parser("sim", help="pushes per second: environment, batch, ceiling")
    chain_args(sim)
    sim.add_argument("--env-pushes", type=int, default=200, help="pushes through the env")
    sim.add_argument("--chains", type=int, default=512, help="chains in the batch run")
    sim.add_argument("--threads", type=int, default=None, help="threads (default: all cores)")
    sim.add_argument("--json", action="store_true", help="print one JSON object")
    sim.set_defaults(func=cmd_bench_sim)
    push = bench_sub.add_parser(
        "pushers", help="pushes per second of each pusher, and what x10 masses change"
    )
    push.add_argument("--links", type=int, default=2)
    push.add_argument("--pushes", type=int, default=60, help="pushes through the env")
    push.add_argument("--pairs", type=int, default=40, help="chains compared with x10 masses")
    push.add_argument("--pushers", default="stiff,kuka,ur10", help="comma-separated")
    push.add_argument("--seed", type=int, default=0)
    push.add_argument("--json", action="store_true", help="print JSON")
    push.set_defaults(func=cmd_bench_pushers)
    bd = bench_sub.add_parser("data", help="collection speed, episodes per second")
    bd.add_argument("--setting", default="2link-0.1-1")
    bd.add_argument("--pusher", default="kuka")
    bd.add_argument("--episodes", type=int, default=1000)
    bd.add_argument("--workers", type=int, default=None)
    bd.set_defaults(func=cmd_bench_data)
    bt = bench_sub.add_parser("train", help="predictor training speed, samples per second")
    bt.add_argument("--setting", default="2link-0.1-1")
    bt.add_argument("--episodes", type=int, default=4000)
    bt.add_argument("--steps", type=int, default=2000)
    bt.set_defaults(func=cmd_bench_train)
    bp = bench_sub.add_parser("ppo", help="PPO training speed, pushes per second")
    bp.add_argument("--setting", default="2link-1-10")
    bp.add_argument("--pusher", default=None, help="default: the setting's")
    bp.add_argument("--algos", default="mlp,recurrent")
    bp.add_argument("--steps", type=int, default=8192)
    bp.add_argument("--envs", default="16", help="comma-separated numbers of environments")
    bp.set_defaults(func=cmd_bench_ppo)
    bm = bench_sub.add_parser("motion", help="how far a dataset's chains moved per push")
    bm.add_argument("--data", required=True)
    bm.add_argument("--episodes", type=int, default=8000)
    bm.set_defaults(func=cmd_bench_motion)
    phys = bench_sub.add_parser(
        "physics", help="rest-pose convergence in the time step, and chaotic sensitivity"
    )
    chain_args(phys)
    phys.add_argument("--pushes", type=int, default=64, help="random single pushes")
    phys.add_argument("--json", action="store_true", help="print JSON")
    phys.set_defaults(func=cmd_bench_physics)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ValueError as err:  # bad input: a clear message, not a traceback
        print(f"masspush: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
