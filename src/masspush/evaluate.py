"""The one evaluation path: fresh simulated episodes, any estimator's estimates, every metric.

An `Estimator` is anything that pushes chains and turns what it saw into estimates of their
mass distributions: a trained predictor with its pushing policy
(`masspush.learn.estimator.PredictorEstimator`), the particle filter
(`masspush.bayes.estimator.BayesEstimator`), or your own. `evaluate` gives it the episodes,
scores what it returns and hands back one typed `EvalResult`, the same for all of them.
`masspush.estimators.load_estimator` makes one from a name or a model file.

Episodes are drawn from the EVAL seed stream (`masspush.data.rollout`), which never meets
the TRAIN stream that datasets are collected from, so evaluation never reuses a training seed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from masspush.config import EnvConfig
from masspush.metrics import all_metrics, percentage_error
from masspush.settings import Setting


@dataclass
class EstimatorRun:
    """What an estimator made of a set of evaluation episodes."""

    index: np.ndarray
    """(m,) the scored episodes' indices in the evaluation stream (failed ones left out)."""
    estimates: np.ndarray
    """(m, K, n) the estimated mass distribution after each push."""
    truth: np.ndarray
    """(m, n) the true mass distributions."""
    failures: int
    """Episodes that failed (a push threw the chain, ...) and are not scored."""
    extra: dict[str, Any] = field(default_factory=dict)
    """What this kind of estimator reports besides (interval coverage, timings, ...)."""


class Estimator(Protocol):
    """Pushes fresh chains and estimates their mass distributions."""

    name: str
    """How results name it: a shipped model's name, a model file, "bayes"."""
    policy: str
    """Which pushes it makes ("random", "learned:...", "information-seeking")."""
    pusher: str
    """The pusher that delivers its pushes (a name in `masspush.sim.pushers.PUSHERS`)."""
    model_file: str | None
    """The file it was loaded from, where there is one."""

    def run(
        self, env_config: EnvConfig, indices: np.ndarray, seed: int, workers: int | None
    ) -> EstimatorRun:
        """Episodes `indices` of the EVAL stream of base seed `seed`, in `env_config`."""


@dataclass
class EvalResult:
    """An estimator's score on fresh episodes (`to_dict` is the JSON of `masspush evaluate`)."""

    setting: str
    model: str
    pusher: str
    policy: str
    seed: int
    episodes: int
    """Episodes scored."""
    failures: int
    metrics: dict[str, float]
    """`masspush.metrics.all_metrics` of the final estimates: percentage_error (the
    paper's metric), relative_error, mae and the constant-guess floors."""
    after_each_push: list[float]
    """The paper's metric after push 1, 2, ..., K."""
    model_file: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    per_episode: dict[str, list] | None = None
    """Each scored episode's index, final estimate and truth (`per_episode_record`)."""

    @property
    def percentage_error(self) -> float:
        return self.metrics["percentage_error"]

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"setting": self.setting, "model": self.model}
        if self.model_file is not None:
            out["model_file"] = self.model_file
        out.update(
            pusher=self.pusher, policy=self.policy, seed=self.seed, episodes=self.episodes,
            failures=self.failures, **self.metrics,
            percentage_error_after_each_push=self.after_each_push, **self.extra,
        )  # fmt: skip
        if self.per_episode is not None:
            out["per_episode"] = self.per_episode
        return out


def evaluate(
    setting: Setting,
    estimator: Estimator,
    episodes: int = 800,
    seed: int = 0,
    workers: int | None = None,
    per_episode: bool = False,
) -> EvalResult:
    """Run `episodes` fresh episodes of `setting` with `estimator` and score them.
    `per_episode` adds each scored episode's index, final estimate and truth, so that two
    estimators can be compared on the same episodes."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    env_config = setting.env_config(estimator.pusher)
    run = estimator.run(env_config, np.arange(episodes), seed, workers)
    if len(run.truth) == 0:
        raise ValueError("every evaluation episode failed; nothing to score")
    final = run.estimates[:, -1]
    return EvalResult(
        setting=setting.name,
        model=estimator.name,
        pusher=estimator.pusher,
        policy=estimator.policy,
        seed=seed,
        episodes=len(run.truth),
        failures=int(run.failures),
        metrics=all_metrics(final, run.truth),
        after_each_push=[
            percentage_error(run.estimates[:, k], run.truth) for k in range(run.estimates.shape[1])
        ],
        model_file=estimator.model_file,
        extra=run.extra,
        per_episode=per_episode_record(run.index, final, run.truth) if per_episode else None,
    )


def per_episode_record(index, estimates, truths) -> dict[str, list]:
    """Scored episodes (their index in the evaluation stream), final estimates and truths,
    as JSON lists."""
    return {
        "index": [int(i) for i in index],
        "estimate": np.asarray(estimates, float).round(6).tolist(),
        "truth": np.asarray(truths, float).round(6).tolist(),
    }
