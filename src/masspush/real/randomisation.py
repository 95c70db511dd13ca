"""Domain randomisation: fine-tune a predictor on episodes from worlds drawn at random.

A predictor trained in one simulated world reads the biases of another world (a real
lab's tracker offset, contact model, friction that varies over the table) as mass. This
module runs a trained model's own policy in worlds drawn per episode from
`masspush.real.target_world.WorldRanges`, with the robot's view of each episode (noisy, biased
observations; the link lengths it was told), and fine-tunes the predictor on them, so that
it learns to read through what differs between worlds. The policy is kept as it is unless
asked otherwise.

    masspush randomise --setting real-ur10-4push --model tp+ --episodes 8000 --ship

With `--policy-steps N` the policy is trained on first, with PPO in randomised worlds
(`masspush.real.robot_env`), and the episodes are the new policy's: the paper's meta-iteration
in randomised worlds.

Episodes go to NPZ shards (the `masspush.data.dataset` format) in `--out`; shard j holds episodes
j*S .. (j+1)*S - 1 and episode i is fully determined by (base seed, i), so a stopped
collection resumes by computing the missing shards. The fine-tuning resumes from its
checkpoint (`masspush.learn.predictor.train_predictor`).
"""

from __future__ import annotations

import json
import os
from concurrent.futures import as_completed
from dataclasses import asdict, dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from masspush.cluster.pool import local_processes
from masspush.config import check_int
from masspush.data.dataset import MANIFEST, Manifest, new_manifest, write_manifest
from masspush.data.rollout import Episodes, Policy, empty_episodes, failure_code
from masspush.real.robot import EstimationEpisode
from masspush.real.robot_env import RobotEnv
from masspush.real.target_world import TargetWorld, TargetWorldRobot, WorldRanges

SHIPPED_NAME = "tp+dr"
"""The name a randomised predictor ships under, beside the model it was tuned from."""
SHIPPED_POLICY_NAME = "tp+drp"
"""... and with its policy trained on in randomised worlds too (`policy_steps`)."""
WHERE = {"randomised": "randomised worlds", "target": "the target world"}
"""Where the episodes are collected: worlds drawn from `ranges` (domain randomisation), or
the sim-to-real target world itself (an upper bound: what fine-tuning on many labelled
episodes of the very setup that is tested could reach, which no sim-trained model may use)."""
WORLDS = tuple(WHERE)
SEED_STRIDE = 64
"""Seeds per episode: a chain that cannot be placed is redrawn with the next seed, so
episode i owns seeds base + 64 i ... base + 64 i + 63."""


@dataclass(frozen=True)
class RandomiseConfig:
    """`masspush randomise`: fine-tune a predictor on its policy's episodes in randomised
    worlds (domain randomisation)."""

    setting: str = "real-ur10-4push"
    """Named setting of the predictor and its chains."""
    model: str = "tp+"
    """Shipped name or path of the predictor to fine-tune; its policy makes the pushes."""
    episodes: int = 8000
    """Randomised episodes to collect."""
    shard_size: int = 250
    """Episodes per shard file (a killed collection resumes by shard)."""
    base_seed: int = 50_000_000
    """Far from the seeds `masspush sim2real` gives the target world (0 ... ~500 000)."""
    steps: int = 10_000
    """Fine-tuning steps (batches of 256 episodes)."""
    policy_steps: int = 0
    """PPO pushes to go on training the model's policy in randomised worlds, against the
    model's predictor frozen, before the episodes are collected with the new policy; 0 keeps
    the policy as it is."""
    policy_envs: int = 8
    """Parallel environments for that PPO training (the arm's recipe in docs/notebook)."""
    policy_rollout: int | None = None
    """Pushes per environment between two PPO updates; None keeps the paper's buffer."""
    ranges: WorldRanges = field(default_factory=WorldRanges)
    world: str = "randomised"
    """randomised: worlds drawn per episode; target: the sim-to-real target world itself, an
    upper bound (what many labelled episodes of the tested setup could give), not to ship."""
    lab: int | None = None
    """With world=target: every episode in this one lab (`masspush sim2real --lab`), whose
    constants stay the same from one episode to the next; None: a new lab per episode. What
    a simulator that knew that lab exactly could learn (not to ship)."""

    def __post_init__(self) -> None:
        if self.world not in WORLDS:
            raise ValueError(f"world must be one of {list(WORLDS)}, got {self.world!r}")
        check_int("lab", self.lab, low=0, optional=True)
        if self.lab is not None and self.world != "target":
            raise ValueError(f"lab is one lab of the target world: pass world=target, not "
                             f"{self.world!r}")  # fmt: skip
        if self.episodes < 2 or self.shard_size < 1 or self.steps < 1:
            raise ValueError(
                f"episodes must be >= 2, shard_size and steps >= 1; got {self.episodes}, "
                f"{self.shard_size}, {self.steps}"
            )
        if self.policy_steps < 0 or self.policy_envs < 1:
            raise ValueError(
                f"policy_steps must be >= 0 and policy_envs >= 1; got {self.policy_steps}, "
                f"{self.policy_envs}"
            )

    @property
    def worlds(self) -> WorldRanges | TargetWorld:
        """What `TargetWorldRobot` is given: ranges to draw from, or the one target world."""
        return self.ranges if self.world == "randomised" else TargetWorld()

    @property
    def shipped_name(self) -> str:
        return SHIPPED_POLICY_NAME if self.policy_steps else SHIPPED_NAME

    @property
    def shards(self) -> int:
        return -(-self.episodes // self.shard_size)

    def shard_len(self, j: int) -> int:
        return min(self.shard_size, self.episodes - j * self.shard_size)

    def identity(self) -> dict[str, Any]:
        """What a resumed collection must share with the one it continues."""
        d = asdict(self)
        for key in ("episodes", "steps"):
            d.pop(key)
        return d


def run_randomised(
    setting: str, model_file: str | os.PathLike, world: WorldRanges | TargetWorld,
    indices: np.ndarray, base_seed: int, policy: Policy | None = None, lab: int | None = None,
) -> Episodes:  # fmt: skip
    """Episodes `indices` of the model's policy (or of `policy`, a `masspush.data.rollout.Policy`)
    in worlds drawn from `world` (or in that one `TargetWorld`, in its lab `lab` if given), as
    the robot saw them (observations with the world's noise and bias, the told link
    lengths)."""
    from masspush.models import model_and_policy
    from masspush.real.robot import run_estimation
    from masspush.settings import get_setting

    setting_ = get_setting(setting)
    predictor, _, model_policy = model_and_policy(model_file, setting_.name)
    policy = policy or model_policy
    pushes = setting_.env_config().pushes
    robot = TargetWorldRobot(setting_, world=world, lab=lab)
    rows = []
    for i in indices:
        robot.seed = base_seed + SEED_STRIDE * int(i)
        first = robot.seed
        episode = run_estimation(robot, predictor, policy, pushes, seed=first)
        if robot.seed - first > SEED_STRIDE:
            raise RuntimeError(f"episode {i} could not place a chain in {SEED_STRIDE} tries")
        rows.append(_episode_arrays(int(i), first, episode, robot.truth, pushes))
    robot.close()
    return Episodes.concatenate(rows)


def _episode_arrays(
    index: int, seed: int, episode: EstimationEpisode, truth: dict, pushes: int
) -> Episodes:
    out = empty_episodes(1, pushes, len(truth["masses"]))
    out.index[0], out.seed[0] = index, seed
    out.observations[0, 0], out.configs[0, 0] = episode.start.config, truth["config"]
    for k, (action, report) in enumerate(zip(episode.actions, episode.reports, strict=True)):
        out.actions[0, k] = action
        out.executed[0, k] = report.details["executed"]
        out.failure[0, k] = failure_code(report.failure)
        if report.failure is None:
            out.observations[0, k + 1] = report.config
            out.configs[0, k + 1] = report.details["config"]
    out.masses[0], out.friction[0] = truth["masses"], truth["friction"]
    out.lengths[0] = episode.start.lengths
    return out


def _shard_job(args: tuple) -> tuple[int, int]:
    import torch

    from masspush.data.dataset import shard_path, write_shard

    torch.set_num_threads(1)  # one process per core, as in `masspush.data.rollout`
    config, model_file, root, j = args
    lo = j * config.shard_size
    indices = np.arange(lo, lo + config.shard_len(j))
    episodes = run_randomised(config.setting, model_file, config.worlds, indices,
                              config.base_seed, lab=config.lab)  # fmt: skip
    write_shard(shard_path(root, j), episodes)
    return j, len(indices)


def collect_randomised(
    config: RandomiseConfig, out: str | os.PathLike, workers: int | None = None,
    progress: bool = True, model_file: str | os.PathLike | None = None,
) -> Episodes:  # fmt: skip
    """Collect (or resume collecting) the randomised episodes into `out`; all of them. The
    pushes are those of `model_file`'s policy (default: the configured model's)."""
    from masspush.data.dataset import read_shard, shard_complete, shard_path
    from masspush.models import resolve_model

    root = Path(out)
    root.mkdir(parents=True, exist_ok=True)
    model_file = model_file or resolve_model(config.model, config.setting)
    stamp = root / "randomise.json"
    identity = json.loads(json.dumps(config.identity()))  # tuples as lists, as on disk
    if not stamp.exists() and (root / MANIFEST).exists():
        raise ValueError(f"{root} holds a dataset of `masspush collect`; use another --out")
    if stamp.exists():
        old = json.loads(stamp.read_text())
        if old != identity:
            raise ValueError(
                f"{root} holds episodes of another randomisation ({old}); use another --out"
            )
    stamp.write_text(json.dumps(identity, indent=2) + "\n")
    # ... and a dataset manifest, so that what reads datasets (`masspush train-density`)
    # reads these episodes too, knowing where they were pushed.
    write_manifest(root, _manifest(config, model_file))

    todo = [
        j for j in range(config.shards)
        if not shard_complete(shard_path(root, j), config.shard_len(j))
    ]  # fmt: skip
    workers = max(1, min(workers or os.cpu_count() or 1, len(todo)))
    done = config.episodes - sum(config.shard_len(j) for j in todo)
    with tqdm(total=config.episodes, initial=done, desc=f"{WHERE[config.world]}, {config.model}",
              unit="ep", disable=not progress) as bar:  # fmt: skip
        if todo:
            with local_processes(workers) as pool:
                jobs = [pool.submit(_shard_job, (config, model_file, root, j)) for j in todo]
                for job in as_completed(jobs):
                    bar.update(job.result()[1])
    return Episodes.concatenate([read_shard(shard_path(root, j)) for j in range(config.shards)])


def _manifest(config: RandomiseConfig, model_file: str | os.PathLike) -> Manifest:
    from masspush.models import model_and_policy
    from masspush.settings import get_setting

    setting = get_setting(config.setting)
    env_config = setting.env_config()
    policy = model_and_policy(model_file, setting.name)[2]
    return new_manifest(setting, env_config, env_config.pusher, policy.name, config.base_seed,
                        config.episodes, config.shard_size, worlds=config.world)  # fmt: skip


def train_randomised_policy(
    config: RandomiseConfig, model_file: str | os.PathLike, out: str | os.PathLike,
    progress: bool = True,
) -> Path:  # fmt: skip
    """Go on training the model's policy with PPO in randomised worlds, rewarded by the
    model's predictor (frozen); returns a model file in `out` that is the same predictor
    with the new policy (what `collect_randomised` then pushes with)."""
    from masspush.learn.policy import PolicyConfig, train_policy
    from masspush.learn.predictor import load_model, save_model
    from masspush.settings import get_setting

    setting = get_setting(config.setting)
    model, meta = load_model(model_file, setting.name)
    if meta.get("policy") != "learned":
        raise ValueError(f"{model_file} has no learned policy to train on")
    root = Path(out)
    policy = train_policy(
        setting.env_config(),
        model_file,
        root / "policy",
        PolicyConfig(
            algo=meta["policy_algo"],
            n_envs=config.policy_envs,
            steps=config.policy_steps,
            n_steps=config.policy_rollout,
            seed=config.base_seed % 2**31,
        ),
        init=Path(model_file).parent / meta["policy_file"],
        progress=progress,
        meta={"randomised": asdict(config)},
        chain_env=partial(
            world_env,
            setting.name,
            config.worlds,
            setting.env_config().pusher,
            setting.env_config().pushes,
            config.lab,
        ),
    )
    pushing = root / "pushing-model.pt"
    # Its policy was fine-tuned on one run per episode, whatever the original's.
    kept = {k: v for k, v in meta.items() if k != "policy_runs"}
    save_model(pushing, model, {**kept, "policy_file": str(policy.relative_to(root))})
    return pushing


def world_env(
    setting: str, world: TargetWorld | WorldRanges, pusher: str, pushes: int, lab: int | None = None
) -> RobotEnv:
    """A policy-training environment whose chains are pushed in `world` (in its lab `lab` if
    given; a `masspush.learn.policy.ChainEnvFactory` once its arguments are bound)."""
    return RobotEnv(TargetWorldRobot(setting, world=world, pusher=pusher, lab=lab), pushes)


@dataclass(frozen=True)
class RandomiseRun:
    """Where and how `masspush randomise` runs."""

    out: str | None = None
    """Run directory; a rerun resumes it (default:
    runs/randomise-<setting>[-policy][-target][-labL])."""
    workers: int | None = None
    """Processes collecting the episodes (default: one per core)."""
    ship: bool = False
    """Ship the result as tp+dr (tp+drp with --policy-steps) beside the model."""

    def __post_init__(self) -> None:
        check_int("workers", self.workers, optional=True)


def randomise_run(config: RandomiseConfig, run: RandomiseRun) -> Path:
    """`randomise` in `run.out`, or in the default directory named for what it does."""
    suffix = "-policy" if config.policy_steps else ""
    suffix += "-target" if config.world == "target" else ""
    suffix += "" if config.lab is None else f"-lab{config.lab}"
    out = run.out or f"runs/randomise-{config.setting}{suffix}"
    return randomise(config, out, run.workers, ship=run.ship)


def randomise(
    config: RandomiseConfig, out: str | os.PathLike, workers: int | None = None,
    ship: bool = False, progress: bool = True,
) -> Path:  # fmt: skip
    """Collect the randomised episodes and fine-tune the model's predictor on them; returns
    the fine-tuned predictor's file (shipped as `config.shipped_name` beside the model if
    `ship`). With `policy_steps`, the policy is first trained on in randomised worlds
    (`train_randomised_policy`) and the episodes are its pushes; it ships beside the
    predictor."""
    from masspush.learn.predictor import load_model, train_predictor
    from masspush.learn.recipe import FINETUNE
    from masspush.models import resolve_model, ship_model, shipped_file

    model_file = resolve_model(config.model, config.setting)
    shipped = shipped_file(config.setting, config.shipped_name)
    # A tuned predictor ships beside the policy it reads; with policy_steps that policy is
    # shipped with it, so any learned model may be its start (e.g. a tp+drp, to go on).
    if (
        ship
        and not config.policy_steps
        and (config.model != "tp+" or Path(model_file).parent != shipped.parent)
    ):
        raise ValueError(
            f"--ship ships the shipped tp+ tuned as {SHIPPED_NAME} (its policy file sits "
            f"beside it); got --model {config.model}"
        )
    if ship and config.world != "randomised":
        raise ValueError(
            "a predictor tuned in the target world itself is an upper bound for the "
            "sim-to-real test, not a model to ship; drop --ship"
        )
    pushing = model_file
    if config.policy_steps:
        pushing = train_randomised_policy(config, model_file, out, progress)
    episodes = collect_randomised(config, out, workers, progress, pushing)
    model, meta = load_model(pushing, config.setting)
    run_dir = Path(out) / "predictor"
    pushing_policy_file = meta.get("policy_file")
    if pushing_policy_file:
        # Named relative to the model file; the tuned predictor lives in run_dir.
        policy_file = Path(pushing).parent / pushing_policy_file
        meta = {**meta, "policy_file": os.path.relpath(policy_file, run_dir)}
    train_predictor(
        episodes,
        run_dir,
        replace(FINETUNE, steps=config.steps, eval_every=min(config.steps, 2_500)),
        {**meta, "finetuned_from": str(model_file), "randomised": asdict(config)},
        progress=progress,
        init=model,
    )
    trained = run_dir / "predictor.pt"
    if not ship:
        return trained
    # Without policy_steps it reads the shipped model's own policy, already beside it.
    shared = None if config.policy_steps else pushing_policy_file
    return ship_model(trained, shipped, shared_policy=shared)[0]
