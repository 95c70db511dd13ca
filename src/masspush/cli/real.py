"""Commands of the real-robot path: the classifier, the sim-to-real test, randomisation."""

from __future__ import annotations

import argparse

from masspush.cli.command import Command
from masspush.cli.options import add_bayes_option, add_fields, build

GROUP = "real robot"
CLASSIFIER_FIELDS = ("folds", "features", "segment", "runs", "seed")


def _finetune_options(p: argparse.ArgumentParser) -> None:
    from masspush.real.classifier import ClassifierConfig
    from masspush.real.classifier_jobs import FinetuneJob

    add_fields(p, FinetuneJob, required=("setting", "episodes"))
    add_fields(p, ClassifierConfig, only=CLASSIFIER_FIELDS)


def _finetune(args: argparse.Namespace) -> int:
    from masspush.real.classifier import ClassifierConfig
    from masspush.real.classifier_jobs import FinetuneJob, finetune

    print("\n".join(finetune(build(FinetuneJob, args), build(ClassifierConfig, args))))
    return 0


def _classify_options(p: argparse.ArgumentParser) -> None:
    from masspush.real.classifier_jobs import ClassifyJob

    add_fields(p, ClassifyJob, required=("episodes",))


def _classify(args: argparse.Namespace) -> int:
    from masspush.real.classifier_jobs import ClassifyJob, classify

    print("\n".join(classify(build(ClassifyJob, args))))
    return 0


def _tune_density_options(p: argparse.ArgumentParser) -> None:
    from masspush.real.classifier_jobs import TuneDensityJob
    from masspush.real.density_tuning import TuneConfig

    add_fields(p, TuneDensityJob, required=("setting", "episodes"))
    add_fields(p, TuneConfig)


def _tune_density(args: argparse.Namespace) -> int:
    from masspush.real.classifier_jobs import TuneDensityJob, tune
    from masspush.real.density_tuning import TuneConfig

    print("\n".join(tune(build(TuneDensityJob, args), build(TuneConfig, args))))
    return 0


def _sim2real_options(p: argparse.ArgumentParser) -> None:
    from masspush.real.classifier import ClassifierConfig
    from masspush.real.transfer import Sim2RealConfig, Sim2RealJob

    add_fields(p, Sim2RealConfig, only=("setting", "episodes_per_class", "seed", "world",
                                        "severity", "lab", "day", "start_range", "start_yaw",
                                        "segments", "governor_fit", "density", "tuned_density",
                                        "check_reach", "read_speeds"))  # fmt: skip
    add_fields(p, ClassifierConfig, only=("folds", "runs"), prefix="classifier_")
    add_fields(p, Sim2RealJob)
    add_bayes_option(p)


def _sim2real(args: argparse.Namespace) -> int:
    from masspush.bayes.filter import bayes_overrides
    from masspush.real.classifier import ClassifierConfig
    from masspush.real.transfer import Sim2RealConfig, Sim2RealJob, sim2real

    classifier = build(ClassifierConfig, args, prefix="classifier_")
    job = build(Sim2RealJob, args)
    models = {"random": job.random_model, "learned": job.learned_model}
    config = build(Sim2RealConfig, args, classifier=classifier, models=models,
                   bayes=bayes_overrides(args.bayes))  # fmt: skip
    print(sim2real(job, config), end="")
    print(f"recordings and summary in {job.out}")
    return 0


def _randomise_options(p: argparse.ArgumentParser) -> None:
    from masspush.real.randomisation import RandomiseConfig, RandomiseRun

    add_fields(p, RandomiseConfig, only=("setting", "model", "episodes", "steps", "base_seed",
                                         "policy_steps", "policy_envs", "world", "lab"),
               rename={"base_seed": "seed", "policy_envs": "envs"})  # fmt: skip
    add_fields(p, RandomiseRun)


def _randomise(args: argparse.Namespace) -> int:
    from masspush.real.randomisation import RandomiseConfig, RandomiseRun, randomise_run

    path = randomise_run(build(RandomiseConfig, args), build(RandomiseRun, args))
    print(f"randomised predictor: {path}")
    return 0


COMMANDS = [
    Command("finetune", GROUP, "a classifier on a predictor's features from labelled recordings",
            _finetune_options, _finetune),
    Command("classify", GROUP, "apply a saved classifier (or a tuned push density) to "
            "recorded episodes", _classify_options, _classify),
    Command("tune-density", GROUP, "tune the particle filter's push density to a lab's "
            "labelled episodes; sort classes by its posterior", _tune_density_options,
            _tune_density),
    Command("sim2real", GROUP, "the paper's real-robot test in the sim-to-real target world",
            _sim2real_options, _sim2real),
    Command("randomise", GROUP, "fine-tune a predictor on its policy's episodes in randomised "
            "worlds", _randomise_options, _randomise),
]  # fmt: skip
