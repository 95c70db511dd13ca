"""The LSTM predictor: push/observation history -> mass distribution, as the authors built it.

Architecture (shared/notes/paper-details.md):
    step input x_t = (a_t, q_{t+1}, lengths) -> FC 128 + ReLU -> LSTM 64 -> FC n -> softmax,
    initial LSTM state (h_0, c_0) = (ReLU(FC 64 (q_0')), ReLU(FC 64 (q_0'))),
    q_0' = (q_0, lengths); loss: squared error averaged over all K step outputs.
Inputs are normalised with the training set's mean and standard deviation (stored in the
model). Training: the paper's plain SGD (batch 16, lr 0.1 halved three times over four
equal phases) by default, or Adam with larger batches (the faster option, measured in
docs/notebook).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from masspush.config import MismatchError, check_match
from masspush.data.rollout import Episodes

MODEL_FORMAT = "masspush-predictor"
MODEL_VERSION = 1
"""A file holding one predictor."""
ENSEMBLE_VERSION = 2
"""A file holding a `PredictorEnsemble` (a masspush that reads only version 1 refuses it by
its version, with a clear message, instead of failing on its weights)."""


class ModelMismatchError(MismatchError):
    """A model file used with a setting or pusher it was not trained for."""


FEATURES = ("paper", "relative")
"""How observations enter the network. "paper": as observed, (x, y, yaw, joint angles) on
the table. "relative": each rest pose in the frame of the one before it (the root's motion
dx, dy turned into the previous root frame, the yaw change wrapped to [-pi, pi), and the
joint angles before and after), which does not change when the chain stands elsewhere on
the table or faces another way; q_0 then contributes only its joint angles."""


def step_inputs(episodes: Episodes, features: str = "paper") -> tuple[np.ndarray, np.ndarray]:
    """(q0 features (E, *), step features (E, K, *)) from recorded episodes."""
    if features not in FEATURES:
        raise ValueError(f"features must be one of {FEATURES}, got {features!r}")
    lengths = episodes.lengths.astype(np.float32)
    obs = episodes.observations.astype(np.float64)
    k = episodes.actions.shape[1]
    per_step_lengths = np.repeat(lengths[:, None, :], k, axis=1)
    if features == "paper":
        q0 = np.concatenate([obs[:, 0], lengths], axis=1)
        steps = np.concatenate([episodes.actions, obs[:, 1:], per_step_lengths], axis=2)
    else:
        before, after = obs[:, :-1], obs[:, 1:]
        yaw = before[..., 2]
        dx, dy = after[..., 0] - before[..., 0], after[..., 1] - before[..., 1]
        c, s = np.cos(yaw), np.sin(yaw)
        motion = np.stack(
            [
                c * dx + s * dy,
                -s * dx + c * dy,
                (after[..., 2] - yaw + np.pi) % (2 * np.pi) - np.pi,
            ],
            axis=-1,
        )
        q0 = np.concatenate([obs[:, 0, 3:], lengths], axis=1)
        steps = np.concatenate(
            [episodes.actions, motion, before[..., 3:], after[..., 3:], per_step_lengths], axis=2
        )
    return q0.astype(np.float32), np.nan_to_num(steps).astype(np.float32)


class Predictor(nn.Module):
    """What reads an episode's history: its features after each push, and the mass
    distribution they say (`MassPredictor`, or several averaged: `PredictorEnsemble`)."""

    n_links: int
    q0_dim: int
    step_dim: int
    features_kind: str

    def features(self, q0: torch.Tensor, steps: torch.Tensor) -> torch.Tensor:
        """(E, K, F) features after each push (what a Dirichlet head or a classifier reads)."""
        raise NotImplementedError

    def estimate(self, features: torch.Tensor) -> torch.Tensor:
        """(.., n) the mass distribution that features (.., F) say."""
        raise NotImplementedError

    def log_estimate(self, features: torch.Tensor) -> torch.Tensor:
        """(.., n) its logarithm, computed without underflow."""
        raise NotImplementedError

    def forward(self, q0: torch.Tensor, steps: torch.Tensor) -> torch.Tensor:
        """(E, K, n) predicted mass distribution after each push."""
        return self.estimate(self.features(q0, steps))

    @torch.no_grad()
    def predict(self, episodes: Episodes) -> np.ndarray:
        """(E, K, n) predictions for recorded episodes (use [:, -1] for the final estimate)."""
        self.eval()
        q0, steps = step_inputs(episodes, self.features_kind)
        return self(torch.as_tensor(q0), torch.as_tensor(steps)).numpy()


class MassPredictor(Predictor):
    """The paper's predictor, with input normalisation built in; with a `width`, the same
    layout wider and deeper (every layer `width` wide, two LSTM layers, a hidden layer
    before the input and the output): the paper's size stops at what 128k episodes teach
    it, a wider one gains with more (docs/notebook/2026-12-01-arm-speed.md)."""

    def __init__(
        self, n_links: int, q0_dim: int, step_dim: int, features: str = "paper",
        width: int | None = None,
    ):  # fmt: skip
        super().__init__()
        self.n_links, self.q0_dim, self.step_dim = n_links, q0_dim, step_dim
        self.features_kind, self.width = features, width
        # Made in this order whatever the width: the weights' order is the model's
        # fingerprint (`predictor_digest`), which the shipped Dirichlet heads record.
        if width is None:  # the paper's: FC 128, LSTM 64 [paper-details]
            self.layers, self.hidden = 1, 64
            self.embed: nn.Module = nn.Linear(step_dim, 128)
            self.lstm = nn.LSTM(128, 64, batch_first=True)
        else:
            self.layers, self.hidden = 2, width
            self.embed = nn.Sequential(
                nn.Linear(step_dim, width), nn.ReLU(), nn.Linear(width, width)
            )
            self.lstm = nn.LSTM(width, width, num_layers=2, batch_first=True)
        self.init_h = nn.Linear(q0_dim, self.layers * self.hidden)
        self.init_c = nn.Linear(q0_dim, self.layers * self.hidden)
        self.head: nn.Module = (
            nn.Linear(64, n_links)
            if width is None
            else nn.Sequential(nn.Linear(width, width), nn.ReLU(), nn.Linear(width, n_links))
        )
        for name, dim in (("q0", q0_dim), ("step", step_dim)):
            self.register_buffer(f"{name}_mean", torch.zeros(dim))
            self.register_buffer(f"{name}_std", torch.ones(dim))

    def set_normaliser(self, q0: np.ndarray, steps: np.ndarray) -> None:
        flat = steps.reshape(-1, steps.shape[-1])
        for name, x in (("q0", q0), ("step", flat)):
            getattr(self, f"{name}_mean").copy_(torch.as_tensor(x.mean(0)))
            getattr(self, f"{name}_std").copy_(torch.as_tensor(np.maximum(x.std(0), 1e-6)))

    def features(self, q0: torch.Tensor, steps: torch.Tensor) -> torch.Tensor:
        """(E, K, 64) LSTM outputs (E, K, width with a width): the predictor's features after
        each push."""
        q0 = (q0 - self.q0_mean) / self.q0_std
        steps = (steps - self.step_mean) / self.step_std

        def state(layer: nn.Linear) -> torch.Tensor:  # (layers, E, hidden), as nn.LSTM takes
            x = torch.relu(layer(q0)).view(len(q0), self.layers, self.hidden)
            return x.transpose(0, 1).contiguous()

        out, _ = self.lstm(torch.relu(self.embed(steps)), (state(self.init_h), state(self.init_c)))
        return out

    def estimate(self, features: torch.Tensor) -> torch.Tensor:
        return torch.softmax(self.head(features), dim=-1)

    def log_estimate(self, features: torch.Tensor) -> torch.Tensor:
        return torch.log_softmax(self.head(features), dim=-1)


class PredictorEnsemble(Predictor):
    """Several predictors of the same inputs, trained apart, their estimates averaged: each
    stops at about the same held-out error whatever its size or training, and their average
    is below every one (docs/notebook/2026-12-01-arm-speed.md). Its features are the
    members' side by side."""

    def __init__(self, members: list[MassPredictor]):
        super().__init__()
        if len(members) < 2:
            raise ValueError(f"an ensemble needs at least 2 predictors, got {len(members)}")
        shape = {(m.n_links, m.q0_dim, m.step_dim, m.features_kind, m.width) for m in members}
        if len(shape) > 1:
            raise ValueError(
                f"an ensemble's predictors must read the same inputs at one width, got {shape}"
            )
        ((self.n_links, self.q0_dim, self.step_dim, self.features_kind, self.width),) = shape
        self.members = nn.ModuleList(members)

    def features(self, q0: torch.Tensor, steps: torch.Tensor) -> torch.Tensor:
        return torch.cat([m.features(q0, steps) for m in self.members], dim=-1)

    def _parts(self, features: torch.Tensor) -> tuple[torch.Tensor, ...]:
        return features.chunk(len(self.members), dim=-1)

    def estimate(self, features: torch.Tensor) -> torch.Tensor:
        parts = zip(self.members, self._parts(features), strict=True)
        return torch.stack([m.estimate(x) for m, x in parts]).mean(0)

    def log_estimate(self, features: torch.Tensor) -> torch.Tensor:
        parts = zip(self.members, self._parts(features), strict=True)
        logs = torch.stack([m.log_estimate(x) for m, x in parts])
        return torch.logsumexp(logs, dim=0) - math.log(len(self.members))


LOSSES = {"mse": torch.square, "l1": torch.abs}
"""The training losses by name, applied to each output's error and averaged."""


@dataclass(frozen=True)
class TrainConfig:
    """How to train a predictor; the defaults are the paper's [code]."""

    optimizer: str = "sgd"
    """"sgd" (the paper's) or "adam" (the faster option)."""
    steps: int = 500_000
    """Gradient steps [paper: 500k]."""
    batch_size: int = 16
    """Episodes per step [paper: 16]."""
    lr: float = 0.1
    """Initial learning rate [paper: 0.1], halved at 1/4, 1/2 and 3/4 of training."""
    features: str = "paper"
    """Input features, one of FEATURES ("paper": as observed)."""
    validation_fraction: float = 0.05
    """Share of episodes held out to report validation error."""
    eval_every: int = 5_000
    """Steps between validation measurements."""
    checkpoint_every: int = 10_000
    """Steps between checkpoints (a killed run resumes from the last)."""
    seed: int = 0
    """Seed of the initial weights, the validation split and the batches."""
    loss: str = "mse"
    """"mse" (the paper's: squared error, whose best estimate is the posterior mean) or "l1"
    (absolute error, whose best estimate is the posterior median: the paper's percentage
    error is the batch's mean absolute error, scaled), over all K step outputs."""
    width: int | None = None
    """The network's width: unset, the paper's (FC 128, LSTM 64); N, every layer N wide and
    two LSTM layers (`MassPredictor`), which learns more from a few hundred thousand
    episodes."""

    def __post_init__(self) -> None:
        if self.optimizer not in ("sgd", "adam"):
            raise ValueError(f"optimizer must be 'sgd' or 'adam', got {self.optimizer!r}")
        if self.loss not in LOSSES:
            raise ValueError(f"loss must be one of {list(LOSSES)}, got {self.loss!r}")
        for name in ("steps", "batch_size", "eval_every", "checkpoint_every"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.width is not None and not 8 <= self.width <= 1024:
            raise ValueError(f"width must be in 8..1024 (or unset: the paper's), got {self.width}")
        if not 0 < self.lr < 10:
            raise ValueError(f"lr must be in (0, 10), got {self.lr}")
        if not 0 <= self.validation_fraction < 0.5:
            raise ValueError(
                f"validation_fraction must be in [0, 0.5), got {self.validation_fraction}"
            )

    def lr_at(self, step: int) -> float:
        return self.lr * 0.5 ** min(3, (4 * step) // self.steps)


ADDED_TRAIN_FIELDS = {"loss": "mse", "width": None}
"""TrainConfig fields added after runs were made, with the value every run before them used:
a recorded config leaves them out at that value, so an old run still resumes (and one made
otherwise does not pass for it)."""


def recorded_config(config: TrainConfig) -> dict[str, Any]:
    """`config` as runs record it: without the fields added since, where at their old value."""
    recorded = asdict(config)
    for name, value in ADDED_TRAIN_FIELDS.items():
        if recorded[name] == value:
            del recorded[name]
    return recorded


FAST = TrainConfig(optimizer="adam", steps=20_000, batch_size=256, lr=3e-3)
"""The faster option: Adam, 256 episodes a step, 20k steps (see docs/notebook)."""


@dataclass(frozen=True)
class PredictorRun:
    """`masspush train-predictor`: the LSTM predictor on a dataset from `masspush collect`."""

    setting: str
    """The dataset's named setting (checked against the dataset)."""
    data: str
    """Dataset directory."""
    out: str | None = None
    """Run directory; a rerun resumes it (default: runs/predictor-<setting>-<episodes>)."""
    episodes: int | None = None
    """Train on the first this many episodes (default: all)."""
    fast: bool = False
    """Start from the fast option (`FAST`: Adam, batch 256, 20k steps) instead of the paper's."""

    def __post_init__(self) -> None:
        if self.episodes is not None and (not isinstance(self.episodes, int) or self.episodes < 2):
            raise ValueError(f"episodes must be an integer >= 2, got {self.episodes!r}")


BATCH_BYTES_PER_PUSH = 10_000
"""Training memory per episode of a batch and push, bytes: a batch of 20,000 two-push
episodes took 400 MB above the model's, one of 100,000 took 1.6 GB (forward, backward and
optimiser step on this machine's CPU build) [ours, measured]."""


def check_batch_memory(
    batch_size: int, pushes: int, bytes_per_push: float = BATCH_BYTES_PER_PUSH,
    what: str | None = None,
) -> None:  # fmt: skip
    """Refuse, before any work, a batch whose training step would not fit in memory: a
    batch of `batch_size` items of `pushes` pushes each, `what` they are (default:
    "{pushes}-push episodes")."""
    need = batch_size * pushes * bytes_per_push
    have = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    if need > have // 2:
        raise ValueError(
            f"batch_size {batch_size:,}: a step on {what or f'{pushes}-push episodes'} needs "
            f"about {need / 2**30:.1f} GiB, more than half of this machine's "
            f"{have / 2**30:.0f} GiB"
        )


def train_on_dataset(
    run: PredictorRun, config: TrainConfig, progress: bool = True
) -> tuple[Path, dict[str, Any]]:
    """Train a predictor on a dataset; returns the model file and the training summary."""
    from masspush.data.dataset import code_version, load_dataset, read_manifest

    manifest = read_manifest(run.data)  # checked before the episodes are loaded
    if manifest.setting["name"] != run.setting:
        raise ValueError(
            f"{run.data} holds setting {manifest.setting['name']!r}, not {run.setting!r}"
        )
    check_batch_memory(config.batch_size, manifest.pushes)
    manifest, episodes = load_dataset(run.data, limit=run.episodes)
    meta = {
        "setting": manifest.setting,
        "pusher": manifest.pusher,
        "policy": manifest.policy,
        "dataset": str(run.data),
        "dataset_episodes": len(episodes),
        "code_version": code_version(),
    }
    out = Path(run.out or f"runs/predictor-{run.setting}-{len(episodes)}")
    _, summary = train_predictor(episodes, out, config, meta, progress=progress)
    return out / "predictor.pt", summary


def save_model(path: str | os.PathLike, model: Predictor, meta: dict[str, Any]) -> None:
    """A self-describing model file: weights, architecture, and what produced it."""
    arch = {"n_links": model.n_links, "q0_dim": model.q0_dim, "step_dim": model.step_dim,
            "features": model.features_kind}  # fmt: skip
    if model.width is not None:  # left out at the paper's size: files as before
        arch["width"] = model.width
    ensemble = isinstance(model, PredictorEnsemble)
    if ensemble:
        arch["members"] = len(model.members)
    payload = {
        "format": MODEL_FORMAT,
        "version": ENSEMBLE_VERSION if ensemble else MODEL_VERSION,
        "arch": arch,
        "state_dict": model.state_dict(),
        "meta": meta,
    }
    tmp = Path(str(path) + ".tmp")
    torch.save(payload, tmp)
    os.replace(tmp, path)


def read_torch_file(path: str | os.PathLike, what: str) -> Any:
    """A masspush file saved with torch (tensors and plain data only), or a ValueError that
    names the file: missing, a directory, or not such a file at all (garbage, truncated)."""
    if Path(path).is_dir():
        raise ValueError(f"{path} is a directory, not a {what} file")
    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise ValueError(f"no {what} file at {path}") from None
    except Exception as err:  # torch raises many kinds for a file that is not its own
        raise ValueError(f"{path} is not a readable {what} file ({type(err).__name__})") from None


def load_model(
    path: str | os.PathLike, setting: str | None = None, pusher: str | None = None,
    allow_mismatch: bool = False, n_links: int | None = None,
) -> tuple[Predictor, dict[str, Any]]:  # fmt: skip
    """Load a predictor (or an ensemble); refuse it for another setting or pusher than it
    was trained for (unless `allow_mismatch`), and always for another number of links
    (`n_links`)."""
    payload = read_torch_file(path, "model")
    if not isinstance(payload, dict) or payload.get("format") != MODEL_FORMAT:
        raise ValueError(f"{path} is not a masspush predictor")
    if payload.get("version") not in (MODEL_VERSION, ENSEMBLE_VERSION):
        raise ValueError(
            f"{path} has model format version {payload.get('version')}, "
            f"this masspush reads {MODEL_VERSION} and {ENSEMBLE_VERSION}"
        )
    meta = payload["meta"]
    trained = meta.get("setting", {})
    if setting is not None and trained.get("name") != setting and not allow_mismatch:
        raise ModelMismatchError(
            f"{path} was trained for setting {trained.get('name')!r}, not {setting!r}; use a "
            "model trained for this setting (or --allow-mismatch)"
        )
    if pusher is not None and meta.get("pusher") != pusher and not allow_mismatch:
        raise ModelMismatchError(
            f"{path} was trained with the {meta.get('pusher')!r} pusher, not {pusher!r} "
            "(--allow-mismatch to use it anyway)"
        )
    if n_links is not None:
        check_match("n_links", str(path), trained.get("n_links"), n_links, allowable=False)
    arch = dict(payload["arch"])
    members = arch.pop("members", 1)
    model: Predictor = (
        PredictorEnsemble([MassPredictor(**arch) for _ in range(members)])
        if members > 1
        else MassPredictor(**arch)
    )
    model.load_state_dict(payload["state_dict"])
    model.eval()
    return model, meta


def predictor_digest(model: Predictor) -> str:
    """A fingerprint of the predictor's weights and normalisation (sha256, hex): what a
    Dirichlet head fitted on its features records, so that a head outlives no retraining."""
    digest = hashlib.sha256()
    for name, tensor in model.state_dict().items():
        digest.update(name.encode())
        digest.update(tensor.detach().cpu().contiguous().numpy().tobytes())
    return digest.hexdigest()


def validation_split(n_episodes: int, config: TrainConfig) -> tuple[np.ndarray, np.ndarray]:
    """(held-out, training) indices of a dataset's usable episodes, as `train_predictor`
    splits them: a predictor's validation error is measured on the held-out ones."""
    order = np.random.default_rng(config.seed).permutation(n_episodes)
    n_val = round(config.validation_fraction * n_episodes)
    return order[:n_val], order[n_val:]


def train_predictor(
    episodes: Episodes,
    run_dir: str | os.PathLike,
    config: TrainConfig = TrainConfig(),
    meta: dict[str, Any] | None = None,
    progress: bool = True,
    init: MassPredictor | None = None,
) -> tuple[MassPredictor, dict[str, Any]]:
    """Train (or resume training) in `run_dir`; returns the model and a summary.

    `run_dir` holds config.json, checkpoint.pt (model, optimiser, step, RNG state: a killed
    run resumes exactly where it stopped), tensorboard/ and, at the end, predictor.pt.
    `init` starts from another predictor's weights (fine-tuning) instead of from scratch.
    """
    from torch.utils.tensorboard import SummaryWriter

    run = Path(run_dir)
    run.mkdir(parents=True, exist_ok=True)
    good = episodes.select(episodes.ok)
    if len(good) < 2:
        raise ValueError(f"only {len(good)} usable episodes; collect more data")
    q0, steps = step_inputs(good, config.features)
    target = good.mass_distribution.astype(np.float32)
    val_idx, train_idx = validation_split(len(good), config)

    if init is not None and not isinstance(init, MassPredictor):
        raise ValueError("fine-tuning starts from one predictor, not an ensemble")
    if init is not None and init.width != config.width:
        raise ValueError(
            f"fine-tuning keeps the network's width ({init.width}), not {config.width}"
        )
    torch.manual_seed(config.seed)
    n_links = target.shape[1]
    model = MassPredictor(n_links, q0.shape[1], steps.shape[2], config.features, config.width)
    if init is not None:
        model.load_state_dict(init.state_dict())
    else:
        model.set_normaliser(q0[train_idx], steps[train_idx])
    optim_cls = torch.optim.SGD if config.optimizer == "sgd" else torch.optim.Adam
    optimiser = optim_cls(model.parameters(), lr=config.lr)
    rng = np.random.default_rng(config.seed + 1)
    step, history = 0, []
    best: dict[str, Any] = {"error": math.inf, "step": 0, "state": None}
    ckpt = run / "checkpoint.pt"
    if ckpt.exists():
        state = torch.load(ckpt, map_location="cpu", weights_only=False)
        if state["config"] != recorded_config(config):
            raise ValueError(f"{run} holds a run with another config; use another run directory")
        model.load_state_dict(state["model"])
        optimiser.load_state_dict(state["optimiser"])
        rng.bit_generator.state = state["rng"]
        torch.set_rng_state(state["torch_rng"])
        step, history = state["step"], state["history"]
        best = state["best"]
    (run / "config.json").write_text(
        json.dumps({"train": asdict(config), "meta": meta or {}, "episodes": len(good)}, indent=2)
    )

    tensors = {
        name: torch.as_tensor(x) for name, x in (("q0", q0), ("steps", steps), ("target", target))
    }
    writer = SummaryWriter(str(run / "tensorboard"))
    started, start_step = time.perf_counter(), step
    bar = tqdm(
        total=config.steps,
        initial=step,
        desc="training predictor",
        unit="step",
        disable=not progress,
    )
    model.train()
    while step < config.steps:
        for group in optimiser.param_groups:
            group["lr"] = config.lr_at(step)
        batch = torch.as_tensor(rng.choice(train_idx, size=config.batch_size))
        pred = model(tensors["q0"][batch], tensors["steps"][batch])
        loss = LOSSES[config.loss](pred - tensors["target"][batch, None, :]).mean()
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        step += 1
        bar.update(1)
        if step % 100 == 0:
            writer.add_scalar(f"losses/train_{config.loss}", loss.item(), step)
            writer.add_scalar("charts/learning_rate", config.lr_at(step), step)
        if step % config.eval_every == 0 or step == config.steps:
            val = _validation(model, tensors, val_idx)
            history.append({"step": step, **val})
            # Keep the weights that did best on held-out episodes: longer training overfits.
            error = val.get("percentage_error", math.inf)
            if error < best["error"] or best["state"] is None:
                state_dict = model.state_dict()
                best = {
                    "error": error,
                    "step": step,
                    "state": {k: v.clone() for k, v in state_dict.items()},
                }
            for key, value in val.items():
                writer.add_scalar(f"validation/{key}", value, step)
            bar.set_postfix(val_pct=f"{val.get('percentage_error', float('nan')):.2f}")
            model.train()
        if step % config.checkpoint_every == 0 or step == config.steps:
            torch.save(
                {
                    "model": model.state_dict(),
                    "optimiser": optimiser.state_dict(),
                    "rng": rng.bit_generator.state,
                    "torch_rng": torch.get_rng_state(),
                    "step": step,
                    "history": history,
                    "config": recorded_config(config),
                    "best": best,
                },
                str(ckpt) + ".tmp",
            )
            os.replace(str(ckpt) + ".tmp", ckpt)
    bar.close()
    writer.close()
    elapsed = time.perf_counter() - started
    if best["state"] is not None:
        model.load_state_dict(best["state"])
    summary = {
        "steps": step,
        "best_step": best["step"],
        "best_validation_error": best["error"],
        "episodes": len(good),
        "train_episodes": len(train_idx),
        "validation_episodes": len(val_idx),
        "history": history,
        "samples_per_s": (step - start_step) * config.batch_size / elapsed if elapsed else math.nan,
        "train_config": asdict(config),
    }
    save_model(run / "predictor.pt", model, {**(meta or {}), "training": summary})
    return model, summary


def train_ensemble(
    episodes: Episodes,
    run_dir: str | os.PathLike,
    config: TrainConfig,
    members: int,
    meta: dict[str, Any] | None = None,
    progress: bool = True,
    init: MassPredictor | None = None,
) -> tuple[PredictorEnsemble, dict[str, Any]]:
    """Train `members` predictors alike but for their seeds (config.seed + k: their initial
    weights unless `init`, their batches and their held-out episodes), each in
    `run_dir`/member-k (resumable as `train_predictor`), and save their average as
    `run_dir`/predictor.pt."""
    if members < 2:
        raise ValueError(f"an ensemble needs at least 2 predictors, got {members}")
    run, trained, summaries = Path(run_dir), [], []
    for k in range(members):
        if progress:
            print(f"ensemble member {k + 1} of {members}", flush=True)
        member, summary = train_predictor(
            episodes, run / f"member-{k}", replace(config, seed=config.seed + k), meta,
            progress, init,
        )  # fmt: skip
        trained.append(member)
        summaries.append({key: v for key, v in summary.items() if key != "history"})
    ensemble = PredictorEnsemble(trained)
    summary = {"members": summaries, "train_config": asdict(config)}
    save_model(run / "predictor.pt", ensemble, {**(meta or {}), "training": summary})
    return ensemble, summary


def _validation(model: MassPredictor, tensors: dict, idx: np.ndarray) -> dict[str, float]:
    from masspush.metrics import all_metrics

    if len(idx) == 0:
        return {}
    model.eval()
    with torch.no_grad():
        index = torch.as_tensor(idx)
        pred = model(tensors["q0"][index], tensors["steps"][index])[:, -1].numpy()
    metrics = all_metrics(pred, tensors["target"][index].numpy())
    return {k: v for k, v in metrics.items() if not k.startswith("constant_floor_")}
