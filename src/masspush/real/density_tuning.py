"""Tuning the particle filter's push density to a lab with the lab's labelled episodes, and
sorting episodes by the tuned density's class posterior.

A push density (`masspush.learn.push_density`) learns how a simulated chain answers a push;
in a lab the chain answers a little differently (its table, contacts, actuation), and by
more than the 0.05 of share that separates the paper's close classes. The protocol already
needs labelled episodes (five known objects, 30 episodes each) for its classifier; here they
also tune the density: maximise the likelihood of every labelled push under the episode's
true masses, the lab's table friction unknown and marginalised over a grid (uniform, as the
filter's prior), starting from the simulation's weights and held near them by an L2 penalty
on the change (L2-SP [Li, Grandvalet & Davoine, ICML 2018]), so that a hundred episodes
correct the density where the lab differs without forgetting the rest.

With the classes' masses known, an episode is then sorted by Bayes' rule: each class's
likelihood of its pushes under the tuned density, friction marginalised, equal priors
(`class_log_likelihoods`), the same reading as `experiments/sim2real/class_oracle.py` with
the untuned one. `masspush tune-density` cross-validates that (the density tuned on the
other folds' episodes) and saves the density tuned on all of them, with its classes, for
`masspush classify --density` and the filter arm (`sim2real --density`). Measured in the
target world's labs: docs/notebook/2026-12-05-lab-tuned-density.md.
"""

from __future__ import annotations

import copy
import math
import warnings
from dataclasses import asdict, dataclass
from typing import Any, NamedTuple

import numpy as np
import torch

from masspush.bayes.filter import friction_prior
from masspush.bayes.hypotheses import grid_inside
from masspush.config import Range, check_int, check_range
from masspush.data.recording import Recording
from masspush.learn.push_density import PushDensity, push_inputs, push_outputs
from masspush.real.classifier import fold_counts, one_thread, stratified_folds

ROWS_PER_PASS = 20_000
"""Pushes x frictions the network evaluates at once."""

LONGER_THAN_CALIBRATION = 1.25
"""Episodes longer than this times the calibration's mean pushes per episode are sorted
with a `CalibrationWarning`. Lab 6's 32-push runs (600 chains) sorted 87.8 % with a density
tuned on a 16-push run, 89.2 % tuned on a 32-push run of other chains and 90.2 % on three
(exact McNemar p = 0.024 against the 16-push calibration); lab 5's 92.0 % either way: the
later pushes meet the chain elsewhere on the table, pushed otherwise
(docs/notebook/2026-12-06-calibration-runs.md) [ours, measured]. The margin leaves room for
calibration episodes that lost the chain early."""


class CalibrationWarning(UserWarning):
    """A tuned density sorting episodes longer than those it was tuned on."""


@dataclass(frozen=True)
class TuneConfig:
    """`masspush tune-density`: the push density tuned to a lab's labelled episodes [ours;
    chosen on one lab's calibration recording, docs/notebook/2026-12-05-lab-tuned-density.md]."""

    steps: int = 100
    """Full-batch Adam steps over every labelled push (on lab 5's calibration recording 100
    sorted the held-out folds better than 20 and as well as 300)."""
    lr: float = 1e-4
    """Adam's step size: a twentieth of the density's own training's peak."""
    anchor: float = 1.0
    """Weight of the L2 penalty on the change of the weights (sum of squares), against the
    mean negative log-likelihood per push."""
    frictions: int = 8
    """Table frictions the lab's unknown one is marginalised over in tuning (evenly inside
    the density's range, ends left out: `masspush.bayes.hypotheses.grid_inside`)."""
    sort_range: Range = (0.3, 1.2)
    """The table frictions marginalised over in sorting: wider than the density's training
    range (the paper's 0.5-1.0), the density extrapolating, so that a table at or beyond its
    edge, or one that drifted there since the calibration, is still read. Lab 9, its table
    at 0.54 as the density reads it, sorted 90.7 % of 75 chains on a day its table was 22 %
    more slippery, against 85.3 % over the density's range, and as well on four other days;
    tuning over this range instead sorted random pushes 1-7 points worse
    (docs/notebook/2026-12-07-wider-friction.md)."""
    sort_frictions: int = 17
    """How many frictions inside `sort_range`: every 0.05 from 0.35 to 1.15."""
    folds: int = 5
    """Cross-validation folds (stratified) of the reported accuracy; 0: tune on all and
    report none."""
    seed: int = 0
    """Seed of the folds' shuffle (the tuning itself draws nothing)."""

    def __post_init__(self) -> None:
        check_int("steps", self.steps, 1)
        check_int("frictions", self.frictions, 1)
        check_int("sort_frictions", self.sort_frictions, 1)
        check_range("sort_range", self.sort_range)
        lo, hi = (float(v) for v in self.sort_range)
        if not 0 < lo < hi:
            raise ValueError(f"sort_range must be 0 < low < high, got {self.sort_range!r}")
        check_int("seed", self.seed, 0)
        check_int("folds", self.folds, 0)
        if self.folds == 1:
            raise ValueError("folds must be 0 (no cross-validation) or at least 2")
        if not (math.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"lr must be a positive finite number, got {self.lr!r}")
        if not (math.isfinite(self.anchor) and self.anchor >= 0):
            raise ValueError(f"anchor must be a finite number >= 0, got {self.anchor!r}")


class LabelledPush(NamedTuple):
    """One episode's pushes as the density reads them: inputs without the masses and
    friction filled in, and outcomes."""

    starts: np.ndarray
    """(K, d) observed rest poses before each push."""
    actions: np.ndarray
    """(K, 2) the pushes as commanded."""
    outputs: np.ndarray
    """(K, out) `push_outputs`: the observed rest pose after each, in the frame of the one
    before."""
    lengths: np.ndarray


def labelled_pushes(recording: Recording) -> list[LabelledPush]:
    """Every episode's observed pushes (those with a rest pose after them)."""
    out = []
    for episode in recording.episodes:
        obs = np.asarray(episode["observations"], float)
        actions = np.asarray(episode["actions"], float).reshape(-1, 2)
        k = min(len(actions), len(obs) - 1)
        out.append(LabelledPush(obs[:k], actions[:k], push_outputs(obs[:k], obs[1 : k + 1]),
                                np.asarray(episode["lengths"], float)))  # fmt: skip
    return out


def first_pushes(pushes: list[LabelledPush], count: int | None) -> list[LabelledPush]:
    """Each episode's first `count` pushes (all with None)."""
    return [LabelledPush(*(v[:count] for v in p[:3]), p.lengths) for p in pushes]


def class_masses(recording: Recording, classes: list[str]) -> np.ndarray:
    """(C, n) each class's link masses, as its labelled episodes give them (all alike)."""
    rows = []
    for name in classes:
        masses = {tuple(e["masses"]) for e in recording.episodes
                  if e.get("label") == name and e.get("masses") is not None}  # fmt: skip
        if len(masses) != 1:
            raise ValueError(
                f"class {name!r}: its episodes must all give the same masses, got "
                f"{sorted(masses) or 'none'}"
            )
        rows.append(next(iter(masses)))
    return np.array(rows, float)


def friction_grid(
    density: PushDensity, count: int, friction_range: Range | None = None
) -> np.ndarray:
    """`count` frictions evenly inside `friction_range` (default: the range the density's
    filter would guess)."""
    if friction_range is None:
        friction_range = friction_prior(density, tuple(density.meta["friction_range"]))
    return grid_inside(*friction_range, count)


def sorting_grid(density: PushDensity) -> np.ndarray:
    """The frictions a tuned density's sorting marginalises over: its `sort_range`, or the
    grid it was tuned over where it was tuned before that was kept."""
    config = density.meta["tuned"]["config"]
    if "sort_range" not in config:
        return friction_grid(density, config["frictions"])
    return friction_grid(density, config["sort_frictions"], config["sort_range"])


def _rows(
    density: PushDensity, pushes: list[LabelledPush], episodes: np.ndarray, masses: np.ndarray,
    frictions: np.ndarray,
) -> tuple[torch.Tensor, torch.Tensor, np.ndarray]:  # fmt: skip
    """Standardised inputs and outputs of `episodes`' pushes, each under `masses[i]` (the
    i-th episode's hypothesis) at every friction, and each row's (i, friction index)."""
    xs, ys, where = [], [], []
    for i, e in enumerate(episodes):
        p = pushes[e]
        k, f = len(p.actions), len(frictions)
        if k == 0:
            continue
        xs.append(push_inputs(np.tile(p.starts, (f, 1)), np.tile(p.actions, (f, 1)),
                              np.repeat(masses[i][None], k * f, 0), np.repeat(frictions, k),
                              p.lengths, density.placed))  # fmt: skip
        ys.append(np.tile(p.outputs, (f, 1)))
        where.append(np.column_stack([np.full(k * f, i), np.repeat(np.arange(f), k)]))
    if not xs:
        return torch.zeros(0), torch.zeros(0), np.zeros((0, 2), np.int64)
    return density._x(np.concatenate(xs)), density._y(np.concatenate(ys)), np.concatenate(where)


def _marginal(
    density: PushDensity, x: torch.Tensor, y: torch.Tensor, where: np.ndarray, n: int, f: int
) -> torch.Tensor:
    """(n,) each hypothesis's log-likelihood of its pushes, friction marginalised."""
    total = torch.zeros(n * f, dtype=torch.float64)
    for i in range(0, len(x), ROWS_PER_PASS):
        part = slice(i, i + ROWS_PER_PASS)
        lp = density.dist(x[part]).log_prob(y[part]).double()
        index = torch.as_tensor(where[part, 0] * f + where[part, 1])
        total = total.index_add(0, index, lp)
    return torch.logsumexp(total.view(n, f), dim=1) - math.log(f)


@torch.no_grad()
def joint_log_likelihoods(
    density: PushDensity, pushes: list[LabelledPush], masses: np.ndarray, frictions: np.ndarray
) -> np.ndarray:
    """(E, C, F) each episode's log-likelihood of its pushes under each class's `masses`
    (C, n) at each of `frictions`."""
    e, f = len(pushes), len(frictions)
    out = np.zeros((e, len(masses), f))
    for j in range(len(masses)):
        x, y, where = _rows(density, pushes, np.arange(e), np.repeat(masses[j][None], e, 0),
                            frictions)  # fmt: skip
        for i in range(0, len(x), ROWS_PER_PASS):
            part = slice(i, i + ROWS_PER_PASS)
            lp = density.dist(x[part]).log_prob(y[part]).double().numpy()
            np.add.at(out[:, j], (where[part, 0], where[part, 1]), lp)
    return out


def class_log_likelihoods(
    density: PushDensity, pushes: list[LabelledPush], masses: np.ndarray, frictions: np.ndarray
) -> np.ndarray:
    """(E, C) each episode's log-likelihood of its pushes under each class's `masses` (C, n),
    the table friction marginalised over `frictions` (uniform)."""
    joint = joint_log_likelihoods(density, pushes, masses, frictions)
    return np.logaddexp.reduce(joint, axis=2) - math.log(len(frictions))


def evidence_per_push(
    density: PushDensity, pushes: list[LabelledPush], labels: np.ndarray, masses: np.ndarray,
    frictions: np.ndarray,
) -> float:  # fmt: skip
    """Mean log-likelihood per push of labelled episodes under their true classes (`masses`
    (C, n), `labels` (E,)), the table friction marginalised over `frictions`: how well a
    density explains a lab's pushes. Higher is better; comparable between densities only on
    the same episodes (e.g. one trained for another tool:
    docs/notebook/2026-12-07-slicker-tool.md)."""
    log_lik = class_log_likelihoods(density, pushes, masses, frictions)
    return true_class_evidence(log_lik, pushes, labels)


def true_class_evidence(
    log_lik: np.ndarray, pushes: list[LabelledPush], labels: np.ndarray
) -> float:
    """`evidence_per_push` from the episodes' class log-likelihoods (E, C) already read
    (`class_log_likelihoods`), so that a caller that also sorts by them reads them once."""
    total = sum(len(p.actions) for p in pushes)
    if total == 0:
        raise ValueError("no labelled push to weigh")
    return float(log_lik[np.arange(len(labels)), labels].sum() / total)


def tune_density(
    density: PushDensity, pushes: list[LabelledPush], masses: np.ndarray, config: TuneConfig,
    progress: bool = True,
) -> PushDensity:  # fmt: skip
    """A copy of `density` tuned to episodes' `pushes` under their true `masses` (E, n):
    `config.steps` full-batch Adam steps on the mean negative log-likelihood per push
    (friction marginalised) plus `config.anchor` x the squared change of the weights."""
    from tqdm import tqdm

    tuned = copy.deepcopy(density).train()
    frictions = friction_grid(density, config.frictions)
    x, y, where = _rows(tuned, pushes, np.arange(len(pushes)), masses, frictions)
    n_pushes = sum(len(p.actions) for p in pushes)
    if n_pushes == 0:
        raise ValueError("no labelled push to tune the density on")
    anchor = [p.detach().clone() for p in tuned.parameters()]
    opt = torch.optim.Adam(tuned.parameters(), lr=config.lr)
    with one_thread():
        for _ in tqdm(range(config.steps), desc="tuning the density", disable=not progress):
            opt.zero_grad()
            nll = -_marginal(tuned, x, y, where, len(pushes), len(frictions)).sum() / n_pushes
            change = sum(((p - a) ** 2).sum() for p, a in zip(tuned.parameters(), anchor,
                                                               strict=True))  # fmt: skip
            (nll + config.anchor * change).backward()
            opt.step()
    return tuned.eval()


def cross_validate_tuning(
    density: PushDensity, pushes: list[LabelledPush], labels: np.ndarray, masses: np.ndarray,
    config: TuneConfig, progress: bool = True, count: int | None = None,
    untuned: np.ndarray | None = None,
) -> dict[str, Any]:  # fmt: skip
    """Stratified k-fold accuracy of sorting episodes by class posterior under the density
    tuned on the other folds (on all their pushes; classes' `masses` (C, n), `labels` (E,)),
    each held-out episode read from its first `count` pushes (all with None): the accuracy,
    the confusion (rows: truth), each episode's out-of-fold class and class
    log-likelihoods, the untuned density's accuracy on the same episodes, and
    (`by_pushes`) the accuracy with each held-out episode read from only its first 2, 4,
    8, ... pushes (`push_ladder`): how the sorting grows with the length of a run.
    `untuned`: the untuned density's class log-likelihoods (E, C) of the same reading, where
    the caller has them (`class_log_likelihoods` over the sorting grid), not read again."""
    c = len(masses)
    counts = fold_counts(labels, c, config.folds)
    # Sorted as the tuned density will sort (`sorting_grid`).
    frictions = friction_grid(density, config.sort_frictions, config.sort_range)
    read = first_pushes(pushes, count)
    if untuned is None:
        untuned = class_log_likelihoods(density, read, masses, frictions)
    elif np.shape(untuned) != (len(labels), c):
        raise ValueError(f"untuned: {np.shape(untuned)} log-likelihoods for {len(labels)} "
                         f"episodes of {c} classes")  # fmt: skip
    log_lik = np.zeros((len(labels), c))
    ladder = push_ladder(max((len(p.actions) for p in read), default=0))
    hits = np.zeros((len(ladder), len(labels)), bool)
    for test in stratified_folds(labels, config.folds, config.seed):
        train = np.setdiff1d(np.arange(len(labels)), test)
        tuned = tune_density(density, [pushes[i] for i in train], masses[labels[train]],
                             config, progress)  # fmt: skip
        held = [read[i] for i in test]
        log_lik[test] = class_log_likelihoods(tuned, held, masses, frictions)
        for row, step in enumerate(ladder):
            early = first_pushes(held, step)
            guess = class_log_likelihoods(tuned, early, masses, frictions).argmax(1)
            hits[row, test] = guess == labels[test]
    predicted = log_lik.argmax(1)
    confusion = np.zeros((c, c), np.int64)
    np.add.at(confusion, (labels, predicted), 1)
    return {
        "accuracy": float(np.mean(predicted == labels)),
        "untuned_accuracy": float(np.mean(untuned.argmax(1) == labels)),
        "confusion": confusion.tolist(),
        "predicted": predicted.tolist(),
        "log_likelihoods": log_lik.tolist(),
        "chance": float(counts.max() / counts.sum()),
        "by_pushes": [
            {"pushes": step, "accuracy": float(row.mean())}
            for step, row in zip(ladder, hits, strict=True)
        ],
        "config": asdict(config),
    }


def push_ladder(longest: int) -> list[int]:
    """2, 4, 8, ... pushes, each shorter than the `longest` episode: the early readings
    `cross_validate_tuning` reports (the full episodes are its main figure)."""
    steps, step = [], 2
    while step < longest:
        steps.append(step)
        step *= 2
    return steps


def pushes_per_episode(pushes: list[LabelledPush]) -> float:
    """The mean pushes of the episodes that have any (the tuned density keeps it)."""
    counts = [len(p.actions) for p in pushes if len(p.actions)]
    return float(np.mean(counts)) if counts else 0.0


def check_calibration_length(density: PushDensity, pushes: float, where: str) -> None:
    """Warn (`CalibrationWarning`) where a tuned density sorts episodes of `pushes` pushes
    (on average) though its calibration's were much shorter (`LONGER_THAN_CALIBRATION`);
    densities tuned before it was recorded pass unchecked."""
    tuned = density.meta.get("tuned") or {}
    calibration = tuned.get("pushes_per_episode")
    if calibration and pushes > LONGER_THAN_CALIBRATION * calibration:
        warnings.warn(
            f"{where} was tuned on episodes of {calibration:.1f} pushes on average and sorts "
            f"episodes of {pushes:.1f}: tune it on runs as long as those it sorts "
            "(docs/real-robot.md, 'Tuning the particle filter's push density to your lab')",
            CalibrationWarning,
            stacklevel=2,
        )


def record_tuning(
    tuned: PushDensity, classes: list[str], masses: np.ndarray, config: TuneConfig,
    pushes: list[LabelledPush], provenance: dict[str, Any] | None = None,
) -> None:  # fmt: skip
    """Write what `tuned_classes`, `posterior_classes` and `check_calibration_length` read
    back into `tuned.meta["tuned"]`: the class masses (C, n), the tuning config, the
    calibration's pushes per episode; `provenance` (where the episodes and the untuned
    density came from, the cross-validation) is kept beside them."""
    tuned.meta["tuned"] = {
        "classes": {name: row.tolist() for name, row in zip(classes, masses, strict=True)},
        "config": asdict(config),
        "pushes_per_episode": pushes_per_episode(pushes),
        **(provenance or {}),
    }


def sort_over(density: PushDensity, config: TuneConfig) -> None:
    """Have the tuned `density` sort over `config`'s frictions from now on (`sort_range`,
    `sort_frictions`), its weights unchanged: a density tuned before they were kept sorts
    over its tuning grid (`sorting_grid`)."""
    density.meta["tuned"]["config"] |= {"sort_range": list(config.sort_range),
                                        "sort_frictions": config.sort_frictions}  # fmt: skip


def tuned_classes(density: PushDensity, where: str) -> tuple[list[str], np.ndarray]:
    """The class names and masses (C, n) a tuned density was tuned on."""
    tuned = density.meta.get("tuned")
    if not tuned or not tuned.get("classes"):
        raise ValueError(f"{where}: not a tuned density (`masspush tune-density` makes one)")
    classes = list(tuned["classes"])
    return classes, np.array([tuned["classes"][c] for c in classes], float)


class SortingEvidence(NamedTuple):
    """What a tuned density makes of a recording's pushes, read once for both the class
    posterior (`class_posterior`) and the table's friction
    (`masspush.real.table_friction.friction_profiles`)."""

    classes: list[str]
    joint: np.ndarray
    """(E, C, F) each episode's log-likelihood under each class at each friction of `grid`."""
    pushed: np.ndarray
    """(E,) whether the episode has a push to read."""
    grid: np.ndarray
    """The density's `sorting_grid`."""


def sorting_evidence(
    density: PushDensity, recording: Recording, where: str, pushes: int | None = None
) -> SortingEvidence:
    """The tuned density's likelihoods of each episode's first `pushes` pushes (all by
    default) under its classes at the frictions of its `sorting_grid`."""
    classes, masses = tuned_classes(density, where)
    read = first_pushes(labelled_pushes(recording), pushes)
    grid = sorting_grid(density)
    return SortingEvidence(classes, joint_log_likelihoods(density, read, masses, grid),
                           np.array([len(p.actions) > 0 for p in read], bool), grid)  # fmt: skip


def class_posterior(joint: np.ndarray) -> np.ndarray:
    """(E, C) each episode's class log-posterior from its `joint` log-likelihoods (E, C, F):
    equal priors, the friction marginalised (uniform)."""
    log_lik = np.logaddexp.reduce(joint, axis=2)
    return log_lik - np.logaddexp.reduce(log_lik, axis=1, keepdims=True)


def posterior_classes(
    density: PushDensity, recording: Recording, where: str, pushes: int | None = None
) -> tuple[list[str], np.ndarray]:
    """The tuned density's classes and each episode's class log-posterior (E, C) from its
    first `pushes` pushes (all by default), equal priors, friction marginalised over its
    `sorting_grid`."""
    evidence = sorting_evidence(density, recording, where, pushes)
    return evidence.classes, class_posterior(evidence.joint)


def posterior_accuracy(
    density: PushDensity, recording: Recording, where: str, pushes: int | None = None
) -> dict[str, Any]:
    """How well the tuned density's class posterior sorts a labelled recording (from each
    episode's first `pushes` pushes): accuracy, confusion (rows: truth, in the density's
    class order), each episode's class."""
    return score_posterior(*posterior_classes(density, recording, where, pushes), recording,
                           where)  # fmt: skip


def score_posterior(
    classes: list[str], log_post: np.ndarray, recording: Recording, where: str
) -> dict[str, Any]:
    """`posterior_accuracy` of a labelled recording's class log-posteriors (E, C)."""
    unknown = sorted({str(label) for label in recording.labels} - set(classes))
    if unknown:
        raise ValueError(f"{where}: tuned for classes {classes}, not {unknown}")
    truth = np.array([classes.index(label) for label in recording.labels])
    guess = log_post.argmax(1)
    confusion = np.zeros((len(classes), len(classes)), np.int64)
    np.add.at(confusion, (truth, guess), 1)
    return {"accuracy": float(np.mean(guess == truth)), "confusion": confusion.tolist(),
            "predicted": guess.tolist(), "classes": classes}  # fmt: skip
