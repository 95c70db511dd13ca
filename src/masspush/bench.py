"""Simulation throughput: the environment path, the batch path, and the raw-stepping ceiling."""

from __future__ import annotations

import os
import time
from collections import Counter
from dataclasses import asdict, dataclass, replace

import numpy as np
from tqdm import tqdm

from masspush.batch import ChainBatch
from masspush.chain import sample_chain
from masspush.config import PhysicsConfig
from masspush.env import ChainEnv


@dataclass(frozen=True)
class SimBenchmark:
    """Pushes per second through each path, and the ceiling they are measured against."""

    n_links: int
    mass_range: tuple[float, float]
    threads: int
    env_pushes_per_s: float
    """One environment, one core, noise on, through `ChainEnv.step`."""
    batch_pushes_per_s: float
    """`ChainBatch` on all threads, model compilation included."""
    batch_pushes_per_s_stepping: float
    """`ChainBatch` on all threads, pushes only (chains already built)."""
    steps_per_push: float
    """Mean physics steps per push (push + settling) in the batch run."""
    ceiling_steps_per_s: float
    """Raw mj_step throughput on all threads, on post-push states (no Python per step)."""
    ceiling_pushes_per_s: float
    """ceiling_steps_per_s / steps_per_push."""
    batch_fraction_of_ceiling: float
    failure_rate: float
    """Share of batch pushes that failed (nan / unstable / timeout)."""
    failures: dict[str, int]
    """Failed batch pushes by reason."""
    pushes: int
    """Pushes in the batch run."""

    def table(self) -> str:
        rows = [
            ("setting", f"{self.n_links} links, masses {list(self.mass_range)} kg"),
            ("threads", f"{self.threads}"),
            ("environment path (1 core)", f"{self.env_pushes_per_s:8.1f} pushes/s"),
            ("batch path, with model building", f"{self.batch_pushes_per_s:8.1f} pushes/s"),
            ("batch path, pushes only", f"{self.batch_pushes_per_s_stepping:8.1f} pushes/s"),
            ("steps per push (mean)", f"{self.steps_per_push:8.1f}"),
            ("ceiling: raw mj_step, all threads", f"{self.ceiling_steps_per_s:8.0f} steps/s"),
            ("ceiling in pushes", f"{self.ceiling_pushes_per_s:8.1f} pushes/s"),
            ("batch (pushes only) / ceiling", f"{self.batch_fraction_of_ceiling:8.2f}"),
            ("batch pushes", f"{self.pushes:8d}"),
            ("failed pushes", f"{100 * self.failure_rate:8.2f} %  {self.failures}"),
        ]
        width = max(len(k) for k, _ in rows)
        return "\n".join(f"{k:<{width}}  {v}" for k, v in rows)

    def as_dict(self) -> dict:
        return asdict(self)


def bench_sim(
    n_links: int = 2,
    mass_range: tuple[float, float] = (0.1, 1.0),
    env_pushes: int = 200,
    batch_chains: int = 512,
    pushes_per_chain: int | None = None,
    threads: int | None = None,
    seed: int = 0,
    progress: bool = True,
) -> SimBenchmark:
    """Measure pushes per second through the environment and the batch path."""
    threads = threads or os.cpu_count() or 1
    physics = replace(PhysicsConfig(), n_links=n_links, mass_range=mass_range)
    k = pushes_per_chain or n_links
    rng = np.random.default_rng(seed)

    env = ChainEnv(n_links=n_links, mass_range=mass_range)
    env.reset(seed=seed)
    done, t0 = 0, time.perf_counter()
    for _ in tqdm(range(env_pushes), desc="environment path", disable=not progress):
        _, _, terminated, _, _ = env.step(env.action_space.sample())
        done += 1
        if terminated:
            env.reset()
    env_rate = done / (time.perf_counter() - t0)

    chains = [sample_chain(physics, rng) for _ in range(batch_chains)]
    actions = rng.uniform(-1, 1, size=(k, batch_chains, 2))
    t0 = time.perf_counter()
    batch = ChainBatch(chains, physics, nthread=threads)
    t_built = time.perf_counter()
    steps, pushes, failures = 0, 0, Counter()
    for a in tqdm(actions, desc="batch path", disable=not progress):
        for outcome in batch.push(a):
            if outcome is not None:
                steps += outcome.steps
                pushes += 1
                if outcome.failure is not None:
                    failures[outcome.failure] += 1
    t_end = time.perf_counter()
    steps_per_push = steps / max(pushes, 1)

    ceiling = _raw_step_rate(chains, physics, threads, actions)
    batch_rate_stepping = pushes / (t_end - t_built)
    ceiling_pushes = ceiling / steps_per_push
    return SimBenchmark(
        n_links=n_links,
        mass_range=tuple(mass_range),
        threads=threads,
        env_pushes_per_s=env_rate,
        batch_pushes_per_s=pushes / (t_end - t0),
        batch_pushes_per_s_stepping=batch_rate_stepping,
        steps_per_push=steps_per_push,
        ceiling_steps_per_s=ceiling,
        ceiling_pushes_per_s=ceiling_pushes,
        batch_fraction_of_ceiling=batch_rate_stepping / ceiling_pushes,
        failure_rate=sum(failures.values()) / max(pushes, 1),
        failures=dict(failures),
        pushes=pushes,
    )


def _raw_step_rate(chains, physics: PhysicsConfig, threads: int, actions: np.ndarray) -> float:
    """Raw mj_step throughput on all threads, on the states the batch run's pushes create.

    Each round, the same chains get the same pushes; right after contact every chain is
    stepped 200 steps in one C call (timed: no Python, no rest checks, no idle threads),
    then rewound and let settle untimed, ready for the next round.
    """
    batch = ChainBatch(chains, physics, nthread=threads)
    n_steps, stepped, elapsed = 200, 0, 0.0
    for a in actions:
        ids, _, controls = batch.prepare_push(a)
        batch.deliver(ids, controls)
        after_push = batch.batch.state[ids].copy()
        t0 = time.perf_counter()
        batch.batch.step(ids, nstep=n_steps)
        elapsed += time.perf_counter() - t0
        stepped += n_steps * ids.size
        batch.batch.state[ids] = after_push
        failures, _ = batch.settle(ids)
        batch.failed[ids] = [failures[i] is not None for i in ids]
    return stepped / elapsed
