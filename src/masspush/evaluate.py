"""The one evaluation path: fresh simulated episodes, any estimator's estimates, every metric.

An `Estimator` is anything that pushes chains and turns what it saw into estimates of their
mass distributions: a trained predictor with its pushing policy
(`masspush.learn.estimator.PredictorEstimator`), the particle filter
(`masspush.bayes.estimator.BayesEstimator`), or your own. `evaluate` gives it the episodes,
scores what it returns and hands back one typed `EvalResult`, the same for all of them.
`masspush.models.load_estimator` makes one from a name or a model file.

Episodes are drawn from the EVAL seed stream (`masspush.data.rollout`), which never meets
the TRAIN stream that datasets are collected from, so evaluation never reuses a training seed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np

from masspush.cluster.pool import Workers, check_address
from masspush.config import EnvConfig, check_input, check_int
from masspush.metrics import (
    all_metrics,
    paired_difference_interval,
    paired_percentage_errors,
    percentage_error,
)
from masspush.settings import Setting
from masspush.sim.pushers import pusher_field, pusher_kind


@dataclass(frozen=True)
class EvaluateConfig:
    """`masspush evaluate`: an estimator on fresh simulated episodes."""

    setting: str
    """Named setting of the episodes."""
    model: str
    """A model file; a shipped name (rp, rp+, tp, tp+, tp+dr); or bayes, bayes-random (the
    particle filter with information-seeking or random pushes)."""
    episodes: int = 800
    """Fresh episodes from the evaluation stream."""
    seed: int = 0
    """Base seed of the evaluation stream."""
    pusher: str | None = pusher_field()
    """The pusher (default: the one the model was trained with; the filter: the setting's)."""
    workers: int | None = None
    """Processes for an arm (default: one per core); with --ray local, the CPUs of the
    cluster started for the run."""
    ray: str | None = None
    """Run the episodes on a Ray cluster: auto, local, ray://HOST:PORT or HOST:PORT."""
    per_episode: bool = False
    """Record each scored episode's estimate and truth, for a later --paired-with (the particle
    filter always does)."""
    paired_with: str | None = None
    """An earlier `evaluate --json --per-episode` of another model on the same setting, seed
    and episodes: also score both on the episodes both scored, with a 95 % bootstrap
    interval of the difference."""
    settings_file: str | None = None
    """TOML file with custom settings."""
    allow_mismatch: bool = False
    """Run a model of another setting or pusher (same number of links), or pair with a
    result of another setting or seed."""

    MAX_EPISODES: ClassVar[int] = 10_000_000
    """More is a typo, not an evaluation: its arrays would not fit in memory."""

    def __post_init__(self) -> None:
        check_int("episodes", self.episodes)
        if self.episodes > self.MAX_EPISODES:
            raise ValueError(
                f"episodes must be at most {self.MAX_EPISODES:,}, got {self.episodes:,}"
            )
        check_int("seed", self.seed, 0)
        check_int("workers", self.workers, optional=True)
        check_address(self.ray)
        if self.pusher is not None:
            pusher_kind(self.pusher)
        if self.paired_with is not None:
            check_input(self.paired_with, "paired_with")


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

    # Optional: `always_per_episode = True` makes every result keep each episode's estimate
    # (for an estimator whose runs are too costly to repeat for a later pairing).

    def run(
        self, env_config: EnvConfig, indices: np.ndarray, seed: int, workers: Workers
    ) -> EstimatorRun:
        """Episodes `indices` of the EVAL stream of base seed `seed`, in `env_config`;
        `workers`: local processes, or a `masspush.cluster.pool.TaskPool` (a cluster) to
        run them on, with the same result."""


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

    def pair_with(self, other: dict[str, Any]) -> None:
        """Score this result and `other` (an earlier result's JSON, with its per-episode
        record) on the episodes both scored, into `extra["paired"]`."""
        if self.per_episode is None:
            raise ValueError("pairing needs this result's per-episode record (per_episode)")
        if not isinstance(other, dict) or "per_episode" not in other:
            raise ValueError("the other result has no per-episode record (--per-episode)")
        mine, theirs = self.per_episode, other["per_episode"]
        own, their_error, n = paired_percentage_errors(mine, theirs)
        self.extra["paired"] = {
            "with": other.get("model"),
            "episodes": n,
            "percentage_error": own,
            "their_percentage_error": their_error,
            "difference_95_interval": paired_difference_interval(mine, theirs),
        }

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
    workers: Workers = None,
    per_episode: bool = False,
) -> EvalResult:
    """Run `episodes` fresh episodes of `setting` with `estimator` and score them.
    `per_episode` adds each scored episode's index, final estimate and truth, so that two
    estimators can be compared on the same episodes."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    per_episode = per_episode or getattr(estimator, "always_per_episode", False)
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


def per_episode_record(
    index: np.ndarray, estimates: np.ndarray, truths: np.ndarray
) -> dict[str, list]:
    """Scored episodes (their index in the evaluation stream), final estimates and truths,
    as JSON lists."""
    return {
        "index": [int(i) for i in index],
        "estimate": np.asarray(estimates, float).round(6).tolist(),
        "truth": np.asarray(truths, float).round(6).tolist(),
    }
