"""Domain randomisation: fine-tune a predictor on episodes from worlds drawn at random.

A predictor trained in one simulated world reads the biases of another world (a real
lab's tracker offset, contact model, friction that varies over the table) as mass. This
module runs a trained model's own policy in worlds drawn per episode from
`masspush.target_world.WorldRanges`, with the robot's view of each episode (noisy, biased
observations; the link lengths it was told), and fine-tunes the predictor on them, so that
it learns to read through what differs between worlds. The policy is kept as it is.

    masspush randomise --setting real-ur10-4push --model tp+ --episodes 8000 --ship

Episodes go to NPZ shards (the `masspush.dataset` format) in `--out`; shard j holds episodes
j*S .. (j+1)*S - 1 and episode i is fully determined by (base seed, i), so a stopped
collection resumes by computing the missing shards. The fine-tuning resumes from its
checkpoint (`masspush.predictor.train_predictor`).
"""

from __future__ import annotations

import json
import os
import shutil
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from masspush.rollout import Episodes, empty_episodes, failure_code
from masspush.target_world import WorldRanges

SHIPPED_NAME = "tp+dr"
"""The name a randomised predictor ships under, beside the model it was tuned from."""
SEED_STRIDE = 64
"""Seeds per episode: a chain that cannot be placed is redrawn with the next seed, so
episode i owns seeds base + 64 i ... base + 64 i + 63."""


@dataclass(frozen=True)
class RandomiseConfig:
    setting: str = "real-ur10-4push"
    model: str = "tp+"
    """Shipped name or path of the predictor to fine-tune; its policy makes the pushes."""
    episodes: int = 8000
    shard_size: int = 250
    base_seed: int = 50_000_000
    """Far from the seeds `masspush sim2real` gives the target world (0 ... ~500 000)."""
    steps: int = 10_000
    """Fine-tuning steps (batches of 256 episodes)."""
    ranges: WorldRanges = field(default_factory=WorldRanges)

    def __post_init__(self) -> None:
        if self.episodes < 2 or self.shard_size < 1 or self.steps < 1:
            raise ValueError(
                f"episodes must be >= 2, shard_size and steps >= 1; got {self.episodes}, "
                f"{self.shard_size}, {self.steps}"
            )

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
    setting: str, model_file: str | os.PathLike, ranges: WorldRanges, indices: np.ndarray,
    base_seed: int,
) -> Episodes:  # fmt: skip
    """Episodes `indices` of the model's policy in randomised worlds, as the robot saw them
    (observations with the world's noise and bias, the told link lengths)."""
    from masspush.evaluate import model_and_policy
    from masspush.robot import run_estimation
    from masspush.settings import get_setting
    from masspush.target_world import TargetWorldRobot

    setting_ = get_setting(setting)
    predictor, _, policy = model_and_policy(model_file, setting_.name)
    pushes = setting_.env_config().pushes
    robot = TargetWorldRobot(setting_, world=ranges)
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


def _episode_arrays(index: int, seed: int, episode, truth: dict, pushes: int) -> Episodes:
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


def _shard_job(args) -> tuple[int, int]:
    import torch

    from masspush.dataset import shard_path, write_shard

    torch.set_num_threads(1)  # one process per core, as in `masspush.rollout`
    config, model_file, root, j = args
    lo = j * config.shard_size
    indices = np.arange(lo, lo + config.shard_len(j))
    episodes = run_randomised(config.setting, model_file, config.ranges, indices,
                              config.base_seed)  # fmt: skip
    write_shard(shard_path(root, j), episodes)
    return j, len(indices)


def collect_randomised(
    config: RandomiseConfig, out: str | os.PathLike, workers: int | None = None,
    progress: bool = True,
) -> Episodes:  # fmt: skip
    """Collect (or resume collecting) the randomised episodes into `out`; all of them."""
    from masspush.dataset import read_shard, shard_complete, shard_path
    from masspush.evaluate import resolve_model

    root = Path(out)
    root.mkdir(parents=True, exist_ok=True)
    model_file = resolve_model(config.model, config.setting)
    stamp = root / "randomise.json"
    identity = json.loads(json.dumps(config.identity()))  # tuples as lists, as on disk
    if stamp.exists():
        old = json.loads(stamp.read_text())
        if old != identity:
            raise ValueError(
                f"{root} holds episodes of another randomisation ({old}); use another --out"
            )
    stamp.write_text(json.dumps(identity, indent=2) + "\n")

    todo = [
        j for j in range(config.shards)
        if not shard_complete(shard_path(root, j), config.shard_len(j))
    ]  # fmt: skip
    workers = max(1, min(workers or os.cpu_count() or 1, len(todo)))
    done = config.episodes - sum(config.shard_len(j) for j in todo)
    with tqdm(total=config.episodes, initial=done, desc=f"randomised worlds, {config.model}",
              unit="ep", disable=not progress) as bar:  # fmt: skip
        if todo:
            with ProcessPoolExecutor(max_workers=workers) as pool:
                jobs = [pool.submit(_shard_job, (config, model_file, root, j)) for j in todo]
                for job in as_completed(jobs):
                    bar.update(job.result()[1])
    return Episodes.concatenate([read_shard(shard_path(root, j)) for j in range(config.shards)])


def randomise(
    config: RandomiseConfig, out: str | os.PathLike, workers: int | None = None,
    ship: bool = False, progress: bool = True,
) -> Path:  # fmt: skip
    """Collect the randomised episodes and fine-tune the model's predictor on them; returns
    the fine-tuned predictor's file (shipped as `SHIPPED_NAME` beside the model if `ship`)."""
    from masspush.evaluate import SHIPPED_DIR, resolve_model
    from masspush.predictor import load_model, train_predictor
    from masspush.train import FINETUNE

    model_file = resolve_model(config.model, config.setting)
    shipped = SHIPPED_DIR / config.setting / f"{SHIPPED_NAME}.pt"
    if ship and (config.model != "tp+" or Path(model_file).parent != shipped.parent):
        raise ValueError(
            f"--ship ships the shipped tp+ tuned as {SHIPPED_NAME} (its policy file sits "
            f"beside it); got --model {config.model}"
        )
    episodes = collect_randomised(config, out, workers, progress)
    model, meta = load_model(model_file, config.setting)
    run_dir = Path(out) / "predictor"
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
    shutil.copyfile(trained, shipped)
    return shipped
