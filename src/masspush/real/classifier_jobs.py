"""`masspush finetune`, `masspush tune-density` and `masspush classify`: the paper's
real-robot adaptation from a recording of labelled episodes (`masspush.real.classifier` holds
the classifier itself, `masspush.real.density_tuning` the push density tuned to a lab)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from masspush.config import check_input, check_int, check_match, check_output
from masspush.data.recording import Recording, iter_recording, read_recording
from masspush.learn.predictor import check_batch_memory, load_model
from masspush.learn.push_density import DENSITY_BYTES_PER_PUSH, density_for, load_push_density
from masspush.models import resolve_model, shipped_density
from masspush.real.classifier import (
    ClassifierConfig,
    classifier_inputs,
    cross_validate,
    episode_log_probs,
    finetune_predictor,
    fit_classifier,
    fold_counts,
    labelled,
    load_classifier,
    save_classifier,
    start_pose_control,
)
from masspush.real.density_tuning import (
    TuneConfig,
    check_calibration_length,
    class_log_likelihoods,
    class_masses,
    class_posterior,
    cross_validate_tuning,
    first_pushes,
    friction_grid,
    labelled_pushes,
    pushes_per_episode,
    record_tuning,
    sorting_evidence,
    sorting_grid,
    true_class_evidence,
    tune_density,
)
from masspush.real.robot import check_geometry, model_speed_reader
from masspush.real.table_friction import (
    calibration_friction,
    check_drift,
    friction_lines,
    friction_profiles,
    pool_reading,
    read_friction,
)
from masspush.settings import get_setting


@dataclass(frozen=True)
class FinetuneJob:
    """`masspush finetune`: a classifier on a predictor's features from labelled recordings."""

    setting: str
    """The predictor's named setting."""
    episodes: str
    """Recording of labelled episodes."""
    model: str = "tp+"
    """Shipped name or file of the predictor."""
    out: str = "classifier.pt"
    """Where to save the classifier (trained on every episode)."""
    predictor_out: str | None = None
    """Instead: fine-tune the predictor itself into this directory (needs the masses)."""
    settings_file: str | None = None
    """TOML file with custom settings."""
    allow_mismatch: bool = False
    """Use a recording or predictor of another setting (same number of links)."""
    read_speeds: bool = True
    """The predictor reads each push the recording keeps the speed of as the action at which
    its own pusher would have moved at that speed (`masspush.real.robot.speed_reader`; the
    classifier file remembers it); --no-read-speeds: as the action commanded."""

    def __post_init__(self) -> None:
        check_input(self.episodes, "episodes")
        if self.predictor_out is None:
            check_output(self.out, "out")


def finetune(job: FinetuneJob, config: ClassifierConfig) -> list[str]:
    """Cross-validate the classifier, then save it trained on every episode (or fine-tune
    the predictor); the report."""
    setting = get_setting(job.setting, job.settings_file)
    recording, predictor, meta, path = read_with_predictor(
        job.episodes, job.model, setting.name, job.allow_mismatch, setting.n_links
    )
    episodes = recording.to_episodes(model_speed_reader(meta) if job.read_speeds else None)
    if job.predictor_out:
        out = finetune_predictor(path, episodes, job.predictor_out, recording=str(job.episodes))
        return [f"fine-tuned predictor: {out}"]
    labels, classes = labelled(recording)
    features, owner = classifier_inputs(predictor, episodes, config)
    scores = cross_validate(features, labels, len(classes), config, owner)
    control = start_pose_control(episodes, labels, len(classes), config)
    lines = [
        f"{len(labels)} episodes, {len(classes)} classes: {config.folds}-fold cross-validated "
        f"accuracy {100 * scores['accuracy']:.1f} % (chance {100 * scores['chance']:.1f} %)",
        f"confusion (rows: truth, columns: predicted), classes in this order: {classes}",
        *("  " + " ".join(f"{v:4d}" for v in row) for row in scores["confusion"]),
        f"start-pose control: {100 * control['accuracy']:.1f} % (the same classifier given "
        "only each episode's start pose; well above chance, which episodes were recorded "
        "depends on the class)",
        *episode_counts(recording, classes),
    ]
    model = fit_classifier(features, labels[owner], len(classes), config)
    info = {"setting": setting.name, "predictor": str(path), "predictor_meta": meta,
            "features": config.features, "segment": config.segment, "runs": config.runs,
            "read_speeds": job.read_speeds, "episodes": str(job.episodes),
            "cross_validation": scores, "start_pose_control": control}  # fmt: skip
    saved = save_classifier(job.out, model, classes, config, info)
    return [*lines, f"saved {saved} (trained on all)"]


def episode_counts(recording: Recording, classes: list[str]) -> list[str]:
    """Per class: episodes, pushes per episode, and those that ended early by reason (the
    `failure` a recording's episodes may carry)."""
    lines = []
    for label in classes:
        ours = [e for e in recording.episodes if e.get("label") == label]
        pushes = np.mean([len(e["actions"]) for e in ours])
        ended: dict[str, int] = {}
        for e in ours:
            if "failure" in e:
                ended[e["failure"]] = ended.get(e["failure"], 0) + 1
        early = ", ".join(f"{n} {why}" for why, n in sorted(ended.items())) or "none"
        lines.append(
            f"  {label}: {len(ours)} episodes, {pushes:.1f} pushes each, ended early: {early}"
        )
    return lines


def read_with_predictor(
    episodes: str, model: str, setting: str, allow_mismatch: bool = False,
    n_links: int | None = None,
) -> tuple[Recording, Any, dict, Path]:  # fmt: skip
    """A recording and the predictor that is to read it (a name `resolve_model` knows, or
    a file), checked against each other (`check_recording_fits`): (the recording, the
    predictor, its metadata, its file). Raises ValueError or OSError naming the file."""
    path = resolve_model(model, setting)
    predictor, meta = load_model(path, setting, allow_mismatch=allow_mismatch, n_links=n_links)
    recording = read_recording(episodes)
    check_recording_fits(recording, episodes, setting, predictor.n_links, allow_mismatch, meta)
    return recording, predictor, meta, path


def check_recording_fits(
    recording: Recording, where: str, setting: str, n_links: int, allow_mismatch: bool,
    predictor_meta: dict | None = None,
) -> None:  # fmt: skip
    """A recording read by a predictor of `setting`: of that setting (unless
    --allow-mismatch) and always of its number of links; a warning where the recording's
    chain geometry is not the predictor's."""
    check_match("n_links", where, recording.n_links, n_links, allowable=False)
    check_match("setting", where, recording.setting, setting, allow_mismatch)
    if recording.geometry is not None and predictor_meta is not None:
        check_geometry(predictor_meta, recording.geometry)


@dataclass(frozen=True)
class ClassifyJob:
    """`masspush classify`: a saved classifier applied to recorded episodes."""

    episodes: str
    """Recording to classify."""
    classifier: str | None = None
    """The classifier file (from `masspush finetune`)."""
    density: str | None = None
    """Instead of a classifier: a push density tuned to the lab (`masspush tune-density`),
    each episode sorted by its class posterior."""
    allow_mismatch: bool = False
    """Classify a recording of another setting (same number of links)."""
    pushes: int | None = None
    """With --density: sort each episode from its first P pushes only (e.g. 2, the paper's
    protocol, on a recording of longer runs); default: all of them."""

    def __post_init__(self) -> None:
        if (self.classifier is None) == (self.density is None):
            raise ValueError("give either --classifier or --density (a tuned push density)")
        check_int("pushes", self.pushes, optional=True)
        if self.pushes is not None and self.density is None:
            raise ValueError(
                "pushes: a classifier reads the runs it was trained on; --pushes is for --density"
            )
        for name in ("classifier", "density"):
            if getattr(self, name) is not None:
                check_input(getattr(self, name), name)
        check_input(self.episodes, "episodes")


def classify(job: ClassifyJob) -> list[str]:
    """Each episode's class and probability, and the accuracy on the labelled ones."""
    if job.density is not None:
        return classify_by_posterior(job)
    model, classes, meta = load_classifier(job.classifier)
    predictor, predictor_meta = load_model(meta["predictor"], meta["setting"])
    # Classifiers saved before runs could be read one by one averaged them.
    reading = ClassifierConfig(
        features=meta.get("features", "estimate"),
        segment=meta.get("segment", 0),
        runs=meta.get("runs", "average"),
    )
    # Read as the classifier's training read them (files from before: as commanded).
    read_speed = model_speed_reader(predictor_meta) if meta.get("read_speeds") else None
    answers: list[tuple[str, str | None, str, float]] = []
    # Piece by piece: a recording of any size is classified in the memory of one piece.
    for i, piece in enumerate(iter_recording(job.episodes)):
        if i == 0:
            check_recording_fits(
                piece, job.episodes, meta["setting"], predictor.n_links, job.allow_mismatch,
                meta.get("predictor_meta"),
            )  # fmt: skip
        features, owner = classifier_inputs(predictor, piece.to_episodes(read_speed), reading)
        probs = np.exp(episode_log_probs(model, features, owner, len(piece.episodes)))
        answers += [(e["id"], e.get("label"), classes[int(p.argmax())], float(p.max()))
                    for e, p in zip(piece.episodes, probs, strict=True)]  # fmt: skip
    return answer_lines(answers)


def answer_lines(answers: list[tuple[str, str | None, str, float]]) -> list[str]:
    """One line per (episode id, its label or None, the class guessed, its probability) and
    the accuracy on the labelled ones."""
    lines, right, known = [], 0, 0
    for name, truth, guess, p in answers:
        right += guess == truth
        known += truth is not None
        mark = "" if truth is None else f"  (label {truth}{', right' if guess == truth else ''})"
        lines.append(f"{name}: {guess}  p={p:.2f}{mark}")
    if known:
        lines.append(f"accuracy on the {known} labelled episode(s): {100 * right / known:.1f} %")
    return lines


def classify_by_posterior(job: ClassifyJob) -> list[str]:
    """`classify` with a tuned push density: each episode's class of highest posterior."""
    try:
        density = load_push_density(job.density)
    except ValueError as err:
        raise ValueError(f"density: {err}") from None
    answers: list[tuple[str, str | None, str, float]] = []
    profiles = []
    where = f"density: {job.density}"
    # Piece by piece, as with a classifier: any size in the memory of one piece.
    for i, piece in enumerate(iter_recording(job.episodes)):
        if i == 0:
            check_recording_fits(piece, job.episodes, density.meta.get("setting"),
                                 density.meta["n_links"], job.allow_mismatch)  # fmt: skip
            length = pushes_per_episode(first_pushes(labelled_pushes(piece), job.pushes))
            check_calibration_length(density, length, where)
        # One reading of the pushes for both the classes and the table's friction.
        evidence = sorting_evidence(density, piece, where, job.pushes)
        classes, log_post = evidence.classes, class_posterior(evidence.joint)
        answers += [(e["id"], e.get("label"), classes[int(row.argmax())], float(np.exp(row.max())))
                    for e, row in zip(piece.episodes, log_post, strict=True)]  # fmt: skip
        profiles.append(friction_profiles(evidence))
    lines = answer_lines(answers)
    stacked = np.concatenate(profiles)
    if len(stacked):
        reading = pool_reading(stacked, sorting_grid(density), f"episodes: {job.episodes}")
        check_drift(reading, density, f"episodes: {job.episodes}")
        lines += friction_lines(reading, calibration_friction(density))
    return lines


@dataclass(frozen=True)
class TuneDensityJob:
    """`masspush tune-density`: the particle filter's push density tuned to a lab's
    labelled episodes (each with its class's masses), the class-posterior sorting
    cross-validated."""

    setting: str
    """The density's named setting."""
    episodes: tuple[str, ...]
    """Recordings of labelled episodes of one lab, each episode with its class's link
    masses (`masses`); several are tuned on together."""
    out: str = "lab-density.pt"
    """Where to save the tuned density (tuned on every episode), with its classes."""
    density: str | None = None
    """The push density to tune (`masspush train-density`); default: the setting's shipped
    one."""
    settings_file: str | None = None
    """TOML file with custom settings."""

    def __post_init__(self) -> None:
        if isinstance(self.episodes, str):  # one recording, as a string
            object.__setattr__(self, "episodes", (self.episodes,))
        if not self.episodes:
            raise ValueError("episodes: name at least one recording")
        for path in self.episodes:
            check_input(path, "episodes")
        if self.density is not None:
            check_input(self.density, "density")
        check_output(self.out, "out")


def tune(job: TuneDensityJob, config: TuneConfig, progress: bool = True) -> list[str]:
    """Cross-validate the class-posterior sorting with the density tuned per fold, then save
    the density tuned on every episode; the report."""
    setting = get_setting(job.setting, job.settings_file)
    path = job.density or str(shipped_density(setting.name))
    if job.density is None and not Path(path).is_file():
        raise ValueError(f"density: setting {setting.name!r} ships no push density; give one")
    try:
        density = density_for(path, setting.env_config())
    except ValueError as err:
        raise ValueError(f"density: {err}") from None
    if density.meta.get("actions", "commanded") != "commanded":
        raise ValueError(
            f"density: {path} is conditioned on the pushes as executed; tuning reads the "
            "recorded pushes as commanded"
        )
    recording = Recording(setting.n_links, setting=setting.name)
    for where in job.episodes:
        part = read_recording(where)
        check_recording_fits(part, where, setting.name, setting.n_links, False)
        recording.episodes += part.episodes
    named = ", ".join(job.episodes)
    try:
        labels, classes = labelled(recording)
        masses = class_masses(recording, classes)
    except ValueError as err:
        raise ValueError(f"episodes: {named}: {err}") from None
    if config.folds:
        try:  # before any tuning
            fold_counts(labels, len(classes), config.folds)
        except ValueError as err:
            raise ValueError(f"folds: {named}: {err} ({', '.join(classes)})") from None
    pushes = labelled_pushes(recording)
    total = sum(len(p.actions) for p in pushes)
    # Every push at every friction is in one step of the tuning, and in one reading of the
    # sorting: refused before it runs out of memory.
    for name, count in (("frictions", config.frictions), ("sort_frictions", config.sort_frictions)):
        try:
            what = f"{total:,} labelled pushes at {count:,} frictions"
            check_batch_memory(total, count, DENSITY_BYTES_PER_PUSH, what)
        except ValueError as err:
            raise ValueError(f"{name}: {err}") from None
    per_episode = pushes_per_episode(pushes)
    lines = [
        f"{len(labels)} episodes, {len(classes)} classes, {total} pushes ({per_episode:.1f} "
        "per episode: for sorting episodes up to about as long)"
    ]
    # Which of several densities (another tool's, another training) fits the lab: the
    # untuned one's evidence, as comparable between them as the sorting and less noisy.
    # Read once: the evidence and the cross-validation's untuned sorting.
    grid = friction_grid(density, config.sort_frictions, config.sort_range)
    untuned = class_log_likelihoods(density, pushes, masses, grid)
    evidence = true_class_evidence(untuned, pushes, labels)
    lines.append(
        f"the untuned density explains these pushes at {evidence:.3f} nats per push (true "
        "classes, friction marginalised; higher fits your lab better: compare densities on "
        "the same episodes)"
    )
    scores = None
    if config.folds:
        scores = cross_validate_tuning(density, pushes, labels, masses, config, progress,
                                       untuned=untuned)  # fmt: skip
        lines += [
            f"sorted by class posterior: untuned density {100 * scores['untuned_accuracy']:.1f} %, "
            f"tuned ({config.folds}-fold cross-validated) {100 * scores['accuracy']:.1f} % "
            f"(chance {100 * scores['chance']:.1f} %)",
            "  held-out episodes read from their first pushes only (is a longer run worth it?): "
            + ", ".join(
                [f"{s['pushes']}: {100 * s['accuracy']:.1f} %" for s in scores["by_pushes"]]
                + [f"all: {100 * scores['accuracy']:.1f} %"]
            ),
            f"confusion (rows: truth, columns: predicted), classes in this order: {classes}",
            *("  " + " ".join(f"{v:4d}" for v in row) for row in scores["confusion"]),
        ]
    tuned = tune_density(density, pushes, masses[labels], config, progress)
    provenance = {"episodes": list(job.episodes), "from": str(path),
                  "from_digest": density.digest(), "cross_validation": scores,
                  "untuned_evidence_per_push": evidence}  # fmt: skip
    record_tuning(tuned, classes, masses, config, pushes, provenance)
    # What a later day's sorting compares its own reading with (`check_drift`).
    reading = read_friction(tuned, recording, f"episodes: {named}")
    tuned.meta["tuned"]["table_friction"] = reading.as_dict()
    Path(job.out).parent.mkdir(parents=True, exist_ok=True)
    tuned.save(job.out)
    return [*lines, *episode_counts(recording, classes), *friction_lines(reading, None),
            f"saved {job.out} (tuned on all)"]  # fmt: skip
