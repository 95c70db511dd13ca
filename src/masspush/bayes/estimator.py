"""The particle filter as an `Estimator` (`masspush.evaluate`): fresh chains pushed by the
setting's pusher, with information-seeking or random pushes, estimated push by push."""

from __future__ import annotations

import copy
import time
import warnings
from dataclasses import replace

import numpy as np
from tqdm import tqdm

from masspush.bayes.filter import (
    BayesConfig,
    InfoSeekingPolicy,
    ParticleFilter,
    PushLikelihood,
    UnexplainedObservationWarning,
    default_config,
    filter_for,
)
from masspush.cluster.pool import Workers, gather, is_pool, split
from masspush.config import EnvConfig
from masspush.data.rollout import EVAL, episode_seed
from masspush.env import ChainEnv
from masspush.evaluate import EstimatorRun
from masspush.metrics import percentage_error
from masspush.settings import Setting
from masspush.sim.pushers import reach_governor
from masspush.sim.workspace import ReachGovernor

BAYES_MODELS = {"bayes": True, "bayes-random": False}
"""Model names `masspush evaluate` accepts for the filter: with information-seeking pushes,
or with the paper's random pushes."""


def run_bayes_episode(
    env: ChainEnv, filt: ParticleFilter, policy: InfoSeekingPolicy | None, seed: int,
    pushes: int, governor: ReachGovernor | None = None,
) -> dict:  # fmt: skip
    """One episode of a ChainEnv estimated by the filter; pushes chosen by `policy` (None:
    uniform random), a stationary robot's through its speed `governor` as it makes them
    (the policy's candidates are governed before they are compared). Returns the truth, the
    posterior after each push and the failure."""
    obs, info = env.reset(seed=seed)
    d = env.physics.obs_dim
    result = {"truth": info["mass_distribution"], "posteriors": [], "actions": [],
              "failure": info["failure"]}  # fmt: skip
    if info["failure"] is not None:
        return result
    filt.reset(obs[d:], episode=seed)
    if hasattr(policy, "reset"):  # a policy with randomness restarts it from the episode's
        policy.reset(seed)
    rng = np.random.default_rng([seed, 1])  # the paper's random policy's stream
    start = obs[:d].astype(float)
    for _ in range(pushes):
        if policy is None:
            # Random pushes over the same range as the information-seeking candidates, so
            # the two differ only in how a push is chosen.
            action = rng.uniform(-1, 1, 2) * (filt.config.max_push, 1.0)
            if governor is not None:
                action = governor(action, start, obs[d:])
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
        density: PushLikelihood | None = None,
    ):  # fmt: skip
        if model not in BAYES_MODELS:
            raise ValueError(f"unknown Bayesian model {model!r}; known: {list(BAYES_MODELS)}")
        self.setting, self.name, self.progress = setting, model, progress
        self.pusher = pusher or setting.pusher
        overrides = overrides or {}
        likelihood = overrides.get("likelihood", "simulator")
        base = config or default_config(setting, self.pusher, likelihood)
        self.config = replace(base, **overrides)
        self.density = density
        if self.config.likelihood == "learned" and density is None:
            raise ValueError("likelihood=learned needs the push density (`density`)")
        self.seeking = BAYES_MODELS[model]
        self.policy = "information-seeking" if self.seeking else "random"
        self.model_file = None

    @property
    def label(self) -> str:
        """What its progress bars say."""
        return f"{self.name} on {self.setting.name}"

    def run(
        self, env_config: EnvConfig, indices: np.ndarray, seed: int, workers: Workers
    ) -> EstimatorRun:
        """The episodes here, one after the other; or, with a `TaskPool` as `workers` (a Ray
        cluster), in chunks on its workers: each episode's estimate depends only on its
        seed, so the result is the same."""
        indices = np.asarray(indices)
        start = time.perf_counter()
        if is_pool(workers):
            chunks = split(indices, workers)
            shared = (self, env_config, seed)
            parts = gather(workers.imap(_chunk_task, chunks, shared, self.label), len(chunks))
        else:
            parts = [self.run_chunk(env_config, indices, seed, self.progress)]
        seconds = (time.perf_counter() - start) / max(len(indices), 1)
        return self._finish(parts, env_config, seconds)

    def run_chunk(
        self, env_config: EnvConfig, indices: np.ndarray, seed: int, progress: bool = False
    ) -> dict:
        """The raw results of episodes `indices` (what `_finish` turns into a run)."""
        env = ChainEnv.from_config(env_config)
        filt = filter_for(self.setting, self.pusher, self.config, seed, self.density)
        governor = reach_governor(env_config.pusher, env_config.physics)
        policy = InfoSeekingPolicy(filt, seed, governor) if self.seeking else None
        k = env_config.pushes
        out: dict = {"index": [], "estimates": [], "means": [], "truths": [], "inside": [],
                     "failures": 0, "unexplained": 0}  # fmt: skip
        for i in tqdm(indices, desc=self.label, disable=not progress):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UnexplainedObservationWarning)
                result = run_bayes_episode(
                    env, filt, policy, episode_seed(EVAL, seed, int(i)), k, governor
                )
            out["unexplained"] += filt.warnings
            if result["failure"] is not None or len(result["posteriors"]) < k:
                out["failures"] += 1  # left out of the metric, as the learned models' are
                continue
            last = result["posteriors"][-1]
            out["index"].append(int(i))
            out["truths"].append(result["truth"])
            out["estimates"].append(np.array([p.estimate for p in result["posteriors"]]))
            out["means"].append(last.mean)
            out["inside"].append((last.low <= result["truth"]) & (result["truth"] <= last.high))
        out["filter"] = filt.settings()
        filt.close()
        return out

    def _finish(self, parts: list[dict], env_config: EnvConfig, seconds: float) -> EstimatorRun:
        k = env_config.pushes
        failures = sum(p["failures"] for p in parts)
        estimates = [e for p in parts for e in p["estimates"]]
        if not estimates:
            return EstimatorRun(np.empty(0, int), np.empty((0, k, 0)), np.empty((0, 0)), failures)
        truth = np.array([t for p in parts for t in p["truths"]])
        means = np.array([m for p in parts for m in p["means"]])
        inside = [v for p in parts for v in p["inside"]]
        return EstimatorRun(
            index=np.array([i for p in parts for i in p["index"]]),
            estimates=np.array(estimates),
            truth=truth,
            failures=failures,
            extra={
                # The other point estimate's error, for the record (BayesConfig.point).
                "percentage_error_of_posterior_mean": percentage_error(means, truth),
                "coverage": float(np.mean(inside)),
                "credible": self.config.credible,
                # As configured here (a worker's own thread count is not the run's).
                "filter": {**parts[0]["filter"], "nthread": self.config.nthread},
                "seconds_per_episode": seconds,
                "unexplained_observations": sum(p["unexplained"] for p in parts),
            },
        )


def _chunk_task(shared: tuple, indices: np.ndarray) -> dict:
    """One chunk of episodes on a pool's worker, the filter on the worker's one thread."""
    estimator, env_config, seed = shared
    one_thread = copy.copy(estimator)
    one_thread.config = replace(estimator.config, nthread=1)
    return one_thread.run_chunk(env_config, indices, seed)
