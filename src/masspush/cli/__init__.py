"""The `masspush` command line."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np


def cmd_demo(args: argparse.Namespace) -> int:
    """A shipped policy pushes a random chain; the shipped predictor estimates its masses."""
    from masspush.reports.demo import DEMO_SETTING, draw_demo, run_demo

    episode = run_demo(args.setting or DEMO_SETTING, args.model, args.seed)
    print(f"wrote {draw_demo(episode, args.out)}  (rest poses, pushes and estimates)")
    if args.video:
        from masspush.reports.render import render_episode

        result = render_episode(
            episode.setting.name,
            episode.pusher,
            args.video,
            seed=args.seed,
            actions=np.asarray(episode.actions),
        )
        print(f"wrote {result.video} ({result.frames} frames, replaying the same episode)")
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    """Estimation episodes through a robot backend, the estimate printed after each push."""
    from masspush.learn.policy import model_policy
    from masspush.learn.predictor import load_model
    from masspush.models import resolve_model
    from masspush.real.backends import RecordedPolicy, make_robot
    from masspush.real.robot import fmt, print_push, run_segments
    from masspush.settings import get_setting

    setting = get_setting(args.setting, args.settings_file)
    path = resolve_model(args.model, setting.name)
    predictor, meta = load_model(path, setting.name)
    masses = None if args.masses is None else tuple(float(m) for m in args.masses.split(","))
    if masses is not None and args.robot == "replay":
        raise ValueError("--masses pins a simulated chain's masses; a replay has its own")
    if args.segments != 1 and args.robot == "replay":
        raise ValueError("--segments runs the policy again; a replay plays its recorded pushes")
    robot = make_robot(args.robot, setting, args.episodes_file, args.seed, masses, args.lab)
    if robot.n_links != setting.n_links:
        raise ValueError(
            f"the robot's chain has {robot.n_links} links, setting {setting.name!r} has "
            f"{setting.n_links}"
        )
    if args.robot == "replay":
        policy = RecordedPolicy(robot)
        count = len(robot.recording.episodes) if args.count is None else args.count
        print(f"Replaying {count} recorded episode(s) with their recorded pushes.")
    else:
        policy, count = model_policy(meta, path), args.count or 1
        print(f"Pushes chosen by the {policy.name} policy of model {args.model!r}.")
    pushes = setting.env_config().pushes if args.pushes is None else args.pushes
    recorded = []
    try:
        for i in range(count):
            print(f"episode {i + 1}:")
            episode = run_segments(
                robot, predictor, policy, pushes, args.segments, print_push, seed=args.seed + i
            )
            if len(episode.run_estimates) > 1:
                mean = np.mean(episode.run_estimates, axis=0)
                print(f"  estimate {fmt(mean)}, averaged over {len(episode.run_estimates)} runs")
            truth = getattr(robot, "truth", {})
            if "mass_distribution" in truth:
                print(f"  truth    {fmt(truth['mass_distribution'])}")
            recorded.append(episode.recorded(id="", masses=truth.get("masses"), label=args.label))
    finally:
        robot.close()
    if args.record:
        _record(args.record, setting, f"masspush simulation ({args.robot})", recorded)
    return 0


def _record(path: str, setting, robot: str, episodes: list[dict]) -> None:
    """Write episodes to a recording, appending when the file exists (one file can then
    gather several runs, e.g. one per labelled class)."""
    from pathlib import Path

    from masspush.data.recording import Recording, read_recording, write_recording

    usable = [e for e in episodes if len(e["actions"])]
    if Path(path).exists():
        recording = read_recording(path)
        if recording.n_links != setting.n_links:
            raise ValueError(f"{path} holds {recording.n_links}-link chains; not appending")
    else:
        recording = Recording(n_links=setting.n_links, robot=robot, setting=setting.name)
    start = len(recording.episodes)
    for i, e in enumerate(usable):
        e["id"] = f"{e.get('label') or 'episode'}-{start + i + 1:04d}"
    recording.episodes.extend(usable)
    write_recording(path, recording)
    print(f"recorded {len(usable)} episode(s) to {path} ({len(recording.episodes)} in all)")


def cmd_finetune(args: argparse.Namespace) -> int:
    """The paper's real-robot adaptation: a classifier on the predictor's features."""
    from masspush.data.recording import read_recording
    from masspush.learn.predictor import load_model
    from masspush.models import resolve_model
    from masspush.real.finetune import (
        ClassifierConfig,
        classifier_inputs,
        cross_validate,
        finetune_predictor,
        fit_classifier,
        labelled,
        save_classifier,
    )
    from masspush.settings import get_setting

    setting = get_setting(args.setting, args.settings_file)
    path = resolve_model(args.model, setting.name)
    predictor, meta = load_model(path, setting.name)
    recording = read_recording(args.episodes)
    if recording.n_links != setting.n_links:
        raise ValueError(
            f"{args.episodes} holds {recording.n_links}-link chains, setting {setting.name!r} "
            f"has {setting.n_links} links"
        )
    episodes = recording.to_episodes()
    if args.predictor_out:
        out = finetune_predictor(path, episodes, args.predictor_out, recording=str(args.episodes))
        print(f"fine-tuned predictor: {out}")
        return 0
    labels, classes = labelled(recording)
    config = ClassifierConfig(
        folds=args.folds, features=args.features, segment=args.segment, runs=args.runs,
        seed=args.seed,
    )  # fmt: skip
    features, owner = classifier_inputs(predictor, episodes, config)
    scores = cross_validate(features, labels, len(classes), config, owner)
    print(
        f"{len(labels)} episodes, {len(classes)} classes: {args.folds}-fold cross-validated "
        f"accuracy {100 * scores['accuracy']:.1f} % (chance {100 * scores['chance']:.1f} %)"
    )
    print("confusion (rows: truth, columns: predicted), classes in this order:", classes)
    for row in scores["confusion"]:
        print("  " + " ".join(f"{v:4d}" for v in row))
    model = fit_classifier(features, labels[owner], len(classes), config)
    info = {"setting": setting.name, "predictor": str(path), "predictor_meta": meta,
            "features": config.features, "segment": config.segment, "runs": config.runs,
            "episodes": str(args.episodes), "cross_validation": scores}  # fmt: skip
    print(f"saved {save_classifier(args.out, model, classes, config, info)} (trained on all)")
    return 0


def cmd_classify(args: argparse.Namespace) -> int:
    """Apply a saved classifier to recorded episodes."""
    from masspush.data.recording import read_recording
    from masspush.learn.predictor import load_model
    from masspush.real.finetune import (
        ClassifierConfig,
        classifier_inputs,
        episode_log_probs,
        load_classifier,
    )

    model, classes, meta = load_classifier(args.classifier)
    predictor, _ = load_model(meta["predictor"], meta["setting"])
    recording = read_recording(args.episodes)
    # Classifiers saved before runs could be read one by one averaged them.
    reading = ClassifierConfig(
        features=meta.get("features", "estimate"),
        segment=meta.get("segment", 0),
        runs=meta.get("runs", "average"),
    )
    features, owner = classifier_inputs(predictor, recording.to_episodes(), reading)
    probs = np.exp(episode_log_probs(model, features, owner, len(recording.episodes)))
    right = 0
    for episode, p in zip(recording.episodes, probs, strict=True):
        guess = classes[int(p.argmax())]
        truth = episode.get("label")
        right += guess == truth
        mark = "" if truth is None else f"  (label {truth}{', right' if guess == truth else ''})"
        print(f"{episode['id']}: {guess}  p={p.max():.2f}{mark}")
    known = sum(e.get("label") is not None for e in recording.episodes)
    if known:
        print(f"accuracy on the {known} labelled episode(s): {100 * right / known:.1f} %")
    return 0


def cmd_sim2real(args: argparse.Namespace) -> int:
    """The paper's real-robot protocol in the sim-to-real target world."""
    from masspush.real.finetune import ClassifierConfig
    from masspush.real.sim2real import Sim2RealConfig, run_sim2real

    config = Sim2RealConfig(
        setting=args.setting,
        episodes_per_class=args.episodes_per_class,
        seed=args.seed,
        world=args.world,
        severity=args.severity,
        lab=args.lab,
        segments=args.segments,
        classifier=ClassifierConfig(folds=args.folds, runs=args.runs, seed=args.seed),
        models={"random": args.random_model, "learned": args.learned_model},
    )
    run_sim2real(config, args.out)
    print((Path(args.out) / "summary.md").read_text(), end="")
    print(f"recordings and summary in {args.out}")
    return 0


def cmd_randomise(args: argparse.Namespace) -> int:
    """Domain randomisation: fine-tune a predictor on episodes from randomised worlds."""
    from masspush.real.randomise import RandomiseConfig, randomise

    config = RandomiseConfig(
        setting=args.setting,
        model=args.model,
        episodes=args.episodes,
        steps=args.steps,
        base_seed=args.seed,
        policy_steps=args.policy_steps,
        policy_envs=args.envs,
        world=args.world,
    )
    suffix = "-policy" if args.policy_steps else ""
    suffix += "-target" if args.world == "target" else ""
    out = args.out or f"runs/randomise-{args.setting}{suffix}"
    path = randomise(config, out, args.workers, ship=args.ship)
    print(f"randomised predictor: {path}")
    return 0


def cmd_calibrate(args: argparse.Namespace) -> int:
    """Fit a model's Dirichlet uncertainty head on fresh episodes of its policy."""
    from masspush.learn.uncertainty import HeadConfig, calibrate
    from masspush.settings import get_setting

    setting = get_setting(args.setting, args.settings_file)
    result = calibrate(setting, args.model, HeadConfig(episodes=args.episodes), args.out)
    print(
        f"wrote {result['file']} (fitted on {result['episodes']} episodes; 90 % intervals "
        f"cover {100 * result['coverage_on_fit']:.1f} % of them); "
        f"`masspush evaluate --setting {setting.name} --model {args.model}` reports coverage"
    )
    return 0


def cmd_bayes_table(args: argparse.Namespace) -> int:
    """The Bayesian estimator and the learned uncertainty beside Table 1 (resumable)."""
    from masspush.reports.baselines import PAPER_TABLE
    from masspush.reports.bayes_table import bayes_table

    names = list(PAPER_TABLE) if args.settings == "all" else args.settings.split(",")
    text = bayes_table(
        names,
        args.episodes,
        args.models.split(","),
        tp_episodes=args.tp_episodes,
        measure_missing=not args.table_only,
    )
    print(text, end="")
    print("wrote results/bayes.md")
    return 0


def cmd_check_episodes(args: argparse.Namespace) -> int:
    """Validate a recording: every problem with its line and field."""
    from masspush.data.recording import check_recording, read_recording

    problems = check_recording(args.file)
    for problem in problems:
        print(f"{args.file}: {problem}")
    if problems:
        return 1
    recording = read_recording(args.file)
    labels = sorted({label for label in recording.labels if label is not None})
    print(
        f"{args.file}: good: {len(recording.episodes)} episode(s) of a {recording.n_links}-link "
        f"chain" + (f", labels {labels}" if labels else "")
    )
    return 0


def cmd_bench_sim(args: argparse.Namespace) -> int:
    from masspush.reports.bench import bench_sim

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

    from masspush.reports.bench import bench_pushers, pushers_table

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
    from masspush.reports.bench import bench_data

    print(json.dumps(bench_data(args.setting, args.pusher, args.episodes, args.workers)))
    return 0


def cmd_bench_train(args: argparse.Namespace) -> int:
    from masspush.reports.bench import bench_train

    for row in bench_train(args.setting, args.episodes, args.steps):
        print(json.dumps(row))
    return 0


def cmd_bench_ppo(args: argparse.Namespace) -> int:
    from masspush.reports.bench import bench_ppo

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
    from masspush.data.dataset import load_dataset

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

    from masspush.sim.convergence import format_table, validate_physics

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
    from masspush.reports.render import render_episode

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
    from masspush.data.dataset import collect
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

    from masspush.data.dataset import code_version, load_dataset
    from masspush.learn.predictor import FAST, TrainConfig, train_predictor

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


def bayes_options(pairs: list[str] | None) -> dict[str, Any] | None:
    """KEY=VALUE pairs into BayesConfig fields: numbers as numbers, "none" as None, text
    for the text fields (arm_model)."""
    from dataclasses import fields

    from masspush.bayes.filter import BayesConfig

    if not pairs:
        return None
    kinds = {f.name: str(f.type) for f in fields(BayesConfig)}
    options: dict[str, Any] = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        if not sep or key not in kinds:
            raise SystemExit(f"--bayes wants KEY=VALUE, KEY one of {sorted(kinds)}; got {pair!r}")
        if kinds[key] == "str":
            options[key] = text
            continue
        try:
            value = None if text.lower() == "none" else float(text)
        except ValueError:
            raise SystemExit(f"--bayes {key} wants a number or none, got {text!r}") from None
        integer = kinds[key].startswith("int") and value is not None
        options[key] = int(value) if integer else value
    return options


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
        bayes=bayes_options(args.bayes),
        per_episode=args.per_episode or args.paired_with is not None,
    )
    if args.paired_with is not None:
        from masspush.metrics import paired_difference_interval, paired_percentage_errors

        other = json.loads(Path(args.paired_with).read_text())
        if "per_episode" not in other:
            raise SystemExit(f"{args.paired_with} has no per-episode record (--per-episode)")
        mine, theirs = result["per_episode"], other["per_episode"]
        own, their_error, n = paired_percentage_errors(mine, theirs)
        result["paired"] = {
            "with": other.get("model"),
            "episodes": n,
            "percentage_error": own,
            "their_percentage_error": their_error,
            "difference_95_interval": paired_difference_interval(mine, theirs),
        }
    if args.json:
        print(json.dumps(result))
    else:
        for key, value in result.items():
            if key == "per_episode":  # one line per episode: for --json only
                continue
            print(f"{key:34s} {value}")
    return 0


def cmd_baselines(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from masspush.learn.predictor import FAST, TrainConfig
    from masspush.reports.baselines import run_baselines, ship
    from masspush.settings import get_setting

    if args.table:
        from masspush.reports.baselines import baselines_table

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
    from masspush.learn.policy import PolicyConfig
    from masspush.learn.recipe import RecipeConfig

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
    from masspush.learn.recipe import Recipe
    from masspush.models import SHIPPED_DIR
    from masspush.reports.reproduce import train_dir
    from masspush.settings import get_setting

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
    from masspush.learn.predictor import FAST
    from masspush.learn.recipe import Recipe
    from masspush.models import SHIPPED_DIR
    from masspush.reports.baselines import PAPER_TABLE, run_baselines, ship
    from masspush.reports.reproduce import train_dir, write_outputs
    from masspush.settings import get_setting

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
    from masspush.learn.policy import ALGOS

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
    p.add_argument("--envs", type=int, default=64, help="parallel environments (default 64)")
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


def _runs_arg(p: argparse.ArgumentParser, segments_flag: str) -> None:
    p.add_argument(
        "--runs", default="each", choices=("each", "average"),
        help=f"with {segments_flag}: classify each run and add up their log-probabilities "
        "(each), or classify the runs' averaged features (average)",
    )  # fmt: skip


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

    demo = sub.add_parser(
        "demo", help="a trained policy pushes a random chain; the estimate after each push"
    )
    demo.add_argument("--setting", default=None, help="named setting (default 2link-1-10)")
    demo.add_argument("--model", default="tp+", help="shipped name (rp, rp+, tp, tp+) or path")
    demo.add_argument("--seed", type=int, default=0, help="the chain's random seed (default 0)")
    demo.add_argument("--out", default="masspush-demo.png", help="picture to write (PNG)")
    demo.add_argument("--video", default=None, help="also render the episode to this MP4/GIF")
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
    ev.add_argument(
        "--model",
        required=True,
        help="a model file; rp, rp+, tp, tp+; or bayes, bayes-random (the particle filter)",
    )
    ev.add_argument("--episodes", type=int, default=800)
    ev.add_argument("--seed", type=int, default=0)
    ev.add_argument("--pusher", default=None, help="default: the one the model was trained with")
    ev.add_argument("--workers", type=int, default=None)
    ev.add_argument("--json", action="store_true", help="print one JSON object")
    ev.add_argument(
        "--bayes", action="append", metavar="KEY=VALUE",
        help="change a BayesConfig field of the particle filter (repeatable), "
        "e.g. --bayes likelihood_power=0.6",
    )  # fmt: skip
    ev.add_argument(
        "--per-episode", action="store_true",
        help="record each scored episode's estimate and truth (the filter always does)",
    )  # fmt: skip
    ev.add_argument(
        "--paired-with", metavar="JSON", default=None,
        help="an earlier `evaluate --json` of another model on the same setting, seed and "
        "episodes: also score both on the episodes both scored, with a 95 %% bootstrap "
        "interval of the difference",
    )  # fmt: skip
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

    run = sub.add_parser(
        "run", help="estimation episodes through a robot backend (simulated or replayed)"
    )
    run.add_argument(
        "--robot", required=True, help="stiff, kuka, ur10, target (sim-to-real) or replay"
    )
    run.add_argument("--setting", required=True, help="named setting, e.g. 2link-0.1-1")
    run.add_argument("--settings-file", default=None, help="TOML file with custom settings")
    run.add_argument("--model", default="tp+", help="shipped name (rp, rp+, tp, tp+) or path")
    run.add_argument("--episodes-file", default=None, help="replay: the recording to play")
    run.add_argument("--count", type=int, default=None, help="episodes (replay: all)")
    run.add_argument("--pushes", type=int, default=None, help="default: one per link")
    run.add_argument("--seed", type=int, default=0, help="simulated chains' first seed")
    run.add_argument("--record", default=None, help="write the session as a recording")
    run.add_argument("--masses", default=None, help="simulated: pin link masses, kg 'm1,m2'")
    run.add_argument("--label", default=None, help="class label written into the recording")
    run.add_argument(
        "--segments", type=int, default=1,
        help="run the policy this many times in a row on each chain (each --pushes pushes) "
        "and average the runs' estimates",
    )  # fmt: skip
    run.add_argument(
        "--lab", type=int, default=None, metavar="SEED",
        help="target: keep one lab's table, calibration, robot and chains for every episode",
    )  # fmt: skip
    run.set_defaults(func=cmd_run)

    ft = sub.add_parser(
        "finetune", help="classifier on a predictor's features from labelled recordings"
    )
    ft.add_argument("--setting", required=True, help="the predictor's setting")
    ft.add_argument("--settings-file", default=None, help="TOML file with custom settings")
    ft.add_argument("--model", default="tp+", help="shipped name or path of the predictor")
    ft.add_argument("--episodes", required=True, help="recording with labelled episodes")
    ft.add_argument("--out", default="classifier.pt", help="where to save the classifier")
    ft.add_argument("--folds", type=int, default=5, help="cross-validation folds")
    ft.add_argument("--seed", type=int, default=0)
    ft.add_argument(
        "--segment", type=int, default=0, metavar="P",
        help="the episodes are runs of P pushes each (recorded with --segments): read each run "
        "on its own (default 0: read each episode whole)",
    )  # fmt: skip
    _runs_arg(ft, "--segment")
    ft.add_argument(
        "--features",
        default="estimate",
        choices=("estimate", "lstm"),
        help="the classifier's input: the predictor's estimate, or its LSTM output (paper)",
    )
    ft.add_argument(
        "--predictor-out",
        default=None,
        help="instead: fine-tune the predictor itself into this directory (needs masses)",
    )
    ft.set_defaults(func=cmd_finetune)

    cl = sub.add_parser("classify", help="apply a saved classifier to recorded episodes")
    cl.add_argument("--classifier", required=True)
    cl.add_argument("--episodes", required=True, help="recording")
    cl.set_defaults(func=cmd_classify)

    s2r = sub.add_parser(
        "sim2real", help="the paper's real-robot test in the sim-to-real target world"
    )
    s2r.add_argument("--setting", default="real-ur10")
    s2r.add_argument("--episodes-per-class", type=int, default=30, help="paper: 30")
    s2r.add_argument("--folds", type=int, default=5, help="cross-validation folds")
    s2r.add_argument("--seed", type=int, default=0)
    s2r.add_argument("--out", default="results/sim2real", help="recordings and summary")
    s2r.add_argument(
        "--world",
        default="target",
        choices=("target", "training"),
        help="training: the control run in the models' own world",
    )
    s2r.add_argument(
        "--severity", type=float, default=1.0,
        help="scale the target world's differences from training: 1 as built, 0 none; how "
        "close to the simulation must a lab be?",
    )  # fmt: skip
    s2r.add_argument(
        "--lab", type=int, default=None, metavar="SEED",
        help="one lab: the target world's table, calibration, robot and chains drawn once "
        "from SEED and kept for every episode, as in a real lab (default: drawn per episode)",
    )  # fmt: skip
    s2r.add_argument(
        "--segments", type=int, default=1,
        help="runs of each policy per episode, on the same chain one after the other (1: the "
        "paper's protocol)",
    )  # fmt: skip
    _runs_arg(s2r, "--segments")
    s2r.add_argument("--random-model", default="rp", help="the random-push arm's model")
    s2r.add_argument("--learned-model", default="tp+", help="the learned arm's model, e.g. tp+dr")
    s2r.set_defaults(func=cmd_sim2real)

    rnd = sub.add_parser(
        "randomise",
        help="fine-tune a predictor on its policy's episodes in randomised worlds",
    )
    rnd.add_argument("--setting", default="real-ur10-4push")
    rnd.add_argument("--model", default="tp+", help="shipped name or path of the predictor")
    rnd.add_argument("--episodes", type=int, default=8000)
    rnd.add_argument("--steps", type=int, default=10_000, help="fine-tuning steps")
    rnd.add_argument("--seed", type=int, default=50_000_000, help="base seed of the episodes")
    rnd.add_argument(
        "--policy-steps", type=int, default=0,
        help="first train the model's policy on with PPO in randomised worlds for this many "
        "pushes (0: keep the policy); ships as tp+drp",
    )  # fmt: skip
    rnd.add_argument("--envs", type=int, default=8, help="PPO's parallel environments")
    rnd.add_argument(
        "--world", choices=("randomised", "target"), default="randomised",
        help="target: collect in the sim-to-real target world itself instead, an upper bound "
        "(what many labelled episodes of the tested setup could give); not for --ship",
    )  # fmt: skip
    rnd.add_argument("--workers", type=int, default=None, help="default: one per core")
    rnd.add_argument("--out", default=None, help="default: runs/randomise-<setting>")
    rnd.add_argument(
        "--ship",
        action="store_true",
        help="ship the result as tp+dr (tp+drp with --policy-steps) beside the model",
    )
    rnd.set_defaults(func=cmd_randomise)

    cal = sub.add_parser(
        "calibrate", help="fit a model's learned uncertainty (a Dirichlet head) for intervals"
    )
    cal.add_argument("--setting", required=True)
    cal.add_argument("--settings-file", default=None, help="TOML file with custom settings")
    cal.add_argument("--model", default="tp+", help="shipped name or path of the predictor")
    cal.add_argument("--episodes", type=int, default=4000, help="fresh episodes to fit on")
    cal.add_argument("--out", default=None, help="default: <model>.dirichlet.pt beside it")
    cal.set_defaults(func=cmd_calibrate)

    bt = sub.add_parser(
        "bayes-table", help="the Bayesian estimator and learned uncertainty beside Table 1"
    )
    bt.add_argument("--settings", default="all", help="all, or a comma-separated list")
    bt.add_argument("--episodes", type=int, default=50, help="per setting, for the filter")
    bt.add_argument("--models", default="bayes,bayes-random,tp+")
    bt.add_argument("--tp-episodes", type=int, default=800, help="for TP+ and its coverage")
    bt.add_argument("--table-only", action="store_true", help="only rebuild from the cache")
    bt.set_defaults(func=cmd_bayes_table)

    chk = sub.add_parser("check-episodes", help="validate a recording (docs/real-robot.md)")
    chk.add_argument("file")
    chk.set_defaults(func=cmd_check_episodes)

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
