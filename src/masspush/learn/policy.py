"""The pushing policy: PPO over the push history, rewarded by a frozen predictor.

At every push the policy sees what the robot has seen so far, the rest poses q_0..q_t and
its own actions a_0..a_{t-1}, as one fixed-size vector (`history_features`: the
predictor's "relative" features, zero for pushes not made yet, and the push number). After
the push the frozen predictor estimates the mass distribution from the history and the
reward is the paper's, as its authors coded it: 10 (1 - 2 mean_i |m_i - m_hat_i|). A push
that fails (the chain flips, the arm touches it) ends the episode with reward 0.

Two learners, both from the field's libraries:
- "recurrent": sb3-contrib RecurrentPPO with the paper's LSTM policy (two tanh layers of 64,
  LSTM 256) and hyperparameters (`PAPER_PPO`);
- "mlp": stable-baselines3 PPO with the same two tanh layers and no LSTM: the padded
  history already holds everything an LSTM would remember in a 2- or 3-push episode.
"""

from __future__ import annotations

import json
import multiprocessing
import os
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np

from masspush.cluster.pool import Workers, is_pool
from masspush.config import EnvConfig
from masspush.data.rollout import POLICIES, Episodes, Policy
from masspush.learn.features import (
    LOSS_REWARD,
    REWARDS,
    history_dim,
    history_features,
    push_reward,
)
from masspush.learn.vec_env import BatchPushVecEnv
from masspush.sim.pushers import on_batch_path, pusher_kind, reach_governor

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecEnv

ChainEnvFactory = Callable[[], gym.Env]
"""Makes the environment whose chains the policy pushes, inside each worker: one that speaks
`masspush.env.ChainEnv`'s language (observation, `info` keys), such as
`masspush.real.robot_env.RobotEnv` over a simulated robot in another world."""

ALGOS = ("recurrent", "mlp")

# PPO hyperparameters [paper-details.md, "Policy"; the authors' code]: learning rate 1e-4,
# 16 environments x 128 steps per update, gamma 0.99, lambda 0.95, entropy 0.01, clip 0.2,
# 4 minibatches x 4 epochs; policy: two tanh layers of 64, then an LSTM of 256.
PAPER_PPO: dict[str, Any] = {
    "learning_rate": 1e-4,
    "n_steps": 128,
    "gamma": 0.99,
    "gae_lambda": 0.95,
    "ent_coef": 0.01,
    "clip_range": 0.2,
    "n_epochs": 4,
    "batch_size": 16 * 128 // 4,
}
PAPER_N_ENVS = 16
PAPER_NET = [64, 64]
PAPER_LSTM = 256


class PushPolicyEnv(gym.Env):
    """One chain, pushed K times; observation: the history; reward: the predictor's accuracy.

    The predictor is loaded from `predictor_path` inside the environment (and so inside each
    worker process of a SubprocVecEnv), frozen, on one thread.

    With `chain_env` (a `ChainEnvFactory`), the chains are those of the environment it makes
    (another world, `masspush.real.randomisation`) instead of the training simulation.

    With `runs` > 1 an episode is that many runs of K pushes on one chain, as
    `masspush.real.robot.run_segments` deploys them: each run starts where the last left the
    chain, with the history (and so the predictor) restarted and the policy's memory kept; a
    chain lost in any run ends the episode.
    """

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 (gymnasium's convention)

    def __init__(
        self, env_config: EnvConfig, predictor_path: str,
        chain_env: ChainEnvFactory | None = None, runs: int = 1, reward: str = "paper",
        loss_reward: float = LOSS_REWARD,
    ):  # fmt: skip
        import torch

        from masspush.env import ChainEnv
        from masspush.learn.predictor import load_model

        if runs < 1:
            raise ValueError(f"runs must be >= 1, got {runs}")
        if runs > 1 and chain_env is not None:
            raise ValueError("runs > 1 needs the training simulation, not another world")
        if reward not in REWARDS:
            raise ValueError(f"reward must be one of {REWARDS}, got {reward!r}")
        self.reward, self.loss_reward = reward, loss_reward
        torch.set_num_threads(1)
        physics = env_config.physics
        self.env_config, self.runs = env_config, runs
        chain_config = replace(env_config, pushes=env_config.pushes * runs)
        self.chain_env = ChainEnv.from_config(chain_config) if chain_env is None else chain_env()
        self.predictor, _ = load_model(predictor_path)
        self.k, self.n, self.d = env_config.pushes, physics.n_links, physics.obs_dim
        self.workspace = pusher_kind(env_config.pusher).workspace
        self.governor = reach_governor(env_config.pusher, physics)
        dim = history_dim(self.n, self.k, self.workspace)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (dim,), np.float32)
        self.action_space = self.chain_env.action_space

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        # A chain that is already unstable before any push is redrawn: nothing to learn there.
        # `options` pin the chain (ChainEnv's options), for tests and demonstrations.
        obs, info = self.chain_env.reset(seed=int(self.np_random.integers(2**63)), options=options)
        while info["failure"] is not None:
            if options:
                raise ValueError(f"the chain of options {options} fails at rest: {info['failure']}")
            obs, info = self.chain_env.reset(seed=int(self.np_random.integers(2**63)))
        self._obs = np.full((1, self.k + 1, self.d), np.nan, np.float32)
        self._actions = np.full((1, self.k, 2), np.nan, np.float32)
        self._lengths = info["lengths"][None].astype(np.float32)
        self._truth = info["mass_distribution"]
        self._obs[0, 0] = obs[: self.d]
        self._t, self._run = 0, 0
        return self._features(), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        action = np.clip(np.asarray(action, np.float32), -1.0, 1.0)
        if self.governor is not None:  # part of the stationary robot, as in deployment
            action = self.governor(action, self._obs[0, self._t], self._lengths[0])
        obs, _, terminated, _, info = self.chain_env.step(action)
        self._actions[0, self._t] = action
        if info["failure"] is not None:
            self._t += 1
            reward = push_reward(None, None, info["failure"], self.reward, self.loss_reward)
            return self._features(), reward, True, False, info
        self._obs[0, self._t + 1] = obs[: self.d]
        self._t += 1
        history = Episodes.history(self._obs, np.nan_to_num(self._actions), self._lengths)
        estimate = self.predictor.predict(history)[0, self._t - 1]
        reward = push_reward(estimate, self._truth, None, self.reward)
        info["estimate"] = estimate
        if self._t == self.k and self._run + 1 < self.runs:
            self._next_run()
        return self._features(), reward, bool(terminated), False, info

    def _next_run(self) -> None:
        """The next run starts from the last rest pose seen, with an empty history."""
        last = self._obs[0, self.k].copy()
        self._obs[:] = np.nan
        self._actions[:] = np.nan
        self._obs[0, 0] = last
        self._t, self._run = 0, self._run + 1

    def _features(self) -> np.ndarray:
        return history_features(self._obs, self._actions, self._lengths, self._t, self.workspace)[0]


@dataclass(frozen=True)
class PolicyConfig:
    """How to train the pushing policy. The network and PPO's other settings are the
    paper's (`PAPER_PPO`); where a default is ours, the field says why (docs/training.md)."""

    algo: str = "recurrent"
    """"recurrent" (RecurrentPPO, the paper's LSTM policy) or "mlp" (PPO, padded history)."""
    n_envs: int = 64
    """Parallel environments [paper: 16; ours: 64 runs the batch path 40 % faster, and
    n_steps shrinks so that an update still sees the paper's 2048 pushes]."""
    steps: int = 75_000
    """PPO environment steps (pushes) per meta-iteration [paper: 70k-80k]."""
    n_steps: int | None = None
    """Steps per environment between updates; None keeps the paper's 16 x 128 buffer."""
    learning_rate: float = 3e-4
    """[ours, SB3's default; paper: 1e-4, with which 75k pushes barely move the policy]."""
    n_epochs: int = 10
    """Passes over each rollout [ours, SB3's default; paper: 4]."""
    log_std_init: float = -1.5
    """Initial log standard deviation of the actions [ours; SB3: 0]. With a standard
    deviation of 1 on a [-1, 1] box most sampled pushes are far from the policy's mean, and
    fast pushes near the joint tip the chain over (reward 0): PPO then learns to push
    slowly, which teaches the predictor least. 0.22 keeps the search local."""
    runs: int = 1
    """Runs of the setting's pushes per training episode, on one chain [ours; issue 28]: each
    run starts where the last left the chain, the history and the predictor restarting, the
    policy's LSTM state kept, and a chain lost in any run ends the episode, so that a push
    leaving the chain where a later run loses it pays for that. A stationary robot's policy
    deployed as runs of the policy (`run_segments`) needs it; 1 is the paper's episode."""
    reward: str = "paper"
    """"paper" (the paper's reward) or "gain" (the paper's minus the prior's guess: a push
    that teaches nothing earns about 0) [ours, for episodes of many runs; `push_reward`]."""
    loss_reward: float = LOSS_REWARD
    """The reward of a push after which a stationary robot lost the chain [ours: -10,
    `LOSS_REWARD`]; lower makes a policy trained on runs keep the chain at the cost of
    informative pushes (docs/notebook 2026-12-02-runs-of-the-policy)."""
    initial_action: tuple[float, float] = (0.5, 0.5)
    """The policy's initial mean action [ours; docs/training.md]. The zero action is a
    saddle in both coordinates: the speed is 5 |a1| and the sign of a1 only picks the side,
    a2 = 0 is the joint, where a fast push tips the chain over, and either side of it is as
    good as the other, so the gradient out of it vanishes. (0.5, 0.5) is a medium-speed push
    on the middle of the second link, which PPO then moves."""
    lockstep_arms: bool = True
    """An arm's environments in lockstep on the batch path (one process, MuJoCo's threads,
    the arm's compiled law as its control callback), as the stiff pusher's always are
    [ours]; --no-lockstep-arms: one process each (where no compiled law exists, always).
    The physics is the same push for push (tested); the transitions are the batch
    environments' (`masspush.learn.vec_env`: a failed push freezes its chain until the
    episode's end, chains drawn from another seed stream), so a policy trains differently
    than in processes. Faster (2 links, 16 environments: 148-152 against 121 pushes/s,
    docs/notebook/2026-12-01-arm-speed.md); the shipped KUKA models were trained this way."""
    seed: int = 0
    """Seed of PPO (weights, sampled actions) and of its environments."""

    def __post_init__(self) -> None:
        if self.algo not in ALGOS:
            raise ValueError(f"algo must be one of {ALGOS}, got {self.algo!r}")
        if len(self.initial_action) != 2 or not all(-1 <= a <= 1 for a in self.initial_action):
            raise ValueError(
                f"initial_action must be two numbers in [-1, 1], got {self.initial_action}"
            )
        if self.learning_rate <= 0 or self.n_epochs < 1:
            raise ValueError(
                f"learning_rate must be > 0 and n_epochs >= 1, got {self.learning_rate}, "
                f"{self.n_epochs}"
            )
        if self.runs < 1:
            raise ValueError(f"runs must be >= 1, got {self.runs}")
        if self.reward not in REWARDS:
            raise ValueError(f"reward must be one of {REWARDS}, got {self.reward!r}")
        if not -1e6 <= self.loss_reward <= 0:
            raise ValueError(f"loss_reward must be in [-1e6, 0], got {self.loss_reward}")
        if self.runs > 1 and self.algo != "recurrent":
            raise ValueError("runs > 1 needs the recurrent policy: it remembers earlier runs")
        if self.n_envs < 1 or self.steps < 1 or (self.n_steps is not None and self.n_steps < 2):
            raise ValueError(
                f"n_envs and steps must be >= 1 and n_steps >= 2, got {self.n_envs}, "
                f"{self.steps}, {self.n_steps}"
            )

    @property
    def rollout_steps(self) -> int:
        """Steps per environment between two PPO updates."""
        return self.n_steps or max(2, PAPER_PPO["n_steps"] * PAPER_N_ENVS // self.n_envs)


def make_vec_env(
    env_config: EnvConfig, predictor_path: str | os.PathLike, n_envs: int, seed: int,
    chain_env: ChainEnvFactory | None = None, workers: Workers = None, runs: int = 1,
    reward: str = "paper", loss_reward: float = LOSS_REWARD, lockstep_arms: bool = True,
) -> VecEnv:  # fmt: skip
    """`n_envs` pushing episodes: for a pusher with a batch path in lockstep on the
    multi-threaded batch path (`masspush.learn.vec_env`), for an arm, in another world
    (`chain_env`), with several runs per episode (`runs`) or other rewards as
    PushPolicyEnvs in worker processes, or in a cluster's actors where `workers` is a pool
    that has them (`RayPool.vec_env`: the same transitions)."""
    from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

    from masspush.learn.subproc_vec_env import WatchedSubprocVecEnv

    kind = pusher_kind(env_config.pusher)
    batch = on_batch_path(env_config.pusher) and chain_env is None
    batch = batch and (lockstep_arms or not kind.arm)
    if batch and runs == 1 and reward == "paper" and loss_reward == LOSS_REWARD:
        vec = BatchPushVecEnv(env_config, str(predictor_path), n_envs, seed)
        vec.seed(seed)
        return VecMonitor(vec)

    vec_cls = WatchedSubprocVecEnv if n_envs > 1 else DummyVecEnv
    if is_pool(workers) and hasattr(workers, "vec_env"):
        vec_cls = workers.vec_env
    vec_env_kwargs = None
    if vec_cls is WatchedSubprocVecEnv:
        # Workers start from a fork server, not a fork of this process: forking a process
        # with threads (MuJoCo's batch pool, torch's, Ray's) once left workers stuck in a
        # futex wait (docs/notebook/2026-12-01-arm-speed.md). The server imports the
        # environment's code once, so that each worker forked from it does not import it.
        multiprocessing.get_context("forkserver").set_forkserver_preload([__name__])
        vec_env_kwargs = {"start_method": "forkserver"}
    return sb3_make_vec_env(
        PushPolicyEnv,
        n_envs=n_envs,
        seed=seed,
        vec_env_cls=vec_cls,
        env_kwargs={
            "env_config": env_config,
            "predictor_path": str(predictor_path),
            "chain_env": chain_env,
            "runs": runs,
            "reward": reward,
            "loss_reward": loss_reward,
        },
        vec_env_kwargs=vec_env_kwargs,
    )


def new_model(config: PolicyConfig, vec_env: VecEnv, tensorboard_log: str | None) -> BaseAlgorithm:
    from torch import nn

    kwargs = dict(PAPER_PPO, verbose=0, seed=config.seed, tensorboard_log=tensorboard_log)
    kwargs["n_steps"] = config.rollout_steps
    kwargs["learning_rate"], kwargs["n_epochs"] = config.learning_rate, config.n_epochs
    kwargs["batch_size"] = max(2, config.rollout_steps * config.n_envs // 4)  # 4 minibatches
    if config.algo == "recurrent":
        from sb3_contrib import RecurrentPPO

        policy_kwargs = {
            "net_arch": PAPER_NET,
            "activation_fn": nn.Tanh,
            "lstm_hidden_size": PAPER_LSTM,
            "log_std_init": config.log_std_init,
        }
        model = RecurrentPPO("MlpLstmPolicy", vec_env, policy_kwargs=policy_kwargs, **kwargs)
        return _start_at(model, config.initial_action)
    from stable_baselines3 import PPO

    policy_kwargs = {
        "net_arch": PAPER_NET,
        "activation_fn": nn.Tanh,
        "log_std_init": config.log_std_init,
    }
    model = PPO("MlpPolicy", vec_env, policy_kwargs=policy_kwargs, **kwargs)
    return _start_at(model, config.initial_action)


def _start_at(model: BaseAlgorithm, action: tuple[float, float]) -> BaseAlgorithm:
    import torch

    with torch.no_grad():
        model.policy.action_net.bias[:] = torch.as_tensor(action)
    return model


def strip_policy(source: str | os.PathLike, target: str | os.PathLike) -> Path:
    """A copy of a saved policy without the optimizer's moments (two thirds of the file):
    what acting needs, and enough to go on training (Adam then starts afresh)."""
    import io
    import zipfile

    import torch

    with zipfile.ZipFile(source) as src, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "policy.optimizer.pth":
                state = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
                buffer = io.BytesIO()
                torch.save({**state, "state": {}}, buffer)
                data = buffer.getvalue()
            dst.writestr(item, data)
    return Path(target)


def load_sb3(path: str | os.PathLike, algo: str, env: VecEnv | None = None) -> BaseAlgorithm:
    if algo == "recurrent":
        from sb3_contrib import RecurrentPPO

        return RecurrentPPO.load(path, env=env, device="cpu")
    from stable_baselines3 import PPO

    return PPO.load(path, env=env, device="cpu")


def train_policy(
    env_config: EnvConfig,
    predictor_path: str | os.PathLike,
    out_dir: str | os.PathLike,
    config: PolicyConfig = PolicyConfig(),
    init: str | os.PathLike | None = None,
    progress: bool = True,
    meta: dict[str, Any] | None = None,
    chain_env: ChainEnvFactory | None = None,
    workers: Workers = None,
) -> Path:
    """Train (or, from `init`, go on training) a policy against a frozen predictor; in the
    training simulation, or on the chains of `chain_env` (see `PushPolicyEnv`).

    Checkpoints every 10 updates (out_dir/checkpoint_<steps>_steps.zip) and resumes from
    the last; the finished policy is out_dir/policy.zip, with policy.json (what it was
    trained for, with `meta`) and progress.csv (the predictor's error after each rollout)."""
    from stable_baselines3.common.callbacks import CallbackList, CheckpointCallback

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    final = out / "policy.zip"
    if final.exists():
        return final
    vec_env = make_vec_env(
        env_config, predictor_path, config.n_envs, config.seed, chain_env, workers,
        config.runs, config.reward, config.loss_reward, config.lockstep_arms,
    )  # fmt: skip
    try:
        checkpoints = sorted(out.glob("checkpoint_*_steps.zip"), key=_checkpoint_steps)
        start = checkpoints[-1] if checkpoints else init
        if start is not None:
            model = load_sb3(start, config.algo, env=vec_env)
            model.tensorboard_log = str(out / "tb")
        else:
            model = new_model(config, vec_env, str(out / "tb"))
        done = _checkpoint_steps(checkpoints[-1]) if checkpoints else 0
        buffer = model.n_steps * config.n_envs
        callback = CallbackList(
            [
                CheckpointCallback(
                    save_freq=max(1, 10 * buffer // config.n_envs),
                    save_path=str(out),
                    name_prefix="checkpoint",
                ),
                _prediction_error_log(out / "progress.csv"),
            ]
        )
        remaining = config.steps - done
        if remaining > 0:
            model.learn(
                remaining,
                callback=callback,
                progress_bar=progress,
                reset_num_timesteps=not checkpoints,
                tb_log_name="ppo",
            )
        model.save(final)
    finally:
        vec_env.close()
    (out / "policy.json").write_text(
        json.dumps(
            {
                **(meta or {}),
                "algo": config.algo,
                "config": asdict(config),
                "pusher": env_config.pusher,
                "predictor": str(predictor_path),
            },
            indent=2,
        )
    )
    for path in out.glob("checkpoint_*_steps.zip"):
        path.unlink()
    return final


def _prediction_error_log(path: Path) -> BaseCallback:
    """A callback: after each PPO rollout, the frozen predictor's error (the paper's metric)
    on the episodes that ended in it, to TensorBoard and to `path` (CSV, appended)."""
    from stable_baselines3.common.callbacks import BaseCallback

    from masspush.metrics import percentage_error

    class PredictionErrorLog(BaseCallback):
        def _on_rollout_start(self) -> None:
            self.final: list[tuple[np.ndarray, np.ndarray]] = []
            self.rewards: list[float] = []

        def _on_step(self) -> bool:
            for info, done, reward in zip(
                self.locals["infos"], self.locals["dones"], self.locals["rewards"], strict=True
            ):
                self.rewards.append(float(reward))
                if done and "estimate" in info:
                    self.final.append((info["estimate"], info["mass_distribution"]))
            return True

        def _on_rollout_end(self) -> None:
            if not self.final:
                return
            pred, true = (np.array(x) for x in zip(*self.final, strict=True))
            error = percentage_error(pred, true)
            self.logger.record("predictor/percentage_error", error)
            new = not path.exists()
            with path.open("a") as f:
                if new:
                    f.write("timesteps,percentage_error,mean_reward,episodes\n")
                f.write(
                    f"{self.num_timesteps},{error:.4f},{np.mean(self.rewards):.4f},"
                    f"{len(self.final)}\n"
                )

    return PredictionErrorLog()


def _checkpoint_steps(path: Path) -> int:
    return int(path.stem.split("_")[1])


class LearnedPolicy:
    """A trained PPO policy as a rollout `Policy`: pushes for a batch of episodes.

    Deterministic (the policy's mean action, as the paper evaluated) or stochastic; a
    stochastic policy draws from torch seeded by the episodes' seeds, so runs repeat."""

    def __init__(
        self, path: str | os.PathLike, algo: str, deterministic: bool = True,
        pusher: str | None = None, runs: int = 1,
    ):  # fmt: skip
        """`pusher`: the pusher it was trained with (a stationary robot's policy also sees
        where the chain lies from the robot; `history_features`); `runs`: the runs per
        episode it was trained on (`PolicyConfig.runs`: its memory spans that many runs)."""
        self.path, self.algo, self.deterministic = str(path), algo, deterministic
        self.runs = runs
        self.workspace = None if pusher is None else pusher_kind(pusher).workspace
        self.name = f"learned:{Path(path).name}"
        self._model = None

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "_model": None}  # worker processes load their own copy

    def in_worker(self) -> None:
        """One torch thread in a worker process: with one worker per core, torch's own
        threads oversubscribed the cores and a policy acting on one observation at a time
        ran ~10x slower."""
        import torch

        torch.set_num_threads(1)

    def reset(self, seeds: np.ndarray) -> None:
        import torch

        if self._model is None:
            self._model = load_sb3(self.path, self.algo)
        torch.manual_seed(int(np.bitwise_xor.reduce(np.asarray(seeds, np.uint64))) % 2**63)
        self._state = None
        self._starts = np.ones(len(seeds), bool)

    def act(
        self, observations: np.ndarray, actions: np.ndarray, step: int, lengths: np.ndarray
    ) -> np.ndarray:
        features = history_features(observations, actions, lengths, step, self.workspace)
        expected = self._model.observation_space.shape[0]
        if features.shape[1] != expected:
            raise ValueError(
                f"{self.path} takes {expected} inputs, the history gives {features.shape[1]}: "
                "a policy trained for another pusher or number of pushes"
            )
        action, self._state = self._model.predict(
            features,
            state=self._state,
            episode_start=self._starts,
            deterministic=self.deterministic,
        )
        self._starts = np.zeros(len(features), bool)
        return np.clip(action, -1.0, 1.0).astype(np.float32)


def model_policy(meta: dict[str, Any], model_file: str | os.PathLike) -> Policy:
    """The pushing policy a predictor was trained with: random, or the learned policy whose
    file its metadata names (relative to the model file), acting deterministically."""
    name = meta.get("policy", "random")
    if name == "learned":
        policy_file = Path(model_file).parent / meta["policy_file"]
        if not policy_file.exists():
            raise ValueError(f"{model_file} needs its policy file {policy_file}, which is missing")
        return LearnedPolicy(
            policy_file,
            meta["policy_algo"],
            deterministic=True,
            pusher=meta.get("pusher"),
            runs=meta.get("policy_runs", 1),
        )
    if name not in POLICIES:
        raise ValueError(f"{model_file} names an unknown policy {name!r}")
    return POLICIES[name]()
