"""A trained predictor with the pushing policy it was trained with, as an `Estimator`
(`masspush.evaluate`): the paper's RP, RP+, TP and TP+ models."""

from __future__ import annotations

import os
import warnings

import numpy as np

from masspush.cluster.pool import Workers
from masspush.config import EnvConfig
from masspush.data.rollout import EVAL, Policy, run_episodes
from masspush.evaluate import EstimatorRun
from masspush.learn.policy import model_policy
from masspush.learn.predictor import Predictor, load_model
from masspush.learn.uncertainty import (
    PrecisionHead,
    StaleHeadError,
    coverage,
    head_path,
    load_head,
)
from masspush.sim.pushers import IDEAL_PUSHER


class PredictorEstimator:
    """Episodes pushed by `policy`, then the predictor's estimate after each push; with a
    Dirichlet head (`masspush.learn.uncertainty`) the result also reports interval coverage."""

    def __init__(
        self, predictor: Predictor, policy: Policy, pusher: str, name: str,
        model_file: str | None = None, head: PrecisionHead | None = None,
    ):  # fmt: skip
        self.predictor, self.policy_impl, self.pusher = predictor, policy, pusher
        self.name, self.model_file, self.head = name, model_file, head
        self.policy = policy.name

    @classmethod
    def from_file(
        cls, path: str | os.PathLike, setting: str, pusher: str | None = None,
        name: str | None = None, allow_mismatch: bool = False, n_links: int | None = None,
    ) -> PredictorEstimator:  # fmt: skip
        """The model file `path` (trained for `setting`), pushed by `pusher` (the pusher it
        was trained with by default), its policy and, where one fitted on it lies beside it, its
        head.
        `allow_mismatch`: run a model of another setting or pusher (of `n_links` links)."""
        predictor, meta = load_model(path, setting, pusher, allow_mismatch, n_links)
        trained_for = meta.get("setting", {}).get("name", setting)
        head = None
        if head_path(path).exists():
            try:
                head = load_head(head_path(path), trained_for, predictor)
            except StaleHeadError as err:  # the estimate stands; only its intervals would lie
                warnings.warn(f"{err}; reporting no coverage", stacklevel=2)
        return cls(predictor, model_policy(meta, path), pusher or meta.get("pusher", IDEAL_PUSHER),
                   name or str(path), str(path), head)  # fmt: skip

    def run(
        self, env_config: EnvConfig, indices: np.ndarray, seed: int, workers: Workers
    ) -> EstimatorRun:
        # Episodes may run on a cluster; the predictor runs here, on all of them at once.
        run = run_episodes(env_config, self.policy_impl, indices, EVAL, seed, workers,
                           desc=f"episodes for {self.name}")  # fmt: skip
        good = run.select(run.ok)
        if len(good) == 0:
            return EstimatorRun(np.empty(0, int), np.empty((0, 0, 0)), np.empty((0, 0)), len(run))
        extra = {}
        if self.head is not None:
            extra["coverage"] = coverage(self.predictor, self.head, good)
        return EstimatorRun(
            index=np.flatnonzero(run.ok),
            estimates=self.predictor.predict(good),
            truth=good.mass_distribution,
            failures=int(len(run) - len(good)),
            extra=extra,
        )
