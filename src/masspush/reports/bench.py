"""Simulation throughput: the environment path, the batch path, and the raw-stepping ceiling."""

from __future__ import annotations

import os
import time
from collections import Counter
from dataclasses import asdict, dataclass, replace
from typing import ClassVar

import numpy as np
from tqdm import tqdm

from masspush.config import MAX_LINKS, PhysicsConfig, check_int
from masspush.env import ChainEnv
from masspush.sim.batch import ChainBatch
from masspush.sim.chain import ChainParams, sample_chain
from masspush.sim.pushers import IDEAL_PUSHER, pusher_field, pusher_kind


@dataclass(frozen=True)
class SimBench:
    """`masspush bench sim`: pushes per second through the environment and the batch path."""

    links: int = 2
    """Links of the benchmark's chains."""
    mass_range: tuple[float, float] = (0.1, 1.0)
    """Each link's mass range, kg."""
    env_pushes: int = 200
    """Pushes through the environment (one core)."""
    chains: int = 512
    """Chains in the batch run."""
    pushes_per_chain: int | None = None
    """Pushes each batch chain gets (default: one per link)."""
    threads: int | None = None
    """Threads of the batch path (default: every core)."""
    seed: int = 0
    """Random seed of the chains and pushes."""

    def __post_init__(self) -> None:
        check_int("links", self.links, 2)
        for name in ("env_pushes", "chains"):
            check_int(name, getattr(self, name))
        check_int("pushes_per_chain", self.pushes_per_chain, optional=True)
        check_int("threads", self.threads, optional=True)
        check_int("seed", self.seed, 0)
        PhysicsConfig(n_links=self.links, mass_range=self.mass_range)  # validates the range


@dataclass(frozen=True)
class PushersBench:
    """`masspush bench pushers`: each pusher's speed, failures and what x10 masses change."""

    links: int = 2
    """Links of the benchmark's chains."""
    pushes: int = 60
    """Pushes through the environment per pusher."""
    pairs: int = 40
    """(chain, push) pairs compared with all masses x10."""
    pushers: tuple[str, ...] = ("stiff", "kuka", "ur10")
    """The pushers to measure."""
    seed: int = 0
    """Random seed of the chains and pushes."""

    def __post_init__(self) -> None:
        check_int("links", self.links, 2)
        check_int("pushes", self.pushes)
        check_int("pairs", self.pairs)
        check_int("seed", self.seed, 0)
        for name in self.pushers:
            pusher_kind(name)


@dataclass(frozen=True)
class DataBench:
    """`masspush bench data`: episodes collected per second with every core."""

    setting: str = "2link-0.1-1"
    """Named setting of the episodes."""
    pusher: str = pusher_field("kuka")
    """The pusher that pushes them."""
    episodes: int = 1000
    """Episodes to collect."""
    workers: int | None = None
    """Processes for an arm (default: one per core)."""

    def __post_init__(self) -> None:
        pusher_kind(self.pusher)
        check_int("episodes", self.episodes)
        check_int("workers", self.workers, optional=True)


@dataclass(frozen=True)
class ArmBench:
    """`masspush bench arm`: an arm's pushes per second on every core against the stiff
    pusher's batch path, measured in the same run, and the compiled law against the
    Python reference."""

    links: int = 2
    """Links of the chains (masses in [0.1, 1] kg, the KUKA settings')."""
    arm: str = pusher_field("kuka", arms_only=True)
    """The arm."""
    episodes: int = 200
    """Episodes of random pushes for each pusher."""
    workers: int | None = None
    """Threads of the batch path (default: one per core), for the arm in lockstep as for the
    stiff pusher; processes for an arm without its compiled law."""
    check_pushes: int = 20
    """Pushes simulated with both laws for `identical`."""
    seed: int = 0
    """Seed of the chains and pushes."""

    GOALS: ClassVar[dict[int, float]] = {2: 0.6, 3: 0.8}
    """The ratios issue 27 asks for: arm / stiff throughput."""

    def __post_init__(self) -> None:
        check_int("links", self.links, 2)
        if self.links > MAX_LINKS:
            raise ValueError(f"links must be at most {MAX_LINKS}, got {self.links}")
        if not pusher_kind(self.arm).arm:
            raise ValueError(f"arm must be an arm pusher, not {self.arm!r}")
        check_int("episodes", self.episodes)
        check_int("workers", self.workers, optional=True)
        check_int("check_pushes", self.check_pushes)
        check_int("seed", self.seed, 0)


def bench_arm(config: ArmBench = ArmBench()) -> dict:
    """The arm's and the stiff pusher's throughput (pushes/s) on every core, their ratio,
    steps per push, and whether the compiled law gives the reference's rest poses."""
    from masspush.config import EnvConfig
    from masspush.data.rollout import NOT_RUN, TRAIN, RandomPolicy, run_episodes
    from masspush.sim.pushers import compiled, make_pusher, on_batch_path
    from masspush.sim.simulate import ChainSim

    physics = PhysicsConfig(n_links=config.links, mass_range=(0.1, 1.0))
    workers = config.workers or os.cpu_count() or 1
    rate = {}
    for name in (config.arm, IDEAL_PUSHER):
        env_config = EnvConfig(physics=physics, pusher=name)
        start = time.perf_counter()
        run = run_episodes(env_config, RandomPolicy(), np.arange(config.episodes), TRAIN,
                           config.seed, workers, threads=workers)  # fmt: skip
        rate[name] = int((run.failure != NOT_RUN).sum()) / (time.perf_counter() - start)
    # The compiled law settling alone against the reference (the Python law, the arm in
    # every step of the settling), and the steps a push takes.
    rng = np.random.default_rng(config.seed)
    arms = {True: make_pusher(config.arm), False: make_pusher(config.arm)}
    arms[False].use_compiled = False
    worst, steps = 0.0, {config.arm: [], IDEAL_PUSHER: []}
    for _ in range(config.check_pushes):
        chain, action = sample_chain(physics, rng), rng.uniform(-1, 1, 2)
        poses = []
        for use in (True, False):
            sim = ChainSim(chain, physics, arms[use], settle_alone=use)
            outcome = sim.push(action)
            poses.append(sim.config())
        worst = max(worst, float(np.abs(poses[0] - poses[1]).max()))
        steps[config.arm].append(outcome.steps)
        steps[IDEAL_PUSHER].append(ChainSim(chain, physics).push(action).steps)
    ratio = rate[config.arm] / rate[IDEAL_PUSHER]
    goal = config.GOALS.get(config.links)
    return {
        "links": config.links,
        "arm": config.arm,
        "compiled": compiled.library() is not None,
        "arm_engine": "lockstep" if on_batch_path(config.arm) else "processes",
        "workers": workers,
        "arm_pushes_per_s": rate[config.arm],
        "stiff_pushes_per_s": rate[IDEAL_PUSHER],
        "ratio": ratio,
        "goal": goal,
        "meets_goal": None if goal is None else bool(ratio >= goal),
        "arm_steps_per_push": float(np.mean(steps[config.arm])),
        "stiff_steps_per_push": float(np.mean(steps[IDEAL_PUSHER])),
        "identical": bool(worst <= 1e-9),
        "largest_difference": worst,
    }


@dataclass(frozen=True)
class TrainBench:
    """`masspush bench train`: predictor training samples per second."""

    setting: str = "2link-0.1-1"
    """Named setting of the training episodes."""
    episodes: int = 4000
    """Training episodes (collected first, on the batch path)."""
    steps: int = 2000
    """Training steps of each option."""

    def __post_init__(self) -> None:
        check_int("episodes", self.episodes, 2)
        check_int("steps", self.steps)


@dataclass(frozen=True)
class PPOBench:
    """`masspush bench ppo`: PPO training pushes per second, simulation and updates together."""

    setting: str = "2link-1-10"
    """Named setting; the policy learns against its shipped RP predictor."""
    pusher: str | None = pusher_field()
    """The pusher (default: the setting's)."""
    algos: tuple[str, ...] = ("mlp", "recurrent")
    """Learners to measure."""
    steps: int = 8192
    """PPO pushes per run."""
    envs: tuple[int, ...] = (16,)
    """Numbers of parallel environments to measure."""
    n_steps: int | None = None
    """Pushes per environment between updates (default: the paper's rollout size)."""
    lockstep_arms: bool = True
    """An arm's environments in lockstep on the batch path, as `masspush train` runs them
    (--no-lockstep-arms: a process each)."""

    def __post_init__(self) -> None:
        if self.pusher is not None:
            pusher_kind(self.pusher)
        check_int("steps", self.steps)
        for n in self.envs:
            check_int("envs", n)
        check_int("n_steps", self.n_steps, 2, optional=True)


@dataclass(frozen=True)
class MotionBench:
    """`masspush bench motion`: how far a dataset's chains moved per push."""

    data: str
    """Dataset directory (from `masspush collect`)."""
    episodes: int = 8000
    """Read the first this many episodes."""

    def __post_init__(self) -> None:
        check_int("episodes", self.episodes)


@dataclass(frozen=True)
class PhysicsBench:
    """`masspush bench physics`: rest-pose convergence in the time step, chaotic sensitivity."""

    links: int = 2
    """Links of the benchmark's chains."""
    mass_range: tuple[float, float] = (0.1, 1.0)
    """Each link's mass range, kg."""
    pushes: int = 64
    """Random single pushes."""
    seed: int = 0
    """Random seed of the chains and pushes."""

    def __post_init__(self) -> None:
        check_int("links", self.links, 2)
        check_int("pushes", self.pushes)
        check_int("seed", self.seed, 0)
        PhysicsConfig(n_links=self.links, mass_range=self.mass_range)


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


def bench_sim(config: SimBench = SimBench(), progress: bool = True) -> SimBenchmark:
    """Measure pushes per second through the environment and the batch path."""
    n_links, mass_range, env_pushes = config.links, config.mass_range, config.env_pushes
    batch_chains, pushes_per_chain = config.chains, config.pushes_per_chain
    threads, seed = config.threads, config.seed
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


def _raw_step_rate(
    chains: list[ChainParams], physics: PhysicsConfig, threads: int, actions: np.ndarray
) -> float:
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


@dataclass(frozen=True)
class PusherBenchmark:
    """One pusher: speed through the environment, failures, and what a mass scale does."""

    pusher: str
    n_links: int
    pushes: int
    pushes_per_s: float
    """Through `ChainEnv.step` (one core, noise on): push, arm control, slide to rest."""
    failures: dict[str, int]
    scale_pairs: int
    """(chain, push) pairs compared with all masses x10."""
    scale_position_median_mm: float
    scale_angle_median_rad: float
    scale_angle_p90_rad: float
    tip_speed: dict[float, float]
    """Commanded push speed -> tip speed at contact on a light chain (arms only), m/s."""


TRACKED_SPEEDS = (0.5, 1.0, 2.0, 3.0, 4.0, 5.0)


def _tip_speeds(name: str, n_links: int) -> dict[float, float]:
    """Tip speed at contact for each commanded speed, pushing a light straight chain."""
    from masspush.sim.pushers import make_pusher
    from masspush.sim.simulate import ChainSim

    if not pusher_kind(name).arm:
        return {}
    physics = replace(PhysicsConfig(), n_links=n_links)
    pins = {
        "masses": [0.1] * n_links,
        "joint_angles": [0.0] * (n_links - 1),
        "root_pose": [0.0, 0.0, 0.0],
    }
    speeds = {}
    for v in TRACKED_SPEEDS:
        chain = sample_chain(physics, np.random.default_rng(0), pins)
        sim = ChainSim(chain, physics, make_pusher(name))
        sim.push(np.array([v / physics.push_speed_max, -0.5]))
        trace = sim.pusher.trace
        speeds[v] = trace.tip_speed[trace.contact_step] if trace.contact_step is not None else 0.0
    return speeds


def bench_pushers(
    config: PushersBench = PushersBench(), progress: bool = True
) -> list[PusherBenchmark]:
    """Pushes per second and the effect of scaling every mass by 10, for each pusher."""
    from masspush.sim.pushers import make_pusher
    from masspush.sim.simulate import ChainSim

    n_links, pushes, pairs, seed = config.links, config.pushes, config.pairs, config.seed
    pushers = config.pushers
    results = []
    for name in pushers:
        env = ChainEnv(n_links=n_links, pusher=name)
        env.reset(seed=seed)
        env.action_space.seed(seed)
        failures: Counter = Counter()
        t0 = time.perf_counter()
        for _ in tqdm(range(pushes), desc=f"{name}: pushes", disable=not progress):
            _, _, terminated, _, info = env.step(env.action_space.sample())
            if info["failure"]:
                failures[info["failure"]] += 1
            if terminated:
                env.reset()
        rate = pushes / (time.perf_counter() - t0)

        physics = replace(PhysicsConfig(), n_links=n_links)
        rng = np.random.default_rng(seed)
        pusher = make_pusher(name)
        positions, angles = [], []
        for _ in tqdm(range(pairs), desc=f"{name}: x10 masses", disable=not progress):
            chain = sample_chain(physics, rng)
            action = rng.uniform(-1, 1, size=2)
            heavy = replace(chain, masses=tuple(10 * m for m in chain.masses))
            poses = []
            for c in (chain, heavy):
                sim = ChainSim(c, replace(physics, mass_range=(0.1, 10.0)), pusher)
                poses.append(None if sim.push(action).failure else sim.config())
            if poses[0] is None or poses[1] is None:
                continue
            d = poses[1] - poses[0]
            positions.append(1000 * np.linalg.norm(d[:2]))
            angles.append(np.abs((d[2:] + np.pi) % (2 * np.pi) - np.pi).max())
        results.append(
            PusherBenchmark(
                pusher=name,
                n_links=n_links,
                pushes=pushes,
                pushes_per_s=rate,
                failures=dict(failures),
                scale_pairs=len(angles),
                scale_position_median_mm=float(np.median(positions)),
                scale_angle_median_rad=float(np.median(angles)),
                scale_angle_p90_rad=float(np.percentile(angles, 90)),
                tip_speed=_tip_speeds(name, n_links),
            )
        )
    return results


def pushers_table(results: list[PusherBenchmark]) -> str:
    lines = [
        "| pusher | links | pushes/s (env, 1 core) | failed pushes | pairs | x10 masses: "
        "position median (mm) | angle median / p90 (rad) |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in results:
        failed = ", ".join(f"{k} {v}" for k, v in sorted(r.failures.items())) or "none"
        lines.append(
            f"| {r.pusher} | {r.n_links} | {r.pushes_per_s:.1f} | {failed} (of {r.pushes}) "
            f"| {r.scale_pairs} | {r.scale_position_median_mm:.1f} "
            f"| {r.scale_angle_median_rad:.3f} / {r.scale_angle_p90_rad:.3f} |"
        )
    arms = [r for r in results if r.tip_speed]
    if arms:
        header = " | ".join(f"{r.pusher} tip speed at contact (m/s)" for r in arms)
        lines += ["", f"| commanded speed (m/s) | {header} |", "|---|" + "---|" * len(arms)]
        for v in TRACKED_SPEEDS:
            cells = " | ".join(f"{r.tip_speed[v]:.2f}" for r in arms)
            lines.append(f"| {v:g} | {cells} |")
    return "\n".join(lines)


def bench_data(config: DataBench = DataBench()) -> dict:
    """Episodes per second collected with every core (the collection engine, no disk)."""
    setting, pusher, episodes, workers = (
        config.setting,
        config.pusher,
        config.episodes,
        config.workers,
    )
    from masspush.data.rollout import TRAIN, RandomPolicy, run_episodes
    from masspush.settings import get_setting

    spec = get_setting(setting)
    config = spec.env_config(pusher)
    t0 = time.perf_counter()
    run = run_episodes(config, RandomPolicy(), np.arange(episodes), TRAIN, 12345, workers)
    elapsed = time.perf_counter() - t0
    return {
        "setting": setting,
        "pusher": pusher,
        "episodes": episodes,
        "episodes_per_s": episodes / elapsed,
        "pushes_per_s": episodes * config.pushes / elapsed,
        "failed_episodes": int((~run.ok).sum()),
        "threads_or_workers": workers or os.cpu_count(),
    }


def bench_train(config: TrainBench = TrainBench()) -> list[dict]:
    """Training samples per second: the paper's SGD (batch 16) and the fast Adam (batch 256)."""
    import tempfile

    from masspush.data.rollout import TRAIN, RandomPolicy, run_batch
    from masspush.learn.predictor import FAST, TrainConfig, train_predictor
    from masspush.settings import get_setting

    setting, episodes, steps = config.setting, config.episodes, config.steps

    spec = get_setting(setting)
    data = run_batch(spec.env_config(IDEAL_PUSHER), RandomPolicy(), np.arange(episodes), TRAIN, 0)
    rows = []
    for name, config in (("paper SGD, batch 16", TrainConfig()), ("fast Adam, batch 256", FAST)):
        config = replace(config, steps=steps, eval_every=steps, checkpoint_every=steps)
        with tempfile.TemporaryDirectory() as run:
            _, summary = train_predictor(data, run, config, progress=False)
        rows.append(
            {
                "option": name,
                "steps": steps,
                "batch_size": config.batch_size,
                "samples_per_s": summary["samples_per_s"],
                "steps_per_s": summary["samples_per_s"] / config.batch_size,
            }
        )
    return rows


def bench_ppo(config: PPOBench = PPOBench()) -> list[dict]:
    """PPO training speed (pushes per second, simulation and updates together) for each
    learner and number of environments, against the setting's shipped RP predictor."""
    import tempfile

    from masspush.learn.policy import PolicyConfig, train_policy
    from masspush.models import resolve_model
    from masspush.settings import get_setting

    setting, pusher, algos, steps = config.setting, config.pusher, config.algos, config.steps
    envs, n_steps, lockstep = config.envs, config.n_steps, config.lockstep_arms

    spec = get_setting(setting)
    pusher = pusher or spec.pusher
    config = spec.env_config(pusher)
    predictor = resolve_model("rp", spec.name)
    rows = []
    for algo in algos:
        for n_envs in envs:
            policy = PolicyConfig(
                algo=algo, n_envs=n_envs, steps=steps, n_steps=n_steps, lockstep_arms=lockstep
            )
            with tempfile.TemporaryDirectory() as out:
                t0 = time.perf_counter()
                train_policy(config, predictor, out, policy, progress=False)
                elapsed = time.perf_counter() - t0
            done = max(steps, policy.rollout_steps * n_envs)  # PPO finishes its rollout
            rows.append(
                {
                    "setting": setting,
                    "pusher": pusher,
                    "algo": algo,
                    "envs": n_envs,
                    "lockstep_arms": lockstep,
                    "pushes": done,
                    "seconds": round(elapsed, 1),
                    "pushes_per_s": round(done / elapsed, 1),
                }
            )
    return rows


def bench_motion(config: MotionBench) -> dict:
    """How far the chains of a dataset moved per push (is there anything to observe?)."""
    from masspush.data.dataset import load_dataset

    manifest, eps = load_dataset(config.data, limit=config.episodes)
    eps = eps.select(eps.ok)
    c = eps.configs.astype(float)
    moved = 1000 * np.linalg.norm(c[:, 1:, :2] - c[:, :-1, :2], axis=-1).ravel()
    joint = np.abs(c[:, 1:, 3] - c[:, :-1, 3]).ravel()
    return {
        "dataset": str(config.data),
        "setting": manifest.setting["name"],
        "pusher": manifest.pusher,
        "pushes": int(moved.size),
        "root_moved_mm_median": float(np.median(moved)),
        "root_moved_mm_p90": float(np.percentile(moved, 90)),
        "share_moved_under_2mm": float(np.mean(moved < 2)),
        "first_joint_change_rad_median": float(np.median(joint)),
    }


def bench_physics(config: PhysicsBench = PhysicsBench(), progress: bool = True) -> list:
    """Rest-pose convergence in the time step and chaotic sensitivity
    (`masspush.sim.convergence`)."""
    from masspush.sim.convergence import validate_physics

    return validate_physics(
        n_links=config.links, mass_range=config.mass_range, pushes=config.pushes,
        seed=config.seed, progress=progress,
    )  # fmt: skip
