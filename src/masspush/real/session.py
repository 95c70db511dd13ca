"""`masspush run`: estimation episodes through a robot backend, reported push by push, and
optionally written to a recording."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from masspush.bayes.estimator import BAYES_MODELS
from masspush.config import (
    SEED_MAX,
    ChainGeometry,
    check_input,
    check_int,
    check_match,
    check_output,
)
from masspush.data.recording import Recording, read_recording, write_recording
from masspush.learn.policy import model_policy
from masspush.learn.predictor import load_model
from masspush.models import resolve_model
from masspush.real.backends import (
    BACKENDS,
    RecordedPolicy,
    check_lab_robot_name,
    is_lab_robot,
    make_robot,
)
from masspush.real.filter_arm import FilterArm, check_bayes_options
from masspush.real.governor import fitted_setting_governor
from masspush.real.robot import (
    Robot,
    check_geometry,
    fmt,
    model_speed_reader,
    print_push,
    run_segments,
    speed_reader,
)
from masspush.settings import Setting, get_setting
from masspush.sim.pushers import PUSHERS, reach_governor
from masspush.sim.workspace import ReachGovernor

SESSION_SEEDS = 1_000_000
"""Seeds each session's `--seed` owns: its chains are drawn from SESSION_SEEDS * seed on, one
or more seeds each (a chain that fails at rest is redrawn with the next), so sessions with
seeds S and S + 1 share no chain. Before 2026-12-06 they began at the seed itself and
shared all but one chain (docs/notebook/2026-12-06-overlapping-seeds.md)."""


@dataclass(frozen=True)
class SessionConfig:
    """`masspush run`: estimation episodes through a robot: simulated, replayed or your own."""

    robot: str
    """The backend: stiff, kuka, ur10 (simulated), target (the sim-to-real world), replay, or
    your own robot as package.module:factory (called with the setting, it returns your
    `Robot`; docs/real-robot.md)."""
    setting: str
    """Named setting, e.g. 2link-0.1-1."""
    model: str = "tp+"
    """Shipped model name (rp, rp+, tp, tp+), a model file, or the particle filter (bayes:
    its information-seeking pushes and estimates; bayes-random: random pushes)."""
    episodes_file: str | None = None
    """replay: the recording to play."""
    count: int | None = None
    """Episodes to run (default: 1; replay: all of the recording's)."""
    pushes: int | None = None
    """Pushes per episode (per run with --segments; default: the setting's; replay: each
    episode's recorded pushes)."""
    seed: int = 0
    """The simulated chains' seed; sessions with other seeds never share a chain."""
    record: str | None = None
    """Write the session to this recording (appended to one of the same setting)."""
    masses: tuple[float, ...] | None = None
    """The link masses, kg (m1,m2,...): simulated robots pin them; for your own robot, the
    chain's known masses, written into the recording (tune-density needs them)."""
    label: str | None = None
    """Class label written into the recording."""
    allow_out_of_range: bool = False
    """Simulated robots: accept --masses outside the setting's mass range (the model was
    not trained on such chains)."""
    allow_mismatch: bool = False
    """Use a model, or replay a recording, of another setting or pusher (same number of
    links)."""
    segments: int = 1
    """Run the policy this many times in a row on each chain (each --pushes pushes) and
    average the runs' estimates."""
    lab: int | None = None
    """target: keep one lab's table, calibration, robot and chains (drawn from this seed)
    for every episode."""
    day: int = 0
    """target, with lab: which day in the lab (0 the day it was calibrated; another, a day
    whose table friction, speed gain and tracker calibration have drifted)."""
    settings_file: str | None = None
    """TOML file with custom settings."""
    read_speeds: bool = True
    """The model reads each push the robot reports the speed of as the action at which its
    own pusher would have moved at that speed (`masspush.real.robot.speed_reader`);
    --no-read-speeds: as the action commanded."""
    governor_fit: str | None = None
    """Fit the robot's speed governor to the random pushes recorded in this file (your
    table's slides; docs/real-robot.md, 'A stationary robot'): a stationary robot's
    sessions after the first."""
    bayes: dict[str, Any] | None = None
    """`BayesConfig` fields changed for the particle filter (model bayes or bayes-random;
    `masspush run --bayes KEY=VALUE`), e.g. {"reach_weight": 0} for pushes chosen for their
    information alone on a stationary robot."""

    def __post_init__(self) -> None:
        check_bayes_options(self.bayes, self.model in BAYES_MODELS)
        known = (*PUSHERS, *BACKENDS)
        if is_lab_robot(self.robot):
            check_lab_robot_name(self.robot)
        elif self.robot not in known:
            raise ValueError(
                f"robot must be one of {list(known)} or package.module:factory (your own), "
                f"got {self.robot!r}"
            )
        check_int("count", self.count, optional=True)
        check_int("pushes", self.pushes, optional=True)
        check_int("seed", self.seed, 0, high=SEED_MAX)
        check_int("segments", self.segments)
        check_int("lab", self.lab, 0, optional=True)
        if self.lab is not None and self.robot != "target":
            raise ValueError(f"lab is one draw of the target world; robot {self.robot!r} has none")
        check_int("day", self.day, 0, high=SEED_MAX)
        if self.day and self.lab is None:
            raise ValueError("day is a day in one lab: pass --lab too")
        if self.episodes_file is not None and self.robot != "replay":
            raise ValueError(f"episodes_file is for the replay robot, not {self.robot!r}")
        if self.robot == "replay":
            if self.episodes_file is None:
                raise ValueError("the replay backend needs --episodes-file (a recording)")
            check_input(self.episodes_file, "episodes_file")
            if self.masses is not None:
                raise ValueError("masses pins a simulated chain's masses; a replay has its own")
            if self.segments != 1:
                raise ValueError(
                    "segments runs the policy again; a replay plays its recorded pushes"
                )
            if self.model in BAYES_MODELS:
                raise ValueError(
                    f"model {self.model}: the particle filter here chooses its own pushes; a "
                    "replay plays recorded ones"
                )
        if self.masses is not None and not all(np.isfinite(m) and m > 0 for m in self.masses):
            raise ValueError(f"masses must be positive, got {list(self.masses)}")
        if self.label is not None and not self.label.isprintable():
            raise ValueError(f"label must be printable text, got {self.label!r}")
        if self.record is not None:
            check_output(self.record, "record")
        if self.governor_fit is not None:
            if self.robot == "replay":
                raise ValueError("governor_fit slows the pushes a robot makes; a replay's are made")
            check_input(self.governor_fit, "governor_fit")


def run_session(config: SessionConfig, say: Callable[[str], object] = print) -> list[dict]:
    """Run the episodes, `say`ing each push and estimate; returns the episodes as a
    recording's (written to `config.record` where given)."""
    setting = get_setting(config.setting, config.settings_file)
    if config.masses is not None:
        if len(config.masses) != setting.n_links:
            raise ValueError(
                f"masses: {len(config.masses)} given, setting has {setting.n_links} links"
            )
        lo, hi = setting.mass_range
        if not config.allow_out_of_range and not all(lo <= m <= hi for m in config.masses):
            raise ValueError(
                f"masses {list(config.masses)} outside setting {setting.name!r}'s mass range "
                f"[{lo:g}, {hi:g}]; pass --allow-out-of-range to simulate them anyway"
            )
    existing = _recording_to_extend(config.record, setting)
    filter_arm = None
    if config.model in BAYES_MODELS:
        predictor = filter_arm = FilterArm.load(
            config.model, setting, config.seed, overrides=config.bayes
        )
        read_speed = speed_reader(setting.pusher, setting.physics())
    else:
        path = resolve_model(config.model, setting.name)
        predictor, meta = load_model(
            path, setting.name, allow_mismatch=config.allow_mismatch, n_links=setting.n_links
        )
        read_speed = model_speed_reader(meta)
    if not config.read_speeds:
        read_speed = None
    pushes = setting.env_config().pushes if config.pushes is None else config.pushes
    fitted = None  # fitted before any robot is made: a bad recording stops nothing running
    if config.governor_fit is not None:
        fitted = fitted_setting_governor(setting, config.governor_fit)
    first = SESSION_SEEDS * config.seed
    robot = make_robot(
        config.robot, setting, config.episodes_file, first,
        config.masses, config.lab, config.allow_out_of_range, pushes * config.segments,
        config.day,
    )  # fmt: skip
    try:
        if robot.n_links != setting.n_links:
            raise ValueError(
                f"the robot's chain has {robot.n_links} links, setting {setting.name!r} has "
                f"{setting.n_links}"
            )
        _govern(robot, setting, config, fitted, say)
        # The chain as measured: your robot's, or the one a replayed recording names.
        geometry = getattr(robot, "geometry", None)
        if geometry is not None and not isinstance(geometry, ChainGeometry):
            raise ValueError(
                f"robot {config.robot!r}: its geometry is a {type(geometry).__name__}, not a "
                "masspush.config.ChainGeometry"
            )
    except ValueError:
        robot.close()
        raise
    if geometry is not None and filter_arm is None:
        check_geometry(meta, geometry)
    if config.robot == "replay":
        try:
            _check_replay(robot.recording, setting, config)
        except ValueError:
            robot.close()
            raise
        policy = RecordedPolicy(robot)
        count = len(robot.recording.episodes) if config.count is None else config.count
        # A replay plays every recorded push unless --pushes asks for fewer.
        episode_pushes = [
            len(e["actions"]) if config.pushes is None else config.pushes
            for e in robot.recording.episodes[:count]
        ]
        which = "" if config.pushes is None else f", the first {config.pushes} of each"
        say(f"Replaying {count} recorded episode(s) with their recorded pushes{which}.")
    elif filter_arm is not None:
        # Its candidates are compared as this robot makes them (a stationary one's governor).
        filter_arm.governor = getattr(robot, "governor", None)
        policy, count = filter_arm, config.count or 1
        episode_pushes = [pushes] * count
        which = "information-seeking" if filter_arm.seeking is not None else "random"
        say(f"Pushes chosen by the particle filter ({which}); its estimate keeps every push.")
    else:
        policy, count = model_policy(meta, path), config.count or 1
        episode_pushes = [pushes] * count
        say(f"Pushes chosen by the {policy.name} policy of model {config.model!r}.")
    target = existing
    if config.record and target is None:
        robot_name = config.robot if is_lab_robot(config.robot) else (
            f"masspush simulation ({config.robot})")  # fmt: skip
        if config.lab is not None:
            robot_name += f", lab {config.lab}" + (f", day {config.day}" if config.day else "")
        if config.governor_fit is not None:
            robot_name += f", speed governor fitted to {config.governor_fit}"
        target = Recording(setting.n_links, robot=robot_name, setting=setting.name,
                           geometry=geometry)  # fmt: skip
    recorded = []
    before = 0 if target is None else len(target.episodes)
    try:
        for i in range(count):
            say(f"episode {i + 1}:")
            episode = run_segments(
                robot, predictor, policy, episode_pushes[i], config.segments, print_push,
                seed=first + i, read_speed=read_speed,
            )  # fmt: skip
            if len(episode.run_estimates) > 1 and filter_arm is None:
                mean = np.mean(episode.run_estimates, axis=0)
                say(f"  estimate {fmt(mean)}, averaged over {len(episode.run_estimates)} runs")
            truth = getattr(robot, "truth", {})
            if "mass_distribution" in truth:
                say(f"  truth    {fmt(truth['mass_distribution'])}")
            masses = truth.get("masses", config.masses)  # your robot's: the ones you stated
            recorded.append(episode.recorded(id="", masses=masses, label=config.label))
            if target is not None and len(recorded[-1]["actions"]):
                # Written as each episode ends: a session stopped part way (a long one on a
                # real robot) keeps every episode it finished.
                _append(config.record, target, recorded[-1])
    finally:
        robot.close()
        if filter_arm is not None:
            filter_arm.close()
        if target is not None:
            say(f"recorded {len(target.episodes) - before} episode(s) to {config.record} "
                f"({len(target.episodes)} in all)")  # fmt: skip
    return recorded


def _govern(
    robot: Robot, setting: Setting, config: SessionConfig, fitted: ReachGovernor | None,
    say: Callable,
) -> None:  # fmt: skip
    """Give the robot the speed governor its pushes go through: your own robot without a
    `governor` attribute the setting's (its models were trained with it); where
    `config.governor_fit` named a recording, the setting's `fitted` to it."""
    if is_lab_robot(config.robot) and not hasattr(robot, "governor"):
        robot.governor = reach_governor(setting.pusher, setting.physics())
        if robot.governor is not None:
            say(f"Your robot has no governor: it gets {setting.name}'s, as its models were "
                "trained (docs/real-robot.md, 'A stationary robot').")  # fmt: skip
    if fitted is not None:
        if getattr(robot, "governor", None) is None:
            raise ValueError(
                f"governor_fit: robot {config.robot!r} follows the chain; only a stationary "
                "robot has a speed governor"
            )
        robot.governor = fitted
        say(f"Speed governor fitted to the pushes in {config.governor_fit}.")


def _check_replay(recording: Recording, setting: Setting, config: SessionConfig) -> None:
    """A replay plays its recording's pushes as they were: the recording must be of this
    setting, and hold at least the pushes asked for in every episode it plays."""
    where = str(config.episodes_file)
    check_match("setting", where, recording.setting, setting.name, config.allow_mismatch)
    if config.count is not None and config.count > len(recording.episodes):
        raise ValueError(
            f"count: {config.episodes_file} holds {len(recording.episodes)} episode(s), "
            f"not {config.count}"
        )
    if config.pushes is not None:
        for e in recording.episodes[: config.count]:
            if len(e["actions"]) < config.pushes:
                raise ValueError(
                    f"pushes: episode {e['id']!r} of {config.episodes_file} recorded "
                    f"{len(e['actions'])} push(es), not {config.pushes}; leave --pushes out "
                    "to play each episode's own"
                )


def _recording_to_extend(path: str | None, setting: Setting) -> Recording | None:
    """The recording a session will append to, checked before any push: of this setting."""
    if path is None or not Path(path).exists():
        return None
    recording = read_recording(path)
    if recording.n_links != setting.n_links or (
        recording.setting is not None and recording.setting != setting.name
    ):
        raise ValueError(
            f"{path} holds episodes of setting {recording.setting!r} "
            f"({recording.n_links} links); not appending episodes of {setting.name!r}"
        )
    return recording


def _append(path: str, recording: Recording, episode: dict) -> None:
    """Add one episode to the recording (named for its class and its place in the file, so
    that a file gathering several sessions, e.g. one per class, keeps its ids unique) and
    write the file."""
    episode["id"] = f"{episode.get('label') or 'episode'}-{len(recording.episodes) + 1:04d}"
    recording.episodes.append(episode)
    try:
        write_recording(path, recording)
    except (OSError, ValueError):
        recording.episodes.pop()  # not written: not counted as recorded
        raise
