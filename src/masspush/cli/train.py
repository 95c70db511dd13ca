"""Commands that train: the predictor, the baselines, the recipe, Table 1, uncertainty, the
filter's learned likelihood."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from masspush.cli.command import Command
from masspush.cli.options import add_fields, build

if TYPE_CHECKING:
    from masspush.learn.recipe import RecipeConfig

GROUP = "train"


def _predictor_options(p: argparse.ArgumentParser) -> None:
    from masspush.learn.predictor import PredictorRun, TrainConfig

    add_fields(p, PredictorRun)
    add_fields(p, TrainConfig, only=("features", "optimizer", "steps", "batch_size", "lr",
                                     "loss", "width", "seed"))  # fmt: skip


def _predictor(args: argparse.Namespace) -> int:
    from masspush.learn.predictor import FAST, PredictorRun, TrainConfig, train_on_dataset

    run = build(PredictorRun, args)
    config = build(TrainConfig, args, base=FAST if run.fast else TrainConfig())
    path, summary = train_on_dataset(run, config)
    print(
        f"wrote {path}: best validation percentage error "
        f"{summary['best_validation_error']:.2f} at step {summary['best_step']} "
        f"({summary['samples_per_s']:.0f} samples/s)"
    )
    return 0


def _baselines_options(p: argparse.ArgumentParser) -> None:
    from masspush.reports.baselines import BaselinesConfig

    add_fields(p, BaselinesConfig, pairs=("episodes",))


def _baselines(args: argparse.Namespace) -> int:
    from masspush.reports.baselines import BaselinesConfig, baselines

    print("\n".join(baselines(build(BaselinesConfig, args))))
    return 0


RECIPE_FIELDS = ("meta_iterations", "first_episodes", "iteration_episodes", "final_episodes",
                 "final_members", "eval_episodes", "seed")  # fmt: skip


def _recipe_options(p: argparse.ArgumentParser) -> None:
    from masspush.learn.policy import PolicyConfig
    from masspush.learn.recipe import FINAL_FINETUNE, RecipeConfig

    renamed = {"steps": "ppo_steps", "n_envs": "envs", "runs": "policy_runs",
               "reward": "policy_reward", "loss_reward": "policy_loss_reward",
               "lockstep_arms": "lockstep_arms"}  # fmt: skip
    add_fields(p, PolicyConfig, only=("algo", *renamed), prefix="policy_", rename=renamed)
    add_fields(p, RecipeConfig, only=RECIPE_FIELDS)
    p.add_argument(
        "--final-steps",
        type=int,
        default=argparse.SUPPRESS,
        help="Gradient steps of TP+'s fine-tuning on the final policy's rollouts; given "
        "otherwise than a run recorded (as --final-episodes), it redoes only TP+ (default: "
        f"the run's own; {FINAL_FINETUNE.steps} for a new run)",
    )
    p.add_argument(
        "--final-lr",
        type=float,
        default=argparse.SUPPRESS,
        help="Learning rate of TP+'s fine-tuning, likewise (default: the run's own; "
        f"{FINAL_FINETUNE.lr:g} for a new run)",
    )
    p.add_argument(
        "--final-loss",
        default=argparse.SUPPRESS,
        help="Loss of TP+'s fine-tuning, likewise: mse (the paper's) or l1 (the metric's) "
        f"(default: the run's own; {FINAL_FINETUNE.loss} for a new run)",
    )
    p.add_argument(
        "--final-width",
        type=int,
        default=argparse.SUPPRESS,
        help="TP+'s network, likewise: every layer this wide, two LSTM layers, trained from "
        "scratch (default: the run's own; the paper's FC 128 / LSTM 64 for a new run)",
    )


def _recipe(args: argparse.Namespace) -> RecipeConfig:
    from dataclasses import replace

    from masspush.learn.policy import PolicyConfig
    from masspush.learn.recipe import FINAL_FINETUNE, RecipeConfig

    policy = build(PolicyConfig, args, prefix="policy_")
    given = {
        k: getattr(args, f"final_{k}")
        for k in ("steps", "lr", "loss", "width")
        if f"final_{k}" in args
    }
    if not given:
        return build(RecipeConfig, args, policy=policy)
    try:  # what is not given is a new run's: the recorded config is not known here
        final = replace(FINAL_FINETUNE, **given)
    except ValueError as err:  # TrainConfig names the field; the user typed the option
        raise ValueError(f"--final-{err}") from None
    return build(RecipeConfig, args, policy=policy, final_finetune=final)


def _train_options(p: argparse.ArgumentParser) -> None:
    from masspush.reports.reproduction import TrainJob

    add_fields(p, TrainJob, required=("setting",))
    _recipe_options(p)


def _train(args: argparse.Namespace) -> int:
    from masspush.reports.reproduction import TrainJob, train_setting

    print("\n".join(train_setting(build(TrainJob, args), _recipe(args))))
    return 0


def _reproduce_options(p: argparse.ArgumentParser) -> None:
    from masspush.reports.reproduction import ReproduceConfig

    add_fields(p, ReproduceConfig)
    _recipe_options(p)


def _reproduce(args: argparse.Namespace) -> int:
    from masspush.reports.reproduction import ReproduceConfig, reproduce

    for path in reproduce(build(ReproduceConfig, args), _recipe(args)):
        print(f"wrote {path}")
    return 0


def _calibrate_options(p: argparse.ArgumentParser) -> None:
    from masspush.learn.uncertainty import HeadConfig
    from masspush.models import CalibrateJob

    add_fields(p, CalibrateJob, required=("setting",))
    add_fields(p, HeadConfig, only=("episodes",))


def _calibrate(args: argparse.Namespace) -> int:
    from masspush.learn.uncertainty import HeadConfig
    from masspush.models import CalibrateJob, calibrate_model

    print(calibrate_model(build(CalibrateJob, args), build(HeadConfig, args)))
    return 0


def _density_options(p: argparse.ArgumentParser) -> None:
    from masspush.learn.push_density import DensityConfig

    add_fields(p, DensityConfig)


def _density(args: argparse.Namespace) -> int:
    from masspush.learn.push_density import DensityConfig, train_push_density

    config = build(DensityConfig, args)
    summary = train_push_density(config)
    print(
        f"wrote {config.out}: trained on {summary['pushes']:,} pushes; on "
        f"{summary['held_out_pushes']:,} held out, log-likelihood "
        f"{summary['held_out_log_likelihood']:.3f} per push (standardised; higher is better); "
        f"{summary['seconds'] / 60:.1f} min"
    )
    return 0


COMMANDS = [
    Command("train-predictor", GROUP, "the LSTM predictor on a dataset (resumable)",
            _predictor_options, _predictor),
    Command("baselines", GROUP, "the paper's RP and RP+ for a setting (resumable)",
            _baselines_options, _baselines),
    Command("train", GROUP, "the alternating recipe: predictor, then policy / predictor rounds",
            _train_options, _train),
    Command("reproduce", GROUP, "the paper's Table 1 and figures (resumable)",
            _reproduce_options, _reproduce),
    Command("train-density", GROUP,
            "the particle filter's learned likelihood of a push on datasets (resumable)",
            _density_options, _density),
    Command("calibrate", GROUP, "fit a model's learned uncertainty (a Dirichlet head)",
            _calibrate_options, _calibrate),
]  # fmt: skip
