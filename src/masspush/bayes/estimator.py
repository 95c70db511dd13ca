"""The particle filter as an `Estimator` (`masspush.evaluate`): fresh chains pushed by the
setting's pusher, with information-seeking or random pushes, estimated push by push."""

from __future__ import annotations

import time
import warnings
from dataclasses import replace

import numpy as np
from tqdm import tqdm

from masspush.bayes.filter import (
    BayesConfig,
    InfoSeekingPolicy,
    ParticleFilter,
    UnexplainedObservationWarning,
    default_config,
    filter_for,
)
from masspush.config import EnvConfig
from masspush.data.rollout import EVAL, episode_seed
from masspush.env import ChainEnv
from masspush.evaluate import EstimatorRun
from masspush.metrics import percentage_error
from masspush.settings import Setting

BAYES_MODELS = {"bayes": True, "bayes-random": False}
"""Model names `masspush evaluate` accepts for the filter: with information-seeking pushes,
or with the paper's random pushes."""


def run_bayes_episode(
    env, filt: ParticleFilter, policy: InfoSeekingPolicy | None, seed: int, pushes: int
) -> dict:
    """One episode of a ChainEnv estimated by the filter; pushes chosen by `policy` (None:
    uniform random). Returns the truth, the posterior after each push and the failure."""
    obs, info = env.reset(seed=seed)
    d = env.physics.obs_dim
    result = {"truth": info["mass_distribution"], "posteriors": [], "actions": [],
              "failure": info["failure"]}  # fmt: skip
    if info["failure"] is not None:
        return result
    filt.reset(obs[d:])
    rng = np.random.default_rng([seed, 1])  # the paper's random policy's stream
    start = obs[:d].astype(float)
    for _ in range(pushes):
        if policy is None:
            # Random pushes over the same range as the information-seeking candidates, so
            # the two differ only in how a push is chosen.
            action = rng.uniform(-1, 1, 2) * (filt.config.max_push, 1.0)
        else:
            action = policy.act(start)
        result["actions"].append(np.asarray(action, float))
        obs, _, done, _, info = env.step(np.asarray(action, np.float32))
        if info["failure"] is not None:
            result["failure"] = info["failure"]
            break
        observed = obs[:d].astype(float)
        result["posteriors"].append(filt.update(start, action, observed))
        start = observed
        if done:
            break
    return result


class BayesEstimator:
    """The filter on fresh episodes: chains pushed by `pusher` (the setting's by default, an
    arm for the KUKA settings), the filter simulating the same pusher (`filter_for`),
    configured by `config` (`default_config`'s by default) changed by `overrides`.

    Besides the metrics it reports interval coverage, seconds per episode and the
    observations no particle explained; and always each episode's estimate, since a run of
    the filter is too costly to repeat for a later pairing."""

    always_per_episode = True

    def __init__(
        self, setting: Setting, model: str = "bayes", pusher: str | None = None,
        config: BayesConfig | None = None, overrides: dict | None = None, progress: bool = True,
    ):  # fmt: skip
        if model not in BAYES_MODELS:
            raise ValueError(f"unknown Bayesian model {model!r}; known: {list(BAYES_MODELS)}")
        self.setting, self.name, self.progress = setting, model, progress
        self.pusher = pusher or setting.pusher
        self.config = replace(config or default_config(setting, self.pusher), **(overrides or {}))
        self.seeking = BAYES_MODELS[model]
        self.policy = "information-seeking" if self.seeking else "random"
        self.model_file = None

    def run(
        self, env_config: EnvConfig, indices: np.ndarray, seed: int, workers: int | None
    ) -> EstimatorRun:
        env = ChainEnv.from_config(env_config)
        filt = filter_for(self.setting, self.pusher, self.config, seed)
        policy = InfoSeekingPolicy(filt, seed) if self.seeking else None
        k = env_config.pushes
        estimates, means, truths, inside, failures, unexplained = [], [], [], [], 0, 0
        scored = []
        start = time.perf_counter()
        label = f"{self.name} on {self.setting.name}"
        for i in tqdm(indices, desc=label, disable=not self.progress):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UnexplainedObservationWarning)
                result = run_bayes_episode(env, filt, policy, episode_seed(EVAL, seed, int(i)), k)
            unexplained += filt.warnings
            if result["failure"] is not None or len(result["posteriors"]) < k:
                failures += 1  # left out of the metric, as the learned models' failures are
                continue
            scored.append(int(i))
            truths.append(result["truth"])
            estimates.append(np.array([p.estimate for p in result["posteriors"]]))
            means.append(result["posteriors"][-1].mean)
            last = result["posteriors"][-1]
            inside.append((last.low <= result["truth"]) & (result["truth"] <= last.high))
        seconds = (time.perf_counter() - start) / max(len(indices), 1)
        filt.close()
        if not estimates:
            return EstimatorRun(np.empty(0, int), np.empty((0, k, 0)), np.empty((0, 0)), failures)
        truth = np.array(truths)
        return EstimatorRun(
            index=np.array(scored),
            estimates=np.array(estimates),
            truth=truth,
            failures=failures,
            extra={
                # The other point estimate's error, for the record (BayesConfig.point).
                "percentage_error_of_posterior_mean": percentage_error(np.array(means), truth),
                "coverage": float(np.mean(inside)),
                "credible": filt.config.credible,
                "filter": filt.settings(),
                "seconds_per_episode": seconds,
                "unexplained_observations": unexplained,
            },
        )
