"""Adapting a simulation-trained predictor to real episodes, as the paper did with its UR10.

The paper could not weigh its real chains' links one by one, so it labelled real episodes
with their class (one of five known mass pairs) and trained a small classifier,
64-ReLU-32-ReLU-C with cross-entropy, on the predictor's features (its LSTM output after the
last push) [paper, Sec. 4.3; paper-details.md]. We train the same classifier, by default on
the predictor's final estimate (the log of the mass distribution) instead: on 34 simulated
episodes of three classes, 4-fold cross-validated accuracy was 94 % from the estimate and
44 % from the 64 LSTM outputs, where a few dozen episodes let the classifier fit the chain's
pose instead of its masses (`features="lstm"` keeps the paper's choice). Episodes made of
several runs of a policy (`segment`) give the classifier a sample per run (`runs="each"`),
and there the LSTM outputs of the learned policy's runs sorted best (docs/notebook,
"Reading each run on its own"). `cross_validate` reports stratified k-fold accuracy; where
the true masses are known, `finetune_predictor` fine-tunes the predictor itself.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from torch import nn

from masspush.data.rollout import Episodes, empty_episodes
from masspush.learn.predictor import Predictor, read_torch_file, step_inputs

if TYPE_CHECKING:
    from masspush.data.recording import Recording

PAPER_CLASSES: dict[str, tuple[float, float]] = {
    "0.160-0.160": (0.16, 0.16),
    "0.064-0.192": (0.064, 0.192),
    "0.064-0.256": (0.064, 0.256),
    "0.192-0.064": (0.192, 0.064),
    "0.256-0.064": (0.256, 0.064),
}
"""The real experiment's five mass pairs, kg [paper-details.md, "Real robot"]."""
CLASSIFIER_FORMAT, CLASSIFIER_VERSION = "masspush-classifier", 1
FEATURE_KINDS = ("estimate", "lstm")
RUN_READINGS = ("each", "average")
PER_POSE, PER_PUSH = ("observations", "configs"), ("actions", "executed", "failure")
"""`Episodes` fields with one entry per rest pose (K + 1) and per push (K)."""


@dataclass(frozen=True)
class ClassifierConfig:
    """Training of the classifier on predictor features."""

    hidden: tuple[int, ...] = (64, 32)
    """Hidden ReLU layers [paper: 64, 32]."""
    epochs: int = 400
    """Full-batch Adam steps (a few hundred episodes at most) [ours]."""
    lr: float = 3e-3
    weight_decay: float = 1e-3
    """L2 penalty: tens of episodes per class overfit quickly [ours]."""
    folds: int = 5
    """Cross-validation folds (stratified) [ours]."""
    features: str = "estimate"
    """"estimate": log of the predictor's final estimate [ours]; "lstm": its LSTM output
    after the last push [paper]."""
    segment: int = 0
    """0: the predictor reads each episode whole. P > 0: an episode is consecutive runs of
    P pushes (the policy run again from where it stopped, `masspush.real.robot.run_segments`);
    the predictor reads each run on its own (`runs` says how the runs are combined)."""
    runs: str = "each"
    """With `segment`: "each": the classifier reads every run on its own (trained on every run
    of the training episodes) and an episode's class is the one with the highest sum of its
    runs' log-probabilities, as for independent looks at one object (in a lab the runs'
    estimates scatter independently: the std of 16 runs' mean is a single run's over 4)
    [ours]; "average": the classifier reads the features averaged over the runs [ours]."""
    seed: int = 0
    """Seed of the folds and the classifier's initial weights."""

    def __post_init__(self) -> None:
        if not self.hidden or min(self.hidden) < 1:
            raise ValueError(f"hidden must be positive layer sizes, got {self.hidden}")
        if self.epochs < 1 or self.lr <= 0 or self.weight_decay < 0:
            raise ValueError("epochs must be >= 1, lr > 0 and weight_decay >= 0")
        if self.features not in FEATURE_KINDS:
            raise ValueError(f"features must be one of {FEATURE_KINDS}, got {self.features!r}")
        if self.folds < 2:
            raise ValueError(f"folds must be >= 2, got {self.folds}")
        if self.segment < 0:
            raise ValueError(f"segment must be >= 0 pushes, got {self.segment}")
        if self.runs not in RUN_READINGS:
            raise ValueError(f"runs must be one of {RUN_READINGS}, got {self.runs!r}")


class MassClassifier(nn.Module):
    """Predictor features -> class logits, with the features' normalisation built in."""

    def __init__(self, in_dim: int, n_classes: int, hidden: tuple[int, ...] = (64, 32)):
        super().__init__()
        layers: list[nn.Module] = []
        width = in_dim
        for h in hidden:
            layers += [nn.Linear(width, h), nn.ReLU()]
            width = h
        self.net = nn.Sequential(*layers, nn.Linear(width, n_classes))
        self.register_buffer("mean", torch.zeros(in_dim))
        self.register_buffer("std", torch.ones(in_dim))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net((x - self.mean) / self.std)


def segments_of(episodes: Episodes, pushes: int) -> tuple[Episodes, np.ndarray]:
    """Each episode cut into consecutive runs of `pushes` pushes, each starting from the
    rest pose the last one ended in: the runs with at least one push seen, and the episode
    each came from."""
    if pushes < 1:
        raise ValueError(f"a segment needs at least one push, got {pushes}")
    k = episodes.actions.shape[1]
    whole = -(-k // pushes) * pushes
    padded = empty_episodes(len(episodes), whole, episodes.lengths.shape[1])
    for name in PER_POSE + PER_PUSH:
        value = getattr(episodes, name)
        getattr(padded, name)[:, : value.shape[1]] = value
    per_episode = {
        f.name: getattr(episodes, f.name)
        for f in fields(Episodes)
        if f.name not in PER_POSE + PER_PUSH
    }
    parts, owner = [], []
    for start in range(0, whole, pushes):
        part = Episodes(
            **per_episode,
            **{name: getattr(padded, name)[:, start : start + pushes + 1] for name in PER_POSE},
            **{name: getattr(padded, name)[:, start : start + pushes] for name in PER_PUSH},
        )
        keep = part.seen.any(axis=1)
        parts.append(part.select(keep))
        owner.append(np.flatnonzero(keep))
    return Episodes.concatenate(parts), np.concatenate(owner)


def first_pushes(episodes: Episodes, pushes: int) -> Episodes:
    """Each episode as if it had stopped after its first `pushes` pushes (what a lab that
    pushed less would have recorded)."""
    if pushes < 1:
        raise ValueError(f"an episode needs at least one push, got {pushes}")
    return Episodes(
        **{
            f.name: getattr(episodes, f.name)[:, : pushes + (f.name in PER_POSE)]
            if f.name in PER_POSE + PER_PUSH
            else getattr(episodes, f.name)
            for f in fields(Episodes)
        }
    )


def predictor_features(
    predictor: Predictor, episodes: Episodes, kind: str = "estimate", segment: int = 0
) -> np.ndarray:
    """What the classifier sees of each episode, after its last recorded push: the log of
    the predictor's estimate (E, n), or the predictor's LSTM output (E, 64). With `segment`
    P > 0, each run of P pushes is read on its own (`segments_of`) and the estimates (or
    LSTM outputs) are averaged over an episode's runs."""
    if kind not in FEATURE_KINDS:
        raise ValueError(f"features must be one of {FEATURE_KINDS}, got {kind!r}")
    if segment:
        out, owner = run_features(predictor, episodes, kind, segment)
        if kind == "estimate":
            out = np.exp(out)
        total = np.zeros((len(episodes), out.shape[1]))
        np.add.at(total, owner, out)
        mean = total / np.bincount(owner, minlength=len(episodes))[:, None]
        return (np.log(mean) if kind == "estimate" else mean).astype(np.float32)
    q0, steps = step_inputs(episodes, predictor.features_kind)
    last, rows = episodes.last_seen(), []
    with torch.no_grad():
        predictor.eval()
        # In chunks: the LSTM's activations for every push of a large recording at once
        # would take gigabytes, a chunk's a few tens of MB.
        for lo in range(0, max(len(q0), 1), FEATURE_CHUNK):
            part = slice(lo, lo + FEATURE_CHUNK)
            out = predictor.features(torch.as_tensor(q0[part]), torch.as_tensor(steps[part]))
            if kind == "estimate":
                out = predictor.log_estimate(out)
            out = out.numpy()
            rows.append(out[np.arange(len(out)), last[part]])
    return np.concatenate(rows)


def start_pose_features(episodes: Episodes) -> np.ndarray:
    """The control classifier's inputs (E, 3 + n + n - 1): each episode's start pose alone,
    x, y, the cosine and sine of yaw, the joint angles, and the link lengths, before any
    push. Above chance, it shows that which episodes were kept depends on the class (a
    selection effect), not what the pushes said."""
    q0 = episodes.observations[:, 0].astype(np.float64)
    yaw = q0[:, 2:3]
    return np.concatenate(
        [q0[:, :2], np.cos(yaw), np.sin(yaw), q0[:, 3:], episodes.lengths], axis=1
    ).astype(np.float32)


def start_pose_control(
    episodes: Episodes, labels: np.ndarray, n_classes: int, config: ClassifierConfig
) -> dict[str, Any]:
    """The control: `cross_validate` of the same classifier on `start_pose_features` alone
    (one row per episode, whatever `config.segment` says of the pushes)."""
    control = replace(config, segment=0)
    return cross_validate(start_pose_features(episodes), labels, n_classes, control)


FEATURE_CHUNK = 16_384
"""Episodes read by the predictor at once for the classifier's features."""


def run_features(
    predictor: Predictor, episodes: Episodes, kind: str, segment: int
) -> tuple[np.ndarray, np.ndarray]:
    """Each run of `segment` pushes read on its own (`predictor_features` of the run), and the
    episode each run belongs to."""
    parts, owner = segments_of(episodes, segment)
    return predictor_features(predictor, parts, kind), owner


def classifier_inputs(
    predictor: Predictor, episodes: Episodes, config: ClassifierConfig
) -> tuple[np.ndarray, np.ndarray]:
    """The rows the classifier reads and the episode each belongs to: one row per episode,
    or with runs read one by one (`ClassifierConfig.runs`), one per run."""
    if config.segment and config.runs == "each":
        return run_features(predictor, episodes, config.features, config.segment)
    features = predictor_features(predictor, episodes, config.features, config.segment)
    return features, np.arange(len(features))


def episode_log_probs(
    model: MassClassifier, features: np.ndarray, owner: np.ndarray, n_episodes: int
) -> np.ndarray:
    """Each episode's class log-probabilities (E, C): the sum of its rows' (runs')
    log-probabilities, normalised; with one row per episode, the classifier's own."""
    with torch.no_grad():
        rows = torch.log_softmax(model(torch.as_tensor(features, dtype=torch.float32)), -1)
    total = np.zeros((n_episodes, rows.shape[1]))
    np.add.at(total, owner, rows.numpy())
    return total - np.logaddexp.reduce(total, axis=1, keepdims=True)


def fit_classifier(
    features: np.ndarray, labels: np.ndarray, n_classes: int, config: ClassifierConfig
) -> MassClassifier:
    """A classifier trained on all the given episodes."""
    with one_thread():
        torch.manual_seed(config.seed)
        model = MassClassifier(features.shape[1], n_classes, config.hidden)
        model.mean.copy_(torch.as_tensor(features.mean(0)))
        model.std.copy_(torch.as_tensor(np.maximum(features.std(0), 1e-6)))
        x, y = torch.as_tensor(features, dtype=torch.float32), torch.as_tensor(labels)
        optimiser = torch.optim.Adam(
            model.parameters(), config.lr, weight_decay=config.weight_decay
        )
        loss_fn = nn.CrossEntropyLoss()
        model.train()
        for _ in range(config.epochs):
            optimiser.zero_grad()
            loss_fn(model(x), y).backward()
            optimiser.step()
        model.eval()
        return model


@contextmanager
def one_thread() -> Iterator[None]:
    """Torch on one thread for the while: a classifier this small trains ~10x faster so
    when the other cores are busy (13 s against 1.4 s for 400 steps beside a simulation on
    2 cores), where torch's thread pool waits on them."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)


def stratified_folds(labels: np.ndarray, folds: int, seed: int) -> list[np.ndarray]:
    """Test indices of each fold; every class spread evenly over the folds."""
    rng = np.random.default_rng(seed)
    parts: list[list[int]] = [[] for _ in range(folds)]
    for c in np.unique(labels):
        members = rng.permutation(np.flatnonzero(labels == c))
        for i, index in enumerate(members):
            parts[i % folds].append(int(index))
    return [np.array(sorted(p), dtype=np.int64) for p in parts]


def fold_counts(labels: np.ndarray, n_classes: int, folds: int) -> np.ndarray:
    """Episodes per class; ValueError unless every class has one for each of `folds`."""
    counts = np.bincount(labels, minlength=n_classes)
    if counts.min() < folds:
        raise ValueError(
            f"every class needs at least {folds} episodes for {folds}-fold "
            f"cross-validation; counts per class: {counts.tolist()}"
        )
    return counts


def out_of_fold_log_probs(
    features: np.ndarray,
    labels: np.ndarray,
    n_classes: int,
    config: ClassifierConfig,
    owner: np.ndarray | None = None,
) -> np.ndarray:
    """Each episode's class log-probabilities (E, C) from the classifier trained on the
    other folds (stratified, `config.folds`). `labels` has one entry per episode; `features`
    one row per episode, or with `owner` (the episode of each row, from `classifier_inputs`)
    any number: an episode's rows are all trained on or all tested."""
    owner = np.arange(len(labels)) if owner is None else np.asarray(owner)
    if len(owner) != len(features):
        raise ValueError(f"{len(features)} rows of features but {len(owner)} owners")
    fold_counts(labels, n_classes, config.folds)
    out = np.zeros((len(labels), n_classes))
    for test in stratified_folds(labels, config.folds, config.seed):
        train = ~np.isin(owner, test)
        model = fit_classifier(features[train], labels[owner[train]], n_classes, config)
        out[test] = episode_log_probs(model, features[~train], owner[~train], len(labels))[test]
    return out


def cross_validate(
    features: np.ndarray,
    labels: np.ndarray,
    n_classes: int,
    config: ClassifierConfig,
    owner: np.ndarray | None = None,
) -> dict[str, Any]:
    """Stratified k-fold accuracy over episodes, the confusion matrix (rows: truth, columns:
    predicted) and each episode's out-of-fold prediction (`out_of_fold_log_probs`'s
    arguments)."""
    predicted = out_of_fold_log_probs(features, labels, n_classes, config, owner).argmax(1)
    confusion = np.zeros((n_classes, n_classes), np.int64)
    np.add.at(confusion, (labels, predicted), 1)
    counts = np.bincount(labels, minlength=n_classes)
    return {
        "accuracy": float(np.trace(confusion) / confusion.sum()),
        "per_fold": [
            float(np.mean(predicted[test] == labels[test]))
            for test in stratified_folds(labels, config.folds, config.seed)
        ],
        "confusion": confusion.tolist(),
        "predicted": predicted.tolist(),
        "chance": float(counts.max() / counts.sum()),
    }


def save_classifier(
    path: str | os.PathLike,
    model: MassClassifier,
    classes: list[str],
    config: ClassifierConfig,
    meta: dict[str, Any],
) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save(
        {
            "format": CLASSIFIER_FORMAT,
            "version": CLASSIFIER_VERSION,
            "classes": classes,
            "config": asdict(config),
            "in_dim": int(model.mean.shape[0]),
            "state_dict": model.state_dict(),
            "meta": meta,
        },
        path,
    )
    return path


def load_classifier(
    path: str | os.PathLike, setting: str | None = None
) -> tuple[MassClassifier, list[str], dict[str, Any]]:
    """A saved classifier, its class names and metadata; refused for another setting."""
    payload = read_torch_file(path, "classifier")
    if not isinstance(payload, dict) or payload.get("format") != CLASSIFIER_FORMAT:
        raise ValueError(f"{path} is not a masspush classifier")
    meta = payload["meta"]
    if setting is not None and meta.get("setting") != setting:
        raise ValueError(
            f"{path} was trained on features of a {meta.get('setting')!r} predictor, "
            f"not {setting!r}"
        )
    config = ClassifierConfig(**{**payload["config"], "hidden": tuple(payload["config"]["hidden"])})
    model = MassClassifier(payload["in_dim"], len(payload["classes"]), config.hidden)
    model.load_state_dict(payload["state_dict"])
    model.eval()
    return model, list(payload["classes"]), meta


def labelled(recording: Recording) -> tuple[np.ndarray, list[str]]:
    """Integer labels of a recording's episodes and the sorted class names."""
    labels = recording.labels
    missing = [
        e["id"] for e, label in zip(recording.episodes, labels, strict=True) if label is None
    ]
    if missing:
        raise ValueError(
            f"episodes without a label: {missing[:5]}{' ...' if len(missing) > 5 else ''}"
        )
    classes = sorted(set(labels))
    if len(classes) < 2:
        raise ValueError(f"a classifier needs at least two classes, got {classes}")
    return np.array([classes.index(label) for label in labels], np.int64), classes


def finetune_predictor(
    predictor_path: str | os.PathLike, episodes: Episodes, out_dir: str | os.PathLike, **meta
) -> Path:
    """Fine-tune a predictor on episodes with known masses (the recipe's fine-tuning)."""
    from masspush.learn.predictor import load_model, train_predictor
    from masspush.learn.recipe import FINETUNE

    if not np.all(episodes.masses > 0):
        raise ValueError("fine-tuning the predictor needs the true masses of every episode")
    model, old = load_model(predictor_path)
    train_predictor(
        episodes, out_dir, FINETUNE, {**old, **meta, "finetuned_from": str(predictor_path)},
        progress=True, init=model,
    )  # fmt: skip
    return Path(out_dir) / "predictor.pt"
