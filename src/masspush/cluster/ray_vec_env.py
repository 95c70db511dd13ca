"""A stable-baselines3 `VecEnv` whose environments live in Ray actors.

Environment i is built by `env_fns[i]`, seeded, stepped and reset exactly as
`SubprocVecEnv`'s worker does it (same auto-reset, same `terminal_observation` and
`TimeLimit.truncated` entries), so for a fixed seed the transitions are those of the local
vectorised environment; only where the environments run differs. The environments are
spread over `groups` actors (one CPU each) that step theirs one after the other: an actor
per environment would hold a CPU per environment, and more environments than CPUs (16 on
a 2-core machine, say) would then wait for CPUs that never come free.

An actor lost mid-rollout is not restarted: its environments' episodes cannot be continued
elsewhere. PPO then stops with an error, and the same command resumes from its last
checkpoint (`masspush.learn.policy.train_policy`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
)


class _EnvGroup:
    """Some environments of the VecEnv, in one actor (`SubprocVecEnv`'s worker, batched)."""

    def __init__(self, env_fns: Sequence[Callable[[], gym.Env]]):
        from stable_baselines3.common.vec_env.patch_gym import _patch_env

        self.envs = [_patch_env(fn()) for fn in env_fns]
        # As SubprocVecEnv's worker: each step reports the environment's latest reset info.
        self.reset_infos: list[dict[str, Any]] = [{} for _ in self.envs]

    def spaces(self) -> tuple[gym.Space, gym.Space]:
        return self.envs[0].observation_space, self.envs[0].action_space

    def step(self, actions: np.ndarray) -> list[tuple]:
        out = []
        for j, (env, action) in enumerate(zip(self.envs, actions, strict=True)):
            observation, reward, terminated, truncated, info = env.step(action)
            done = terminated or truncated
            info["TimeLimit.truncated"] = truncated and not terminated
            if done:
                info["terminal_observation"] = observation
                observation, self.reset_infos[j] = env.reset()
            out.append((observation, reward, done, info, self.reset_infos[j]))
        return out

    def reset(self, seeds: list, options: list) -> list[tuple]:
        out = []
        for j, (env, seed, option) in enumerate(zip(self.envs, seeds, options, strict=True)):
            observation, self.reset_infos[j] = env.reset(
                seed=seed, **({"options": option} if option else {})
            )
            out.append((observation, self.reset_infos[j]))
        return out

    def call(self, local: list[int], what: str, *args: Any) -> list[Any]:
        from stable_baselines3.common.env_util import is_wrapped

        envs = [self.envs[j] for j in local]
        if what == "get_attr":
            return [env.get_wrapper_attr(args[0]) for env in envs]
        if what == "set_attr":
            for env in envs:
                setattr(env, args[0], args[1])
            return [None] * len(envs)
        if what == "env_method":
            name, a, kw = args
            return [env.get_wrapper_attr(name)(*a, **kw) for env in envs]
        if what == "is_wrapped":
            return [is_wrapped(env, args[0]) for env in envs]
        if what == "render":
            return [env.render() for env in envs]
        raise NotImplementedError(what)

    def close(self) -> None:
        for env in self.envs:
            env.close()


class RayVecEnv(VecEnv):
    """`len(env_fns)` environments in `groups` Ray actors of one CPU each."""

    def __init__(self, env_fns: list[Callable[[], gym.Env]], groups: int = 1):
        import ray

        n = len(env_fns)
        groups = max(1, min(groups, n))
        self._slices = [range(g * n // groups, (g + 1) * n // groups) for g in range(groups)]
        actor = ray.remote(num_cpus=1, max_restarts=0)(_EnvGroup)
        self._actors = [actor.remote([env_fns[i] for i in s]) for s in self._slices]
        observation_space, action_space = self._get(self._actors[0].spaces.remote())
        super().__init__(n, observation_space, action_space)
        self._pending: list[Any] | None = None

    @staticmethod
    def _get(refs: Any) -> Any:
        import ray
        from ray.exceptions import RayActorError, RayTaskError

        try:
            return ray.get(refs)
        except RayTaskError as err:
            raise err.cause from None
        except RayActorError as err:
            from masspush.cluster.errors import ClusterError

            raise ClusterError(
                "an environment actor was lost on the Ray cluster; rerun the same command "
                f"to resume from the last checkpoint ({' '.join(str(err).split())[:120]})"
            ) from None

    def step_async(self, actions: np.ndarray) -> None:
        self._pending = [
            a.step.remote(actions[s.start : s.stop])
            for a, s in zip(self._actors, self._slices, strict=True)
        ]

    def step_wait(self) -> VecEnvStepReturn:
        assert self._pending is not None, "step_async first"
        results = [r for part in self._get(self._pending) for r in part]
        self._pending = None
        obs, rewards, dones, infos, self.reset_infos = zip(*results, strict=True)
        return np.stack(obs), np.stack(rewards), np.stack(dones), infos

    def reset(self) -> VecEnvObs:
        refs = [
            a.reset.remote([self._seeds[i] for i in s], [self._options[i] for i in s])
            for a, s in zip(self._actors, self._slices, strict=True)
        ]
        results = [r for part in self._get(refs) for r in part]
        obs, self.reset_infos = zip(*results, strict=True)
        self._reset_seeds()
        self._reset_options()
        return np.stack(obs)

    def close(self) -> None:
        import ray

        if self._actors:
            if self._pending is not None:
                self._get(self._pending)
            self._get([a.close.remote() for a in self._actors])
            for a in self._actors:
                ray.kill(a)
            self._actors = []

    def _call(self, indices: VecEnvIndices, what: str, *args: Any) -> list[Any]:
        wanted = self._get_indices(indices)
        refs, order = [], []
        for a, s in zip(self._actors, self._slices, strict=True):
            local = [i - s.start for i in wanted if i in s]
            if local:
                refs.append(a.call.remote(local, what, *args))
                order += [s.start + j for j in local]
        values = dict(zip(order, [v for part in self._get(refs) for v in part], strict=True))
        return [values[i] for i in wanted]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return self._call(indices, "get_attr", attr_name)

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        self._call(indices, "set_attr", attr_name, value)

    def env_method(
        self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs
    ) -> list[Any]:
        return self._call(indices, "env_method", method_name, method_args, method_kwargs)

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        return self._call(indices, "is_wrapped", wrapper_class)

    def get_images(self) -> Sequence[np.ndarray | None]:
        return self._call(None, "render")
