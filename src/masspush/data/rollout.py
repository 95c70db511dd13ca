"""Episodes in bulk: a policy pushes many chains, and every step is recorded.

Two engines give the same episodes for the same seeds:
- the batch engine (stiff pusher): one `ChainBatch` on all threads;
- the environment engine (any pusher, arms included): `ChainEnv` episodes, spread over
  worker processes, one per core.
The batch engine draws its random numbers exactly as `ChainEnv` does (one generator per
episode, seeded like `env.reset(seed=...)`), so both engines give bit-identical episodes
(`tests/test_rollout.py`).

Seeds: episode i of a run with base seed b and purpose p (TRAIN or EVAL) is seeded from
SeedSequence([p, b, i]); training and evaluation episodes therefore never share a seed.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from typing import Protocol

import numpy as np

from masspush.cluster.pool import Workers, gather, is_pool, local_processes, split
from masspush.config import EnvConfig
from masspush.sim.chain import ChainParams, sample_chain
from masspush.sim.pushers import on_batch_path, reach_governor
from masspush.sim.simulate import FAILURES

TRAIN, EVAL = 0, 1
"""Seed purposes: episodes for training data and for evaluation come from disjoint streams."""
NOT_RUN = -1
"""Failure code of a push that was never made (the episode ended earlier)."""


def episode_seed(purpose: int, base_seed: int, index: int) -> int:
    """The integer seed of one episode (what `env.reset(seed=...)` receives)."""
    ss = np.random.SeedSequence([purpose, base_seed, index])
    return int(ss.generate_state(2, dtype=np.uint64)[0] >> np.uint64(1))


class Policy(Protocol):
    """Chooses pushes for a batch of episodes from what has been observed so far."""

    name: str

    def reset(self, seeds: np.ndarray) -> None:
        """Start len(seeds) episodes; `seeds` are the episodes' seeds (for any randomness)."""

    def act(
        self, observations: np.ndarray, actions: np.ndarray, step: int, lengths: np.ndarray
    ) -> np.ndarray:
        """(E, 2) actions in [-1, 1] for step `step`, given the observations q_0..q_step
        (E, K + 1, D), the actions a_0..a_{step-1} (E, K, 2) so far and the link lengths
        (E, n)."""

    # Optional: `in_worker()`, called once in each worker process before the policy acts
    # there (`run_episodes` with several workers).


class RandomPolicy:
    """Uniform random pushes, independent of what is observed (the paper's RP policy)."""

    name = "random"

    def reset(self, seeds: np.ndarray) -> None:
        self._rngs = [np.random.default_rng([int(s), 1]) for s in seeds]

    def act(
        self, observations: np.ndarray, actions: np.ndarray, step: int, lengths: np.ndarray
    ) -> np.ndarray:
        return np.array([rng.uniform(-1.0, 1.0, size=2) for rng in self._rngs], dtype=np.float32)


POLICIES: dict[str, Callable[[], Policy]] = {"random": RandomPolicy}


@dataclass
class Episodes:
    """A batch of recorded episodes (E episodes of up to K pushes, n links, D = 3 + n - 1)."""

    index: np.ndarray
    """(E,) int64: the episodes' indices in their run (their seeds follow from it)."""
    seed: np.ndarray
    """(E,) uint64: the seed each episode's environment was reset with."""
    observations: np.ndarray
    """(E, K + 1, D) float32: the noisy rest configurations q_0..q_K the robot saw."""
    configs: np.ndarray
    """(E, K + 1, D) float32: the true rest configurations."""
    actions: np.ndarray
    """(E, K, 2) float32: the policy's actions."""
    executed: np.ndarray
    """(E, K, 2) float32: the actions executed (with action noise, clipped)."""
    failure: np.ndarray
    """(E, K) int8: 0 for a good push, 1 + FAILURES.index(reason) for a failed one,
    NOT_RUN for pushes never made. Steps after a failure hold NaN observations."""
    masses: np.ndarray
    """(E, n) float32: link masses, kg."""
    friction: np.ndarray
    """(E,) float32: table friction coefficient."""
    lengths: np.ndarray
    """(E, n) float32: link lengths, m (observed exactly)."""

    @property
    def mass_distribution(self) -> np.ndarray:
        return self.masses / self.masses.sum(axis=1, keepdims=True)

    @property
    def ok(self) -> np.ndarray:
        """(E,) bool: episodes in which every push succeeded."""
        return (self.failure == 0).all(axis=1)

    @property
    def seen(self) -> np.ndarray:
        """(E, K) bool: pushes after which a rest pose was observed."""
        return ~np.isnan(self.observations[:, 1:, 0])

    def last_seen(self) -> np.ndarray:
        """(E,) index of each episode's last push with a rest pose after it; a ValueError
        if an episode has none."""
        seen = self.seen
        if not seen.any(axis=1).all():
            raise ValueError("every episode needs at least one push with a rest pose after it")
        return seen.shape[1] - 1 - np.argmax(seen[:, ::-1], axis=1)

    def __len__(self) -> int:
        return len(self.index)

    @staticmethod
    def history(observations: np.ndarray, actions: np.ndarray, lengths: np.ndarray) -> Episodes:
        """Episodes holding only what the robot knows (for predicting mid-episode): the
        other fields are zero."""
        e, k = actions.shape[:2]
        out = empty_episodes(e, k, lengths.shape[1])
        out.observations, out.actions, out.lengths = observations, actions, lengths
        return out

    def chain(self, e: int, masses: Sequence[float] | None = None) -> ChainParams:
        """Episode `e`'s chain at its true start pose (with other `masses` if given): to
        push it again outside the episode."""
        return ChainParams.at_pose(
            self.masses[e] if masses is None else masses, self.friction[e], self.lengths[e],
            self.configs[e, 0],
        )  # fmt: skip

    def select(self, mask: np.ndarray) -> Episodes:
        return Episodes(**{f.name: getattr(self, f.name)[mask] for f in fields(self)})

    @staticmethod
    def concatenate(parts: Sequence[Episodes]) -> Episodes:
        return Episodes(
            **{
                f.name: np.concatenate([getattr(p, f.name) for p in parts])
                for f in fields(Episodes)
            }
        )


def failure_code(reason: str | None) -> int:
    return 0 if reason is None else 1 + FAILURES.index(reason)


def empty_episodes(e: int, k: int, n: int) -> Episodes:
    d = 3 + n - 1
    return Episodes(
        index=np.zeros(e, np.int64),
        seed=np.zeros(e, np.uint64),
        observations=np.full((e, k + 1, d), np.nan, np.float32),
        configs=np.full((e, k + 1, d), np.nan, np.float32),
        actions=np.full((e, k, 2), np.nan, np.float32),
        executed=np.full((e, k, 2), np.nan, np.float32),
        failure=np.full((e, k), NOT_RUN, np.int8),
        masses=np.zeros((e, n), np.float32),
        friction=np.zeros(e, np.float32),
        lengths=np.zeros((e, n), np.float32),
    )


def run_batch(
    env_config: EnvConfig,
    policy: Policy,
    indices: np.ndarray,
    purpose: int,
    base_seed: int,
    nthread: int = 0,
) -> Episodes:
    """Episodes on the batch path (pushers with one), drawing noise exactly as ChainEnv."""
    from masspush.env import executed_action, noisy_observation
    from masspush.sim.batch import ChainBatch

    physics = env_config.physics
    k, n = env_config.pushes, physics.n_links
    obs_sigma = env_config.obs_noise
    out = empty_episodes(len(indices), k, n)
    seeds = np.array([episode_seed(purpose, base_seed, int(i)) for i in indices], np.uint64)
    rngs = [np.random.default_rng(int(s)) for s in seeds]
    chains = [sample_chain(physics, rng) for rng in rngs]
    batch = ChainBatch(chains, physics, nthread=nthread, pusher=env_config.pusher)
    out.index[:] = indices
    out.seed[:] = seeds
    for e, chain in enumerate(chains):
        out.masses[e], out.friction[e], out.lengths[e] = chain.masses, chain.friction, chain.lengths
    alive = ~batch.initial_failures_mask()
    configs = batch.configs()
    for e in np.flatnonzero(alive):
        out.configs[e, 0] = configs[e]
        out.observations[e, 0] = noisy_observation(configs[e], rngs[e], obs_sigma)
    policy.reset(seeds)
    for t in range(k):
        actions = np.asarray(policy.act(out.observations, out.actions, t, out.lengths), np.float32)
        executed = np.zeros((len(indices), 2))
        for e in np.flatnonzero(alive):
            executed[e] = executed_action(actions[e], rngs[e], env_config.action_noise)
        batch.failed[:] = ~alive  # chains whose episode is over are not pushed
        outcomes = batch.push(executed)
        configs = batch.configs()
        for e in np.flatnonzero(alive):
            out.actions[e, t], out.executed[e, t] = actions[e], executed[e]
            out.failure[e, t] = failure_code(outcomes[e].failure)
            if outcomes[e].failure is not None:
                alive[e] = False
                continue
            out.configs[e, t + 1] = configs[e]
            out.observations[e, t + 1] = noisy_observation(
                configs[e], rngs[e], env_config.obs_noise
            )
    return out


def run_env(
    env_config: EnvConfig, policy: Policy, indices: np.ndarray, purpose: int, base_seed: int
) -> Episodes:
    """Episodes through ChainEnv, one after the other (any pusher)."""
    from masspush.env import ChainEnv

    physics = env_config.physics
    k, n = env_config.pushes, physics.n_links
    env = ChainEnv.from_config(env_config)
    governor = reach_governor(env_config.pusher, physics)
    out = empty_episodes(len(indices), k, n)
    d = physics.obs_dim
    for e, i in enumerate(indices):
        seed = episode_seed(purpose, base_seed, int(i))
        obs, info = env.reset(seed=seed)
        out.index[e], out.seed[e] = i, seed
        out.masses[e], out.friction[e], out.lengths[e] = (
            info["masses"],
            info["friction"],
            info["lengths"],
        )
        if info["failure"] is not None:
            continue
        out.observations[e, 0], out.configs[e, 0] = obs[:d], info["config"]
        policy.reset(np.array([seed], np.uint64))
        for t in range(k):
            # The policy sees this episode's history so far (views: filled in as we go).
            action = policy.act(
                out.observations[e : e + 1], out.actions[e : e + 1], t, out.lengths[e : e + 1]
            )[0]
            if governor is not None:  # a stationary robot's pushes, as it makes them
                action = governor(action, out.observations[e, t], out.lengths[e])
            obs, _, terminated, _, info = env.step(np.asarray(action, np.float32))
            out.actions[e, t], out.executed[e, t] = action, info["push"]["action"]
            out.failure[e, t] = failure_code(info["failure"])
            if info["failure"] is not None:
                break
            out.observations[e, t + 1], out.configs[e, t + 1] = obs[:d], info["config"]
            if terminated:
                break
    return out


def _enter_worker(policy: Policy) -> None:
    # A policy that computes (a learned one) keeps to one thread in a worker: one worker per
    # core already, and its own threads would oversubscribe the cores.
    in_worker = getattr(policy, "in_worker", None)
    if in_worker is not None:
        in_worker()


def _run_env_job(args: tuple) -> Episodes:
    _enter_worker(args[1])
    return run_env(*args)


def run_chunk(shared: tuple, indices: np.ndarray) -> Episodes:
    """One task of a `TaskPool`: the episodes `indices` on one thread, as `run_episodes`
    would run them (`shared`: env_config, policy, purpose, base_seed)."""
    env_config, policy, purpose, base_seed = shared
    _enter_worker(policy)
    return run_episodes(env_config, policy, indices, purpose, base_seed, workers=1, threads=1)


def run_episodes(
    env_config: EnvConfig,
    policy: Policy,
    indices: np.ndarray,
    purpose: int,
    base_seed: int,
    workers: Workers = None,
    threads: int = 0,
    desc: str | None = None,
) -> Episodes:
    """Episodes with every core: the batch engine for a pusher that has one (on `threads`
    threads, 0: all), else processes (`workers`, one per core by default); or, with a
    `TaskPool` as `workers` (a Ray cluster), in chunks on its workers (a bar named `desc`
    over them). The episodes are the same whichever runs them."""
    indices = np.asarray(indices, np.int64)
    if is_pool(workers):
        chunks = split(indices, workers)
        shared = (env_config, policy, purpose, base_seed)
        return Episodes.concatenate(
            gather(workers.imap(run_chunk, chunks, shared, desc), len(chunks))
        )
    if on_batch_path(env_config.pusher):
        return run_batch(env_config, policy, indices, purpose, base_seed, threads)
    workers = workers or os.cpu_count() or 1
    if workers == 1 or len(indices) < 2:
        return run_env(env_config, policy, indices, purpose, base_seed)
    parts = np.array_split(indices, workers)
    jobs = [(env_config, policy, p, purpose, base_seed) for p in parts if len(p)]
    with local_processes(len(jobs)) as pool:
        return Episodes.concatenate(list(pool.map(_run_env_job, jobs)))
