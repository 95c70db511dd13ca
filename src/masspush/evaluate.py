"""The one evaluation path: fresh simulated episodes, a model's estimates, every metric.

Episodes are drawn from the EVAL seed stream (`masspush.rollout`), which never meets the
TRAIN stream that datasets are collected from, so evaluation never reuses a training seed.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from masspush.metrics import all_metrics, percentage_error
from masspush.predictor import load_model
from masspush.rollout import EVAL, POLICIES, run_episodes
from masspush.settings import Setting, get_setting

SHIPPED_DIR = Path(__file__).parent / "models"
"""Trained models shipped with the package: models/<setting>/<name>.pt."""
SHIPPED_NAMES = ("rp", "rp+", "tp", "tp+", "tp+dr")


def resolve_model(model: str | os.PathLike, setting: str) -> Path:
    """A shipped model's file for `setting` (by name: rp, rp+, tp, tp+), or a path."""
    if str(model) in SHIPPED_NAMES:
        path = SHIPPED_DIR / setting / f"{model}.pt"
        if not path.exists():
            have = sorted(p.stem for p in (SHIPPED_DIR / setting).glob("*.pt"))
            raise ValueError(
                f"no shipped {model!r} model for setting {setting!r} yet"
                + (f" (shipped for it: {have})" if have else "")
            )
        return path
    path = Path(model)
    if not path.exists():
        raise ValueError(f"no model file at {path} (shipped names: {list(SHIPPED_NAMES)})")
    return path


def model_policy(meta: dict[str, Any], model_file: str | os.PathLike):
    """The pushing policy a predictor was trained with: random, or the learned policy whose
    file its metadata names (relative to the model file), acting deterministically."""
    name = meta.get("policy", "random")
    if name == "learned":
        from masspush.policy import LearnedPolicy

        policy_file = Path(model_file).parent / meta["policy_file"]
        if not policy_file.exists():
            raise ValueError(f"{model_file} needs its policy file {policy_file}, which is missing")
        return LearnedPolicy(policy_file, meta["policy_algo"], deterministic=True)
    if name not in POLICIES:
        raise ValueError(f"{model_file} names an unknown policy {name!r}")
    return POLICIES[name]()


def model_and_policy(model: str | os.PathLike, setting: str):
    """A model (shipped name or path) for `setting`: its predictor, metadata and the
    policy it was trained with (`model_policy`)."""
    path = resolve_model(model, setting)
    predictor, meta = load_model(path, setting)
    return predictor, meta, model_policy(meta, path)


def evaluate(
    setting: str | Setting,
    model: str | os.PathLike,
    episodes: int = 800,
    seed: int = 0,
    pusher: str | None = None,
    settings_file: str | os.PathLike | None = None,
    workers: int | None = None,
    bayes: dict[str, Any] | None = None,
    per_episode: bool = False,
) -> dict[str, Any]:
    """Run `episodes` fresh episodes with the model's policy and report every metric.
    `model` "bayes" / "bayes-random" is the particle filter (`masspush.bayes`), its
    configuration changed by `bayes` (BayesConfig fields) where given. `per_episode` adds
    each scored episode's index, final estimate and truth (`per_episode_record`), which the
    filter always reports, so that two models can be compared on the same episodes."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    spec = setting if isinstance(setting, Setting) else get_setting(setting, settings_file)
    from masspush.bayes import BAYES_MODELS, evaluate_bayes

    if str(model) in BAYES_MODELS:
        return evaluate_bayes(spec, str(model), episodes, seed, pusher, overrides=bayes)
    if bayes:
        raise ValueError(f"bayes options apply to the particle filter, not to {model!r}")
    path = resolve_model(model, spec.name)
    predictor, meta = load_model(path, setting=spec.name, pusher=pusher)
    pusher = pusher or meta.get("pusher", "stiff")
    policy = model_policy(meta, path)
    env_config = spec.env_config(pusher)
    run = run_episodes(env_config, policy, np.arange(episodes), EVAL, seed, workers)
    good = run.select(run.ok)
    if len(good) == 0:
        raise ValueError("every evaluation episode failed; nothing to score")
    predictions = predictor.predict(good)
    truth = good.mass_distribution
    extra = {}
    from masspush.uncertainty import coverage, head_path, load_head

    if head_path(path).exists():  # the model's learned uncertainty
        extra["coverage"] = coverage(predictor, load_head(head_path(path), spec.name), good)
    result = {
        "setting": spec.name,
        "model": str(model),
        "model_file": str(path),
        "pusher": pusher,
        "policy": policy.name,
        "seed": seed,
        "episodes": len(good),
        "failures": int(len(run) - len(good)),
        **all_metrics(predictions[:, -1], truth),
        "percentage_error_after_each_push": [
            percentage_error(predictions[:, k], truth) for k in range(predictions.shape[1])
        ],
        **extra,
    }
    if per_episode:
        result["per_episode"] = per_episode_record(
            np.flatnonzero(run.ok), predictions[:, -1], truth
        )
    return result


def per_episode_record(index, estimates, truths) -> dict[str, list]:
    """Scored episodes (their index in the evaluation stream), final estimates and truths,
    as JSON lists."""
    return {
        "index": [int(i) for i in index],
        "estimate": np.asarray(estimates, float).round(6).tolist(),
        "truth": np.asarray(truths, float).round(6).tolist(),
    }
