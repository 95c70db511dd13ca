"""Many pushing episodes in lockstep on MuJoCo's multi-threaded batch (the stiff pusher, arms).

A stable-baselines3 `VecEnv` with the same observations and rewards as
`masspush.learn.policy.PushPolicyEnv`, but all environments' chains live in one `ChainBatch`,
and the frozen predictor scores all of them in one call. Every episode has exactly K
pushes and all environments start and end their episodes together. A push that fails
freezes that chain for the rest of the episode: reward 0 at the failure and after it
(the one-environment version ends the episode at once; both pay nothing for it).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvStepReturn

from masspush.config import EnvConfig
from masspush.data.rollout import Episodes
from masspush.learn.features import history_dim, history_features, paper_reward
from masspush.sim.pushers import on_batch_path


class BatchPushVecEnv(VecEnv):
    """`n_envs` pushing episodes on the batch path, rewarded by a frozen predictor."""

    def __init__(self, env_config: EnvConfig, predictor_path: str, n_envs: int, seed: int = 0):
        from masspush.learn.predictor import load_model

        if not on_batch_path(env_config.pusher):
            raise ValueError(f"{env_config.pusher!r} pushes do not run on the batch path here")
        self.env_config = env_config
        physics = env_config.physics
        self.k, self.n, self.d = env_config.pushes, physics.n_links, physics.obs_dim
        self.predictor, _ = load_model(predictor_path)
        dim = history_dim(self.n, self.k)
        super().__init__(
            n_envs,
            gym.spaces.Box(-np.inf, np.inf, (dim,), np.float32),
            gym.spaces.Box(-1.0, 1.0, (2,), np.float32),
        )
        self._seed_sequence = np.random.SeedSequence(seed)
        self._actions: np.ndarray | None = None

    # --- VecEnv -----------------------------------------------------------------------
    def reset(self) -> np.ndarray:
        from masspush.env import noisy_observation
        from masspush.sim.batch import ChainBatch
        from masspush.sim.chain import sample_chain

        if self._seeds and self._seeds[0] is not None:  # VecEnv.seed() was called
            self._seed_sequence = np.random.SeedSequence(self._seeds[0])
        self._reset_seeds()
        physics = self.env_config.physics
        self._rngs = [np.random.default_rng(s) for s in self._seed_sequence.spawn(self.num_envs)]
        chains = [sample_chain(physics, rng) for rng in self._rngs]
        batch = ChainBatch(chains, physics, pusher=self.env_config.pusher)
        # A chain that is already unstable before any push is redrawn (rare).
        for _ in range(10):
            bad = np.flatnonzero(batch.initial_failures_mask())
            if bad.size == 0:
                break
            for e in bad:
                chains[e] = sample_chain(physics, self._rngs[e])
            batch = ChainBatch(chains, physics, pusher=self.env_config.pusher)
        self.batch = batch
        self.alive = ~batch.initial_failures_mask()
        self.obs = np.full((self.num_envs, self.k + 1, self.d), np.nan, np.float32)
        self.acts = np.full((self.num_envs, self.k, 2), np.nan, np.float32)
        self.lengths = np.array([c.lengths for c in chains], np.float32)
        self.truth = np.array([c.mass_distribution for c in chains])
        configs = batch.configs()
        for e in range(self.num_envs):
            self.obs[e, 0] = noisy_observation(configs[e], self._rngs[e], self.env_config.obs_noise)
        self.t = 0
        return self._features()

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.clip(np.asarray(actions, np.float32), -1.0, 1.0)

    def step_wait(self) -> VecEnvStepReturn:
        from masspush.env import executed_action, noisy_observation

        assert self._actions is not None, "step_async first"
        actions, t = self._actions, self.t
        executed = np.zeros((self.num_envs, 2))
        for e in np.flatnonzero(self.alive):
            executed[e] = executed_action(actions[e], self._rngs[e], self.env_config.action_noise)
        self.batch.failed[:] = ~self.alive
        outcomes = self.batch.push(executed)
        configs = self.batch.configs()
        self.acts[:, t] = actions
        failure = [None] * self.num_envs
        for e in np.flatnonzero(self.alive):
            failure[e] = outcomes[e].failure
            if failure[e] is not None:
                self.alive[e] = False
                continue
            self.obs[e, t + 1] = noisy_observation(
                configs[e], self._rngs[e], self.env_config.obs_noise
            )
        self.t += 1
        history = Episodes.history(self.obs, np.nan_to_num(self.acts), self.lengths)
        estimates = self.predictor.predict(history)[:, t]
        rewards = np.where(self.alive, paper_reward(estimates, self.truth), 0.0)
        done = self.t >= self.k
        infos: list[dict[str, Any]] = [{"failure": f} for f in failure]
        for e in np.flatnonzero(self.alive):
            infos[e].update(estimate=estimates[e], mass_distribution=self.truth[e])
        features = self._features()
        if done:
            for e in range(self.num_envs):
                infos[e]["terminal_observation"] = features[e]
            features = self.reset()
        dones = np.full(self.num_envs, done)
        return features, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        pass

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [getattr(self, attr_name)] * len(self._get_indices(indices))

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        setattr(self, attr_name, value)

    def env_method(
        self, method_name: str, *args: Any, indices: VecEnvIndices = None, **kwargs: Any
    ) -> list[Any]:
        raise NotImplementedError("BatchPushVecEnv has no per-environment methods")

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        return [False] * len(self._get_indices(indices))

    # --- helpers ----------------------------------------------------------------------
    def _features(self) -> np.ndarray:

        return history_features(self.obs, np.nan_to_num(self.acts), self.lengths, self.t)
