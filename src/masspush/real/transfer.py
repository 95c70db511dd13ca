"""The paper's real-robot protocol, run in the sim-to-real target world.

For each policy (random pushes with the random-push predictor RP, the learned policy with
TP+), episodes of the paper's five mass classes are run in `masspush.real.target_world` and
recorded like real ones (`masspush.data.recording`, labelled). A classifier on the predictor's
features is then cross-validated on each recording, as the paper did with its UR10
episodes [paper-details.md, "Real robot"]. Recordings are kept, so a rerun only
re-scores; `masspush finetune` on them gives the same accuracies. `lab` keeps one lab's
setup for every episode (`target_world.Lab`); `segments` runs each policy several times per
episode, and the classifier reads the runs as `ClassifierConfig.runs` says (by default each
on its own, an episode's runs' log-probabilities added up).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from tqdm import tqdm

from masspush.bayes.estimator import BAYES_MODELS
from masspush.cluster.pool import Workers, check_address, gather, is_pool, open_pool
from masspush.config import SEED_MAX, check_int
from masspush.real.classifier import (
    FEATURE_KINDS,
    PAPER_CLASSES,
    ClassifierConfig,
    classifier_inputs,
    cross_validate,
    first_pushes,
    labelled,
    one_thread,
    predictor_features,
    start_pose_control,
)
from masspush.real.density_tuning import (
    check_calibration_length,
    class_posterior,
    posterior_accuracy,
    score_posterior,
    sorting_evidence,
)
from masspush.real.filter_arm import FilterArm, check_bayes_options
from masspush.real.governor import fitted_setting_governor
from masspush.real.table_friction import (
    calibration_friction,
    check_drift,
    friction_profiles,
    pool_reading,
)
from masspush.sim.simulate import REACH_FAILURES

if TYPE_CHECKING:
    from masspush.data.recording import Recording, SpeedReader
    from masspush.data.rollout import Policy
    from masspush.learn.push_density import PushDensity
    from masspush.real.robot import HistoryPredictor, Robot
    from masspush.real.target_world import TargetWorld
    from masspush.settings import Setting

HAND_YAW_SCATTER = 5.0
"""How far a chain laid by hand strays from the heading asked (`Sim2RealConfig.start_yaw`),
degrees [ours: a chain aligned by eye with a line on the table]."""
PAPER_ACCURACY = {"random": 40.74, "learned": 81.4}
"""The paper's real-robot accuracies, % (chance 20 %) [paper-details.md]."""
ARMS = {"random": "rp", "learned": "tp+"}
"""Which shipped model each arm of the experiment uses by default; each brings its own
policy. A recording names its model unless it is the default (`record_arm`)."""
WORLDS = ("target", "training")


@dataclass(frozen=True)
class Sim2RealConfig:
    setting: str = "real-ur10"
    episodes_per_class: int = 30
    """Usable episodes (at least one push seen) per class and policy [paper: 30]."""
    seed: int = 0
    """The chains' seed: both arms push the same chains; runs with other seeds never share
    a chain."""
    world: str = "target"
    """"target": the sim-to-real target world; "training": the world the models were
    trained in (the control: what the protocol gives without any gap)."""
    severity: float = 1.0
    """The target world's differences from training, scaled (`target_world.scaled_world`):
    1 the target world, 0 the training world's knobs; only with world "target"."""
    lab: int | None = None
    """None: every episode draws the target world's constants afresh (a lab of its own per
    episode, the stress test); a seed: one lab's constants for all episodes and each class's
    object its own (`target_world.Lab`), as in a real lab; only with world "target"."""
    day: int = 0
    """Which day in the lab: 0, the day every lab figure before 2026-12-07 was measured on
    (its governor fits and calibration runs too); another, a later day on which the table's
    friction, the robot's speed gain and the tracker's calibration have drifted
    (`target_world.Lab`). Only with lab."""
    governor_fit: str | None = None
    """A recording of random pushes made in this world (e.g. an earlier run's random.jsonl):
    the stationary robot's speed governor takes its slide bounds from them
    (`masspush.real.governor.fit_governor`) instead of the training world's."""
    start_range: float | None = None
    """Where the lab places each episode's chain: its first link's centre within
    +-start_range m of the table origin (x and y each; yaw and hinge angles as the setting
    draws them), e.g. 0.02 for a chain put down by hand on a marked spot. None: the
    setting's own range (`real-ur10`: 0.2 m, over most of the stationary robot's workspace),
    as its models were trained."""
    start_yaw: float | None = None
    """Which way the lab lays each episode's chain, degrees: its first link's heading relative
    to the direction the stationary robot faces (0: pointing straight away from the robot,
    the chain lying along a radius of its workspace; 90: across, along the arc), within
    5 degrees of it (`HAND_YAW_SCATTER`). None: any heading, as the setting draws them and
    its models were trained. Only for a setting whose robot stands still."""
    check_reach: bool = False
    """The particle-filter arm asks the robot's planner whether it can make a push before
    choosing it (`masspush.sim.arm_reach`), as a robot that knows its inverse kinematics
    would, and pushes the best candidate it can make; off: the best candidate, unasked, as
    every figure before 2026-12-05 was measured. Only for a filter arm on a stationary
    robot."""
    segments: int = 1
    """Each episode runs the policy this many times in a row on the same chain, each run the
    setting's pushes (`masspush.real.robot.run_segments`); the classifier reads the runs as
    `classifier.runs` says. 1: the paper's protocol."""
    density: str | None = None
    """The push density (`masspush train-density`) a particle-filter arm (model bayes or
    bayes-random) weighs pushes with; default: the setting's shipped one."""
    tuned_density: str | None = None
    """A push density tuned to the lab on other chains' labelled episodes (`masspush
    tune-density`): every arm's episodes are also sorted by its class posterior, with no
    classifier trained on them. The filter arm still pushes and estimates with `density`:
    pushing with a tuned density sorted fewer chains in lab 5
    (docs/notebook/2026-12-05-lab-tuned-density.md)."""
    bayes: dict[str, Any] | None = None
    """`BayesConfig` fields a particle-filter arm runs with instead of its defaults
    (`masspush sim2real --bayes KEY=VALUE`), e.g. {"likelihood_power": 0.5}."""
    read_speeds: bool = True
    """The models read each push at the speed the robot reports it reached, as the action at
    which their own pusher would have moved at that speed (`masspush.real.robot.speed_reader`);
    --no-read-speeds: as the action commanded."""
    classifier: ClassifierConfig = field(default_factory=ClassifierConfig)
    models: dict[str, str] = field(default_factory=lambda: dict(ARMS))
    """Each arm's model (shipped name or path): its policy pushes, its predictor's
    features feed the classifier."""

    def __post_init__(self) -> None:
        from masspush.settings import get_setting

        get_setting(self.setting)  # a setting that exists, before run_sim2real makes `out`
        if set(self.models) != set(ARMS):
            raise ValueError(f"models must name one model for each of {list(ARMS)}")
        if self.world not in WORLDS:
            raise ValueError(f"world must be one of {WORLDS}, got {self.world!r}")
        if not 0 <= self.severity <= 1:
            raise ValueError(f"severity must be in [0, 1], got {self.severity!r}")
        if self.world != "target" and self.severity != 1:
            raise ValueError("severity scales the target world; it needs world 'target'")
        if self.segments < 1:
            raise ValueError(f"segments must be >= 1, got {self.segments}")
        if self.governor_fit is not None and not Path(self.governor_fit).is_file():
            raise ValueError(f"governor_fit: no such recording {self.governor_fit}")
        filtered = any(m in BAYES_MODELS for m in self.models.values())
        if self.density is not None:
            if not filtered:
                raise ValueError("density is the particle filter's; no arm's model is bayes")
            from masspush.learn.push_density import density_for

            try:  # a bad file is refused before any episode
                density_for(self.density, get_setting(self.setting).env_config())
            except ValueError as err:
                raise ValueError(f"density: {err}") from None
        if self.tuned_density is not None:
            self.sorting_density()
        check_int("seed", self.seed, low=0, high=SEED_MAX)
        check_int("lab", self.lab, low=0, optional=True)
        check_int("day", self.day, low=0, high=SEED_MAX)
        if self.day and self.lab is None:
            raise ValueError("day is a day in one lab: pass --lab too")
        if self.start_range is not None and not 0 <= self.start_range <= 1:
            raise ValueError(f"start_range must be in [0, 1] m, got {self.start_range!r}")
        if self.start_yaw is not None:
            if not -180 <= self.start_yaw <= 180:
                raise ValueError(
                    f"start_yaw must be in [-180, 180] degrees, got {self.start_yaw!r}"
                )
            if _robot_facing(self.setting) is None:
                raise ValueError(f"start_yaw is relative to a stationary robot; the robot "
                                 f"of setting {self.setting!r} follows the chain")  # fmt: skip
        if self.check_reach:
            if not filtered:
                raise ValueError("check_reach is the particle filter's; no arm's model is bayes")
            if _robot_facing(self.setting) is None:
                raise ValueError(f"check_reach is for a stationary robot; the robot of "
                                 f"setting {self.setting!r} follows the chain")  # fmt: skip
        check_bayes_options(self.bayes, filtered)
        if self.world != "target" and self.lab is not None:
            raise ValueError("a lab is one draw of the target world; it needs world 'target'")
        if self.episodes_per_class < self.classifier.folds:
            raise ValueError(
                f"episodes_per_class must be >= the {self.classifier.folds} folds, "
                f"got {self.episodes_per_class}"
            )

    def sorting_density(self) -> PushDensity | None:
        """The `tuned_density`, checked: of this setting, tuned for the protocol's classes."""
        from masspush.learn.push_density import density_for
        from masspush.settings import get_setting

        try:
            net = density_for(self.tuned_density, get_setting(self.setting).env_config())
        except ValueError as err:
            raise ValueError(f"tuned_density: {err}") from None
        classes = net.meta.get("tuned", {}).get("classes")
        if classes is None:
            raise ValueError(
                f"tuned_density: {self.tuned_density} is not tuned (`masspush tune-density`)"
            )
        if classes != {k: list(v) for k, v in PAPER_CLASSES.items()}:
            raise ValueError(
                f"tuned_density: {self.tuned_density} was tuned for the classes {classes}, "
                f"not the protocol's {dict(PAPER_CLASSES)}"
            )
        pushes = self.segments * get_setting(self.setting).env_config().pushes
        check_calibration_length(net, pushes, f"tuned_density: {self.tuned_density}")
        return net


@dataclass(frozen=True)
class Sim2RealJob:
    """Where `masspush sim2real` writes, and the models of its two arms."""

    out: str = "results/sim2real"
    """Directory of the recordings and the summary (a rerun reuses its recordings)."""
    random_model: str = ARMS["random"]
    """The random-push arm's model."""
    learned_model: str = ARMS["learned"]
    """The learned arm's model, e.g. tp+dr."""
    ray: str | None = None
    """Record the classes' episodes on a Ray cluster, a task per class and arm: auto, local,
    ray://HOST:PORT or HOST:PORT (pip install 'masspush[ray]')."""

    def __post_init__(self) -> None:
        check_address(self.ray)


def sim2real(job: Sim2RealJob, config: Sim2RealConfig) -> str:
    """`masspush sim2real`: both arms recorded and scored; the summary (Markdown). The
    classifier's folds and weights follow the experiment's seed."""
    config = replace(
        config,
        models={"random": job.random_model, "learned": job.learned_model},
        classifier=replace(config.classifier, seed=config.seed),
    )
    with open_pool(job.ray) as workers:
        run_sim2real(config, job.out, workers=workers)
    return (Path(job.out) / "summary.md").read_text()


def record_classes(
    config: Sim2RealConfig, predictor: HistoryPredictor, policy: Policy, robot_name: str,
    desc: str = "", progress: bool = True, target: TargetWorld | None = None,
    workers: Workers = None,
) -> tuple[Recording, dict[str, int], dict[str, dict]]:  # fmt: skip
    """`config.episodes_per_class` episodes of each of the paper's classes, pushed by
    `policy` in `config.world`: the recording (labelled; every episode with at least one
    good push, classified from the pushes it has), the failed pushes by reason, and per
    class the episodes attempted, kept, lost (the robot lost the chain:
    `sim.simulate.REACH_FAILURES`), failed otherwise, and the good pushes. An episode that
    fails is never replaced: which episodes survive could depend on the class, and a lead
    measured on survivors would then be partly selection (docs/real-robot.md). `target`
    replaces the target world (default: the target world at `config.severity`). With a
    `TaskPool` as `workers` (a Ray cluster), each class is a task: the same recording."""
    from masspush.data.recording import Recording
    from masspush.real.target_world import scaled_world
    from masspush.settings import get_setting

    setting = get_setting(config.setting)
    recording = Recording(n_links=setting.n_links, robot=robot_name, setting=setting.name)
    failures: dict[str, int] = {}
    classes: dict[str, dict[str, int]] = {}
    world = target or scaled_world(config.severity)
    governor = (
        None
        if config.governor_fit is None
        else fitted_setting_governor(setting, config.governor_fit)
    )
    shared = (config, predictor, policy, world, governor)
    jobs = list(range(len(PAPER_CLASSES)))
    if is_pool(workers):
        results = gather(workers.imap(_record_class, jobs, shared, desc or None), len(jobs))
    else:
        bar = tqdm(total=config.episodes_per_class * len(jobs), desc=desc, disable=not progress)
        results = [_record_class(shared, c, bar.update) for c in jobs]
        bar.close()
    for label, (episodes, class_failures, tally) in zip(PAPER_CLASSES, results, strict=True):
        recording.episodes += episodes
        classes[label] = tally
        for reason, count in class_failures.items():
            failures[reason] = failures.get(reason, 0) + count
    return recording, failures, classes


def _speed_reader(config: Sim2RealConfig) -> SpeedReader | None:
    """How the arms' models read a push's reported speed here, or None (`read_speeds`)."""
    from masspush.real.robot import speed_reader
    from masspush.settings import get_setting

    if not config.read_speeds:
        return None
    setting = get_setting(config.setting)
    return speed_reader(setting.pusher, setting.physics())


CLASS_SEEDS = 100_000
"""Seeds each class's robot owns within a run (one or more per chain: a chain that cannot be
placed is redrawn with the next)."""
RUN_SEEDS = len(PAPER_CLASSES) * CLASS_SEEDS
"""Seeds each run (`--seed`) owns, so that runs never share a chain. Before 2026-12-06 a
run's chains began at `seed` itself, and seed S + 1's chains were seed S's shifted by one
(docs/notebook/2026-12-06-overlapping-seeds.md); seed 0's chains are unchanged."""


def class_robot(
    setting: Setting, c: int, seed: int = 0, world: TargetWorld | None = None,
    lab: int | None = None, pushes: int | None = None, day: int = 0,
) -> Robot:  # fmt: skip
    """The robot that pushes the chains of class `c` (of `PAPER_CLASSES`) in `masspush
    sim2real --seed SEED`: in the target world `world` (a `TargetWorld`; `lab` one lab of
    it, on its day `day`), or with `world` None in the training world, there with room for
    `pushes` pushes.
    Seeds differ between classes but not between a run's arms or experiments that use
    this: they see the same chains, frictions and biases, so comparisons are paired; other
    seeds see other chains (`RUN_SEEDS`)."""
    from masspush.real.backends import SimRobot
    from masspush.real.target_world import TargetWorldRobot

    masses = list(PAPER_CLASSES.values())[c]
    first = RUN_SEEDS * seed + CLASS_SEEDS * c
    if world is not None:
        return TargetWorldRobot(setting, world, seed=first, masses=masses, lab=lab, day=day)
    # The classes are the paper's masses in any setting, as in the target world.
    pushes = pushes or setting.env_config().pushes
    return SimRobot(setting, seed=first, masses=masses, pushes=pushes, allow_out_of_range=True)


class ClassEpisode(NamedTuple):
    """One episode of `class_episodes`: its class, its number within the class, its id (as
    in `masspush sim2real`'s recordings), the robot and the chain's first rest pose."""

    c: int
    i: int
    id: str
    robot: Any
    pose: Any


def episode_id(c: int, i: int) -> str:
    """The id of class `c`'s episode `i` (from 0) in a recording: '0.160-0.160-001'."""
    return f"{list(PAPER_CLASSES)[c]}-{i + 1:03d}"


def class_episodes(
    setting: Setting, per_class: int, seed: int = 0, lab: int | None = None,
    pushes: int | None = None,
) -> Iterator[ClassEpisode]:  # fmt: skip
    """The chains of `masspush sim2real --seed SEED [--lab LAB]`, class by class, each robot
    started on its next chain (whether or not the caller pushes it, so that a resumed run
    sees the same chains), in the training world or with `lab` in that lab of the target
    world; each class's robot is closed after its last episode."""
    from masspush.real.target_world import TargetWorld

    world = None if lab is None else TargetWorld()
    for c in range(len(PAPER_CLASSES)):
        robot = class_robot(setting, c, seed, world, lab, pushes)
        try:
            for i in range(per_class):
                yield ClassEpisode(c, i, episode_id(c, i), robot, robot.start())
        finally:
            robot.close()


def _robot_facing(setting_name: str) -> float | None:
    """The yaw a setting's stationary robot faces, rad; None where its base follows the chain."""
    from masspush.settings import get_setting
    from masspush.sim.pushers import pusher_kind

    workspace = pusher_kind(get_setting(setting_name).pusher).workspace
    return None if workspace is None else workspace.base[2]


def _placement(config: Sim2RealConfig) -> dict[str, Any]:
    """The physics overrides that put each chain down where the lab does (start_range,
    start_yaw); empty: where the setting draws it."""
    out: dict[str, Any] = {}
    if config.start_range is not None:
        out["root_xy_range"] = config.start_range
    if config.start_yaw is not None:
        centre = _robot_facing(config.setting) + math.radians(config.start_yaw)
        scatter = math.radians(HAND_YAW_SCATTER)
        out["root_yaw_range"] = (centre - scatter, centre + scatter)
    return out


def _record_class(
    shared: tuple, c: int, advance: Callable[[], object] | None = None
) -> tuple[list, dict, dict]:
    """Class `c`'s episodes, one robot for them all (its randomness runs on from episode to
    episode): the recorded episodes, the failed pushes by reason, the tally."""
    from masspush.real.robot import run_segments
    from masspush.settings import get_setting

    config, predictor, policy, world, governor = shared
    label = list(PAPER_CLASSES)[c]
    setting = get_setting(config.setting)
    placement = _placement(config)
    if placement:  # the same setting (and models), the chain put down by the lab
        setting = replace(setting, overrides={**setting.overrides, **placement})
    pushes = setting.env_config().pushes
    robot = class_robot(
        setting, c, config.seed, world if config.world == "target" else None, config.lab,
        pushes * config.segments, config.day,
    )  # fmt: skip
    if governor is not None:
        robot.governor = governor
    if isinstance(policy, FilterArm):  # its candidates compared as this robot makes them
        policy.governor = robot.governor
        if config.check_reach:  # by the robot's planner, which knows the setting's chain
            from masspush.sim.arm_reach import reach_check

            policy.reach_check = reach_check(setting.pusher, setting.physics())
    read_speed = _speed_reader(config)
    episodes, failures = [], {}
    tally = {k: 0 for k in ("attempted", "kept", "lost", "failed")}
    tally["good_pushes"] = 0
    for i in range(config.episodes_per_class):
        episode = run_segments(robot, predictor, policy, pushes, config.segments,
                               seed=robot.seed, read_speed=read_speed)  # fmt: skip
        tally["attempted"] += 1
        tally["good_pushes"] += len(episode.estimates)
        if episode.failure is not None:
            failures[episode.failure] = failures.get(episode.failure, 0) + 1
            tally["lost" if episode.failure in REACH_FAILURES else "failed"] += 1
        if episode.estimates:
            tally["kept"] += 1
            episodes.append(
                episode.recorded(id=episode_id(c, i), label=label, masses=robot.truth["masses"])
            )
        if advance is not None:
            advance()
    robot.close()
    return episodes, failures, tally


def record_arm(
    config: Sim2RealConfig, arm: str, path: Path, progress: bool = True,
    target: TargetWorld | None = None, robot_name: str | None = None, workers: Workers = None,
) -> dict[str, Any]:  # fmt: skip
    """Run one arm's episodes in the target world into the recording at `path` (kept, with
    its failed pushes, each class's episodes attempted, kept and lost, and a filter arm's
    settings as run beside it; reused when complete and made by the same robot and filter
    settings); returns those counts (and the filter's settings).
    `target` replaces the target world (`record_classes`); `robot_name`, which names the
    recording and decides whether a kept one is reused, then tells the worlds apart."""
    from masspush.data.recording import read_recording, write_recording
    from masspush.models import model_and_policy
    from masspush.settings import get_setting

    wanted = config.episodes_per_class * len(PAPER_CLASSES)
    counts = path.with_suffix(".failures.json")
    model = config.models[arm]
    if robot_name is None:
        robot_name = f"masspush {config.world} world"
        if config.severity != 1:
            robot_name += f" (differences x{config.severity:g})"
        if config.lab is not None:
            robot_name += f", lab {config.lab}"
        if config.day:
            robot_name += f", day {config.day}"
        if config.governor_fit is not None:
            robot_name += f", speed governor fitted to {config.governor_fit}"
        if config.start_range is not None:
            robot_name += f", chains placed within {config.start_range:g} m of the origin"
        if config.start_yaw is not None:
            robot_name += f", chains laid at {config.start_yaw:g} deg to the robot's facing"
        if config.segments != 1:
            robot_name += f", {config.segments} runs of the policy per episode"
        robot_name += "" if model == ARMS[arm] else f", {model}"
        if model in BAYES_MODELS and config.density is not None:
            robot_name += f" weighing pushes with {Path(config.density).name}"
        if model in BAYES_MODELS and config.bayes:
            robot_name += f" ({', '.join(f'{k}={v}' for k, v in sorted(config.bayes.items()))})"
        if model in BAYES_MODELS and config.check_reach:
            robot_name += ", pushes checked for reach"
        if model in BAYES_MODELS:  # its recorded estimates depend on it
            robot_name += ", speeds read" if config.read_speeds else ", speeds not read"
    arm_filter, filter_settings = None, None
    if model in BAYES_MODELS:
        arm_filter = FilterArm.load(
            model, get_setting(config.setting), config.seed, config.density, config.bayes
        )
        # The filter as configured, defaults included: the robot's name lists only the
        # options given, and a recording made under other defaults must not be reused.
        filter_settings = json.loads(json.dumps(arm_filter.filter.settings()))
    if path.exists() and counts.exists():
        kept = json.loads(counts.read_text())
        recording = read_recording(path)
        if (
            isinstance(kept, dict)
            and "by_class" in kept  # written by the protocol that never replaces episodes
            and sum(c["attempted"] for c in kept["by_class"].values()) == wanted
            and recording.robot == robot_name
            and kept.get("filter") == filter_settings
        ):
            if arm_filter is not None:
                arm_filter.close()
            return {"episodes": wanted, **kept, "reused": True}
    if arm_filter is not None:
        predictor = policy = arm_filter
    else:
        predictor, _, policy = model_and_policy(model, config.setting)
    # The arms' network calls are small: torch's thread pool only waits on them, and with
    # three runs side by side on two cores a filter-arm episode took 300 s instead of 34 s
    # (the recordings are the same; docs/notebook/2026-12-06-late-reach-weight.md).
    try:
        with one_thread():
            recording, failures, classes = record_classes(
                config, predictor, policy, robot_name, f"{config.world} world, {arm} pushes",
                progress, target, workers,
            )  # fmt: skip
    finally:
        if arm_filter is not None:
            arm_filter.close()
    write_recording(path, recording)
    kept = {"failed_pushes": failures, "by_class": classes}
    if filter_settings is not None:
        kept["filter"] = filter_settings
    counts.write_text(json.dumps(kept) + "\n")
    return {"episodes": wanted, **kept, "reused": False}


def arm_feature_kinds(model: str) -> tuple[str, ...]:
    """The kinds of features an arm's model gives the classifier: a particle filter has
    its estimate but no LSTM."""
    return ("estimate",) if model in BAYES_MODELS else FEATURE_KINDS


def score_arm(config: Sim2RealConfig, arm: str, path: Path) -> dict[str, Any]:
    """Cross-validated accuracy of the classifier on one arm's recording, with each kind
    of predictor feature, and the predictor's own error on it."""
    from masspush.data.recording import read_recording
    from masspush.learn.predictor import load_model
    from masspush.metrics import percentage_error
    from masspush.models import resolve_model
    from masspush.settings import get_setting

    recording = read_recording(path)
    model = config.models[arm]
    episodes = recording.to_episodes(_speed_reader(config))
    labels, classes = labelled(recording)
    kinds = arm_feature_kinds(model)
    scores: dict[str, Any] = {
        "model": model,
        "classes": classes,
        "ids": [e["id"] for e in recording.episodes],
        "labels": labels.tolist(),
        "kinds": list(kinds),
    }
    pushes = get_setting(config.setting).env_config().pushes
    segment = 0 if config.segments == 1 else pushes

    if model in BAYES_MODELS:
        # The filter's own estimates as it ran: its posterior after the first p pushes
        # (an episode lost earlier classified from those it has).
        recorded = [_recorded_estimates(e, path) for e in recording.episodes]

        def features(p: int | None, kind: str) -> tuple[np.ndarray, None]:
            at = [len(r) if p is None else min(p, len(r)) for r in recorded]
            return np.log([r[k - 1] for r, k in zip(recorded, at, strict=True)]), None

        estimate = np.array([r[-1] for r in recorded])
        cfg = config.classifier
    else:
        predictor, _ = load_model(resolve_model(model, config.setting), config.setting)
        cfg = replace(config.classifier, segment=segment)

        def features(p: int | None, kind: str) -> tuple[np.ndarray, np.ndarray]:
            shown = episodes if p is None else first_pushes(episodes, p)
            return classifier_inputs(predictor, shown, replace(cfg, features=kind))

        # Without any fine-tuning: how far the simulation-trained estimate is from the truth.
        estimate = np.exp(predictor_features(predictor, episodes, "estimate", segment))

    def score(p: int | None, kind: str) -> dict[str, Any]:
        rows, owner = features(p, kind)
        return cross_validate(rows, labels, len(classes), replace(cfg, features=kind), owner)

    for kind in kinds:
        scores[kind] = score(None, kind)
    tuned = None if config.tuned_density is None else config.sorting_density()
    if tuned is not None:
        # No classifier: Bayes' rule over the classes the density was tuned on, with
        # episodes of other chains (`masspush tune-density`).
        # All pushes read once for both the classes and the table's friction.
        evidence = sorting_evidence(tuned, recording, config.tuned_density)
        scores["posterior"] = score_posterior(evidence.classes, class_posterior(evidence.joint),
                                              recording, config.tuned_density)  # fmt: skip
        reading = pool_reading(friction_profiles(evidence), evidence.grid, config.tuned_density)
        check_drift(reading, tuned, f"tuned_density: {config.tuned_density}")
        calibration = calibration_friction(tuned)
        scores["table_friction"] = reading.as_dict() | (
            {} if calibration is None else {"change": reading.change(calibration)}
        )
    # The control: the start pose alone. Above chance only if which episodes were kept
    # depends on the class.
    scores["start_pose_control"] = start_pose_control(
        episodes, labels, len(classes), config.classifier
    )
    scores["percentage_error"] = percentage_error(estimate, episodes.mass_distribution)

    def sorted_right(p: int) -> float:
        return posterior_accuracy(tuned, recording, config.tuned_density, p)["accuracy"]

    if config.segments > 1:
        # What a lab that stopped after fewer runs would have got, from the same episodes
        # (all runs were scored above).
        scores["by_runs"] = [
            {"runs": runs, "pushes": runs * pushes}
            | {
                kind: scores[kind]["accuracy"]
                if runs == config.segments
                else score(runs * pushes, kind)["accuracy"]
                for kind in kinds
            }
            | ({} if tuned is None else {"posterior": sorted_right(runs * pushes)})
            for runs in run_counts(config.segments)
        ]
    return scores


def _recorded_estimates(episode: dict[str, Any], path: Path) -> np.ndarray:
    if "estimates" not in episode:
        raise ValueError(
            f"{path}: episode {episode['id']} has no estimates; a particle-filter arm is "
            "scored on the estimates it recorded (delete the file to record it again)"
        )
    return np.asarray(episode["estimates"], float)


def friction_words(reading: dict[str, Any]) -> str:
    """A `table_friction` score in a few words."""
    words = f"{reading['value']:.3f} ({reading['low']:.3f}-{reading['high']:.3f})"
    if reading.get("change") is not None:
        words += f", {100 * reading['change']:+.0f} % from the calibration's"
    return words


def run_counts(segments: int) -> list[int]:
    """1, 2, 4, ... runs, and all of them."""
    counts = [2**i for i in range(segments.bit_length()) if 2**i < segments]
    return [*counts, segments]


SUMMARY_FILE = "summary.json"
"""What `run_sim2real` writes in its output directory: the config and each arm's scores."""


def read_summary(run: str | Path) -> dict[str, Any]:
    """The summary `run_sim2real` wrote in the directory `run`; a one-line ValueError where
    there is none or it is not one."""
    path = Path(run) / SUMMARY_FILE
    if not path.is_file():
        raise ValueError(f"{run}: no {SUMMARY_FILE} (not a `masspush sim2real` run directory)")
    try:
        summary = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ValueError(f"{path} cannot be read as JSON: {' '.join(str(err).split())}") from None
    if not isinstance(summary, dict) or not {"config", "arms"} <= summary.keys():
        raise ValueError(f"{path} is not a `masspush sim2real` summary (no config and arms)")
    return summary


def run_sim2real(
    config: Sim2RealConfig, out_dir: str | Path, progress: bool = True, workers: Workers = None
) -> dict[str, Any]:
    """Both arms: record (or reuse; on `workers`) and score; writes summary.json and
    summary.md."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    results: dict[str, Any] = {"config": asdict(config), "arms": {}}
    for arm in ARMS:
        path = out / f"{arm}.jsonl"
        collected = record_arm(config, arm, path, progress, workers=workers)
        scores = score_arm(config, arm, path)
        for kind in scores["kinds"]:
            # Every attempted episode counts: one with no good push is a wrong answer.
            right = np.trace(np.array(scores[kind]["confusion"]))
            scores[kind]["accuracy_attempted"] = float(right / collected["episodes"])
        results["arms"][arm] = {**collected, **scores}
    random, learned = results["arms"]["random"], results["arms"]["learned"]
    # The same chains, so a paired comparison, on the episodes both arms kept.
    results["paired"] = {
        kind: paired_test(*paired_answers(learned, random, kind))
        for kind in FEATURE_KINDS
        if kind in random["kinds"] and kind in learned["kinds"]
    }
    (out / SUMMARY_FILE).write_text(json.dumps(results, indent=2) + "\n")
    (out / "summary.md").write_text(summary_markdown(results))
    if config.segments > 1:
        plot_accuracy_by_pushes({"": results}, out / "accuracy-by-pushes.png")
    return results


def paired_answers(
    first: dict[str, Any], second: dict[str, Any], kind: str = "estimate"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(true labels, `first`'s predictions, `second`'s) on the episodes both kept, paired by
    episode id: two arms' scores (`score_arm`) of one run, or one arm's of two runs that
    pushed the same chains. What `paired_test` reads."""
    both = sorted(set(first["ids"]) & set(second["ids"]))
    at_first, at_second = ([r["ids"].index(i) for i in both] for r in (first, second))
    return (
        np.array(first["labels"])[at_first],
        np.array(first[kind]["predicted"])[at_first],
        np.array(second[kind]["predicted"])[at_second],
    )


def sign_test(wins: int, losses: int) -> float:
    """Exact two-sided sign test: the p-value of so uneven a split of wins and losses (ties
    left out) if neither side were better."""
    n, k = wins + losses, min(wins, losses)
    tail = sum(math.comb(n, i) for i in range(k + 1)) / 2**n if n else 1.0
    return min(1.0, 2 * tail)


def paired_test(truth: np.ndarray, learned: np.ndarray, random: np.ndarray) -> dict[str, Any]:
    """Exact McNemar test on the same episodes classified after each arm's pushes: the
    episodes only one arm got right, and the two-sided p-value of so uneven a split if
    neither arm were better (the sign test on them)."""
    a, b = learned == truth, random == truth
    only_learned, only_random = int(np.sum(a & ~b)), int(np.sum(~a & b))
    return {
        "only_learned": only_learned,
        "only_random": only_random,
        "p_value": sign_test(only_learned, only_random),
    }


FEATURE_NAMES = {"estimate": "estimate features", "lstm": "LSTM features (paper's)",
                 "posterior": "class posterior of the tuned density"}  # fmt: skip


def plot_accuracy_by_pushes(runs: dict[str, dict[str, Any]], path: str | Path) -> Path:
    """Accuracy against pushes per episode for each arm, from `sim2real` results with
    `segments` > 1, a panel per kind of feature: one thin line per named result (e.g. per
    lab), and with several of them their mean in bold; the paper's real-robot accuracies
    dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    single = len(runs) == 1
    fig, axes = plt.subplots(1, len(FEATURE_KINDS), figsize=(12, 4.5), sharey=True)
    for ax, kind in zip(axes, FEATURE_KINDS, strict=True):
        for arm, colour in zip(ARMS, ("tab:grey", "tab:blue"), strict=True):
            curves = [r["arms"][arm]["by_runs"] for r in runs.values()]
            if any(kind not in c[0] for c in curves):
                continue  # a particle filter has no LSTM features
            pushes = [step["pushes"] for step in curves[0]]
            if any([step["pushes"] for step in c] != pushes for c in curves):
                raise ValueError("the results were not run with the same segments and setting")
            acc = 100 * np.array([[step[kind] for step in c] for c in curves])
            for name, row in zip(runs, acc, strict=True):
                model = runs[name]["arms"][arm].get("model", ARMS[arm])
                label = f"{arm} ({model}) {name}".strip() if single else None
                ax.plot(pushes, row, color=colour, lw=2 if single else 1, alpha=0.8,
                        marker="o", ms=3, label=label)  # fmt: skip
            if not single:
                ax.plot(pushes, acc.mean(0), color=colour, lw=3, marker="o",
                        label=f"{arm}, mean of {len(runs)}")  # fmt: skip
            ax.axhline(PAPER_ACCURACY[arm], color=colour, ls="--", lw=1,
                       label=f"paper, {arm} (real UR10, 2 pushes)")  # fmt: skip
        ax.axhline(90, color="tab:green", ls=":", lw=1, label="goal: 90 %")
        ax.set_xscale("log", base=2)
        ax.set_xticks(pushes, [str(p) for p in pushes])
        ax.set_xlabel("pushes per episode")
        ax.set_title(FEATURE_NAMES[kind])
        ax.set_ylim(0, 100)
    axes[0].set_ylabel("classifier accuracy, % (chance 20 %)")
    # Every line of any panel once (an arm without LSTM features is in the first only).
    shown: dict[str, Any] = {}
    for ax in axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            shown.setdefault(label, handle)
    axes[-1].legend(list(shown.values()), list(shown), fontsize=8, loc="lower right")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def reach_note(arms: dict[str, Any], stationary: bool = True) -> str:
    """A sentence for each filter arm whose pushes also valued leaving the chain room in
    the reach (`BayesConfig.reach_weight`, on by default for a stationary robot), which a
    reader of the summary would otherwise not see; "" for none, and where the robot is not
    `stationary` (its base follows the chain: no reach to weigh, the weight is unused)."""
    if not stationary:
        return ""
    notes = []
    for arm, r in arms.items():
        settings = r.get("filter") or {}
        if settings.get("reach_weight"):
            notes.append(
                f" The {arm} arm's filter also valued leaving the chain room in the reach from "
                f"push {settings.get('reach_from', 0) + 1} on (reach_weight "
                f"{settings['reach_weight']:g})."
            )
    return "".join(notes)


def summary_markdown(results: dict[str, Any]) -> str:
    """The accuracy table (ours beside the paper's) and each arm's confusion matrices."""
    config = results["config"]
    lines = [
        "| policy | model | accuracy, estimate features | accuracy, LSTM features (paper's) "
        "| paper (real UR10) | chance | start-pose control | predictor error, no fine-tuning "
        "| failed pushes |",
        "|---|---|---|---|---|---|---|---|---|",
    ]

    def percent(r: dict[str, Any], kind: str, key: str = "accuracy") -> str:
        return f"{100 * r[kind][key]:.1f} %" if kind in r else "-"

    for arm, r in results["arms"].items():
        lines.append(
            f"| {arm} | {r['model']} | {percent(r, 'estimate')} "
            f"| {percent(r, 'lstm')} | {PAPER_ACCURACY[arm]:.1f} % "
            f"| {100 * r['estimate']['chance']:.0f} % "
            f"| {100 * r['start_pose_control']['accuracy']:.1f} % | {r['percentage_error']:.2f} "
            f"| {sum(r.get('failed_pushes', {}).values())} |"
        )
    lines += ["", "Accuracy is over the episodes kept (at least one good push), each classified "
              "from the pushes it has; no episode is replaced. The start-pose control is the "
              "same classifier given only each episode's start pose: above chance, which "
              "episodes were kept depends on the class. "
              + ("The models read each push at the speed the robot reported (--read-speeds)."
                 if config.get("read_speeds", False) else
                 "The models read each push as commanded (--no-read-speeds).")
              + ("" if config.get("start_range") is None else
                 f" Chains placed within {config['start_range']:g} m of the origin "
                 f"(--start-range).")
              + ("" if config.get("start_yaw") is None else
                 f" Chains laid with the first link at {config['start_yaw']:g} degrees to "
                 f"the direction the robot faces (--start-yaw).")
              + (" The filter arm pushed the best candidate the arm could reach "
                 "(--check-reach)." if config.get("check_reach") else "")
              + reach_note(results["arms"], _robot_facing(config["setting"]) is not None), "",
              "| policy | class | attempted | kept | lost the chain | failed otherwise "
              "| good pushes per episode |", "|---|---|---|---|---|---|---|"]  # fmt: skip
    for arm, r in results["arms"].items():
        for label, c in r.get("by_class", {}).items():
            lines.append(
                f"| {arm} | {label} | {c['attempted']} | {c['kept']} | {c['lost']} "
                f"| {c['failed']} | {c['good_pushes'] / max(c['attempted'], 1):.1f} |"
            )
        if "accuracy_attempted" in r["estimate"]:
            lines.append(
                f"| {arm} | all, counting an episode without a good push as wrong | | | | "
                f"| accuracy {percent(r, 'estimate', 'accuracy_attempted')} (estimate), "
                f"{percent(r, 'lstm', 'accuracy_attempted')} (LSTM) |"
            )
    if config["segments"] > 1:
        reading = {"each": "each run classified on its own, an episode's runs' log-probabilities "
                   "added up", "average": "the runs' features averaged"}  # fmt: skip
        lines += ["", f"{config['segments']} runs of the policy per episode; "
                  f"{reading[config['classifier']['runs']]}."]  # fmt: skip
    sorted_by = {arm: r["posterior"]["accuracy"] for arm, r in results["arms"].items()
                 if "posterior" in r}  # fmt: skip
    if sorted_by:
        each = ", ".join(f"{arm} {100 * a:.1f} %" for arm, a in sorted_by.items())
        lines += ["", "Sorted by the class posterior of the push density tuned to the lab ("
                  f"{config.get('tuned_density')}, --tuned-density; no classifier trained on "
                  f"these episodes): {each}."]  # fmt: skip
        read = {arm: r["table_friction"] for arm, r in results["arms"].items()
                if "table_friction" in r}  # fmt: skip
        if read:
            lines.append(
                "The table's friction as that density reads it, with a 90 % interval "
                "(docs/real-robot.md, 'Another day in the lab'): "
                + "; ".join(f"{arm} {friction_words(f)}" for arm, f in read.items())
                + "."
            )
    for kind, p in results.get("paired", {}).items():
        lines += ["", f"Paired (the same chains), {FEATURE_NAMES[kind]}: {p['only_learned']} "
                  f"episodes only the learned policy's got right, {p['only_random']} only the "
                  f"random pushes'; exact McNemar p = {p['p_value']:.2g}."]  # fmt: skip
    by_runs = {arm: r["by_runs"] for arm, r in results["arms"].items() if "by_runs" in r}
    if by_runs:
        columns = [(arm, kind) for arm in by_runs for kind in (*FEATURE_KINDS, "posterior")
                   if kind in by_runs[arm][0]]  # fmt: skip
        steps = next(iter(by_runs.values()))
        lines += ["", "Accuracy had each episode stopped after fewer runs of the policy:", "",
                  "| pushes per episode | "
                  + " | ".join(f"{arm}, {FEATURE_NAMES[kind]}" for arm, kind in columns) + " |",
                  "|---" * (len(columns) + 1) + "|"]  # fmt: skip
        for i, step in enumerate(steps):
            lines.append(
                f"| {step['pushes']} ({step['runs']} run{'s' * (step['runs'] > 1)}) | "
                + " | ".join(f"{100 * by_runs[arm][i][kind]:.1f} %" for arm, kind in columns)
                + " |"
            )
    for arm, r in results["arms"].items():
        classes = r["classes"]
        for kind in r.get("kinds", FEATURE_KINDS):
            lines += ["", f"Confusion, {arm} policy, {FEATURE_NAMES[kind]} (rows: truth, "
                      "columns: predicted; masses in kg):", "",
                      "| truth \\ predicted | " + " | ".join(classes) + " |",
                      "|---" * (len(classes) + 1) + "|"]  # fmt: skip
            for label, row in zip(classes, r[kind]["confusion"], strict=True):
                lines.append(f"| {label} | " + " | ".join(str(v) for v in row) + " |")
    return "\n".join(lines) + "\n"
