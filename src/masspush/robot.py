"""The robot interface: what a lab implements to run masspush on its own arm.

A `Robot` starts an episode with a chain lying still on the table and reports its rest
configuration, then executes pushes one at a time, each followed by waiting for the chain
to come to rest and observing it again. masspush owns everything else: which push to make
(a policy), what the pushes say about the masses (a predictor), and the record of it all.

Backends here: `SimRobot` (the simulated stiff pusher, KUKA or UR10), `TargetWorldRobot`
(a simulated world unlike training, `masspush.target_world`) and `ReplayRobot` (plays back
a recorded session, `masspush.recording`). A hardware backend is a class with
the same three methods; docs/real-robot.md shows one.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from masspush.rollout import Episodes


@dataclass(frozen=True)
class RestPose:
    """The chain at rest, as observed: table frame, metres and radians."""

    config: np.ndarray
    """(3 + n - 1,): x, y of the first link's centre, its yaw, then the joint angles."""
    lengths: np.ndarray
    """(n,): link lengths, m."""


@dataclass(frozen=True)
class PushReport:
    """What happened in one push."""

    config: np.ndarray | None
    """The rest configuration after the push; None when it failed."""
    failure: str | None = None
    """None, or why the push failed (the chain tipped over, left the table, was hit by
    something other than the tool): the episode ends there."""
    details: dict[str, Any] = field(default_factory=dict)
    """Backend-specific extras (the simulation reports the executed push, settle time)."""


class Robot(Protocol):
    """A robot that pushes a chain and observes it at rest."""

    n_links: int

    def start(self) -> RestPose:
        """Begin an episode: the chain is on the table, at rest; observe it."""

    def push(self, action: np.ndarray) -> PushReport:
        """Execute the push for `action` (in [-1, 1]^2, docs/real-robot.md), wait until the
        chain is at rest, observe it."""

    def close(self) -> None:
        """Release the hardware."""


class SimRobot:
    """The simulation as a robot: each `start` places a new random chain of the setting."""

    def __init__(
        self,
        setting,
        pusher: str | None = None,
        seed: int = 0,
        masses: tuple[float, ...] | None = None,
        pushes: int | None = None,
    ):
        from dataclasses import replace

        from masspush.env import ChainEnv
        from masspush.settings import get_setting

        self.setting = get_setting(setting) if isinstance(setting, str) else setting
        self.pusher = pusher or self.setting.pusher
        config = self.setting.env_config(self.pusher)
        # The environment ends an episode after the setting's pushes unless told otherwise
        # (runs of the policy, `run_segments`, push on).
        if pushes is not None:
            config = replace(config, pushes=pushes)
        self.env = ChainEnv.from_config(config)
        self.n_links = self.setting.n_links
        self.seed = seed
        self.options = None if masses is None else {"masses": list(masses)}
        """Pinned link masses (kg) for every chain, e.g. to record a labelled class."""
        self.truth: dict[str, Any] = {}
        """The current chain's hidden parameters (masses, friction), for scoring only."""

    def start(self) -> RestPose:
        while True:
            obs, info = self.env.reset(seed=self.seed, options=self.options)
            self.seed += 1
            if info["failure"] is None:
                break
        self.truth = {k: info[k] for k in ("masses", "mass_distribution", "friction")}
        self.truth["config"] = info["config"]
        return RestPose(obs[: self.env.physics.obs_dim].copy(), info["lengths"].copy())

    def push(self, action: np.ndarray) -> PushReport:
        obs, _, _, _, info = self.env.step(np.asarray(action, np.float32))
        details = {**info["push"], "settle_time": info["settle_time"], "config": info["config"]}
        if info["failure"] is not None:
            return PushReport(None, info["failure"], details)
        return PushReport(obs[: self.env.physics.obs_dim].copy(), None, details)

    def close(self) -> None:
        self.env.close()


class ReplayMismatchError(RuntimeError):
    """A replayed session was asked for a push other than the one recorded."""


class ReplayRobot:
    """Plays back a recorded session: `start` gives the next episode's first rest pose,
    `push` the recorded rest pose after the recorded push. Asking for another push than the
    recorded one is refused: what would have happened is not in the file."""

    def __init__(self, recording: str | os.PathLike, tolerance: float = 1e-4):
        from masspush.recording import read_recording

        self.recording = read_recording(recording)
        self.n_links = self.recording.n_links
        self.tolerance = tolerance
        self._next = 0
        self.episode: dict[str, Any] | None = None
        self._k = 0

    @property
    def recorded_actions(self) -> np.ndarray:
        """The current episode's recorded actions (what a `RecordedPolicy` replays)."""
        assert self.episode is not None, "start() first"
        return np.asarray(self.episode["actions"], np.float32)

    def start(self) -> RestPose:
        if self._next >= len(self.recording.episodes):
            raise StopIteration("every recorded episode has been replayed")
        self.episode = self.recording.episodes[self._next]
        self._next += 1
        self._k = 0
        observations = np.asarray(self.episode["observations"], np.float32)
        return RestPose(observations[0], np.asarray(self.episode["lengths"], np.float32))

    def push(self, action: np.ndarray) -> PushReport:
        assert self.episode is not None, "start() first"
        actions = self.recorded_actions
        if self._k >= len(actions):
            raise ReplayMismatchError(
                f"episode {self.episode['id']!r} has only {len(actions)} recorded pushes"
            )
        if np.max(np.abs(np.asarray(action) - actions[self._k])) > self.tolerance:
            raise ReplayMismatchError(
                f"episode {self.episode['id']!r}, push {self._k + 1}: asked for "
                f"{np.round(action, 4).tolist()}, recorded {actions[self._k].tolist()}; "
                "replay with the recorded pushes (policy 'recorded')"
            )
        self._k += 1
        config = np.asarray(self.episode["observations"][self._k], np.float32)
        return PushReport(config, None, {"id": self.episode["id"]})

    def close(self) -> None:
        pass


class RecordedPolicy:
    """The pushes a `ReplayRobot`'s current episode recorded, as a rollout Policy."""

    name = "recorded"

    def __init__(self, robot: ReplayRobot):
        self.robot = robot

    def reset(self, seeds: np.ndarray) -> None:
        pass

    def act(self, observations, actions, step, lengths) -> np.ndarray:
        return self.robot.recorded_actions[step][None]


@dataclass
class EstimationEpisode:
    """One episode run through a robot: what was seen, done and estimated."""

    start: RestPose
    actions: list[np.ndarray] = field(default_factory=list)
    reports: list[PushReport] = field(default_factory=list)
    estimates: list[np.ndarray] = field(default_factory=list)
    run_estimates: list[np.ndarray] = field(default_factory=list)
    """Each run's last estimate, when the episode is runs of the policy (`run_segments`)."""

    @property
    def failure(self) -> str | None:
        return self.reports[-1].failure if self.reports else None

    def recorded(self, **fields: Any) -> dict[str, Any]:
        """The episode as a recording's episode (`masspush.recording`): its successful
        pushes and rest poses, plus `fields` (id, label, masses...)."""
        configs = [r.config for r in self.reports if r.config is not None]
        return {
            **fields,
            "lengths": self.start.lengths,
            "observations": [self.start.config, *configs],
            "actions": self.actions[: len(configs)],
        }

    def history(self) -> Episodes:
        """The successful pushes so far, in the predictor's input format."""
        configs = [self.start.config] + [r.config for r in self.reports if r.config is not None]
        k = len(configs) - 1
        return Episodes.history(
            np.asarray(configs, np.float32)[None],
            np.asarray(self.actions[:k], np.float32).reshape(1, k, 2),
            self.start.lengths[None].astype(np.float32),
        )


BACKENDS = ("target", "replay")
"""Robot backends besides the simulated pushers."""

PushCallback = Callable[[int, np.ndarray, PushReport, "np.ndarray | None"], None]


def run_estimation(
    robot: Robot,
    predictor,
    policy,
    pushes: int,
    on_push: PushCallback | None = None,
    start: RestPose | None = None,
    seed: int = 0,
) -> EstimationEpisode:
    """One episode: the policy picks each push from what has been seen, the robot executes
    it, and the predictor estimates the mass distribution after it. `on_push(k, action,
    report, estimate)` hears of every push as it happens (estimate None for a failed push);
    `start` is the episode's first rest pose when the caller has started the robot."""
    rest = start if start is not None else robot.start()
    episode = EstimationEpisode(rest)
    d = len(rest.config)
    observed = np.full((1, pushes + 1, d), np.nan, np.float32)
    chosen = np.full((1, pushes, 2), np.nan, np.float32)
    observed[0, 0] = rest.config
    lengths = rest.lengths[None].astype(np.float32)
    policy.reset(np.array([seed], np.uint64))
    for k in range(pushes):
        action = np.asarray(policy.act(observed, chosen, k, lengths)[0], np.float32)
        result = robot.push(action)
        episode.actions.append(action)
        episode.reports.append(result)
        estimate = None
        if result.failure is None:
            chosen[0, k], observed[0, k + 1] = action, result.config
            estimate = predictor.predict(episode.history())[0, -1]
            episode.estimates.append(estimate)
        if on_push is not None:
            on_push(k, action, result, estimate)
        if result.failure is not None:
            break
    return episode


def run_segments(
    robot: Robot,
    predictor,
    policy,
    pushes: int,
    segments: int,
    on_push: PushCallback | None = None,
    seed: int = 0,
) -> EstimationEpisode:
    """`segments` episodes of `pushes` pushes in a row on the same chain, each starting where
    the last one left it, the policy and the predictor starting afresh each time: one
    episode of up to segments x pushes pushes (`masspush.finetune.segments_of` cuts it back).
    Its estimates are each segment's own. With one segment this is `run_estimation`."""
    if segments < 1:
        raise ValueError(f"segments must be >= 1, got {segments}")
    rest = robot.start()
    whole = EstimationEpisode(rest)
    for s in range(segments):
        told = None if on_push is None else _numbered_from(s * pushes, on_push)
        part = run_estimation(
            robot, predictor, policy, pushes, told, start=rest, seed=seed * segments + s
        )
        whole.actions += part.actions
        whole.reports += part.reports
        whole.estimates += part.estimates
        whole.run_estimates += part.estimates[-1:]
        if part.failure is not None:
            break
        rest = RestPose(part.reports[-1].config, rest.lengths)
    return whole


def _numbered_from(first: int, on_push: PushCallback) -> PushCallback:
    """`on_push` hearing a run's pushes numbered on from `first`."""

    def told(k, action, report, estimate) -> None:
        on_push(first + k, action, report, estimate)

    return told


def print_push(k: int, action: np.ndarray, result: PushReport, estimate) -> None:
    """The plain report of a push, for `masspush run`."""
    if result.failure is not None:
        print(f"push {k + 1}: a={fmt(action, 2)} failed ({result.failure})")
        return
    print(f"push {k + 1}: a={fmt(action, 2)} -> at rest q{k + 1} = {fmt(result.config)}")
    print(f"  estimate {fmt(estimate)}")


def make_robot(
    backend: str,
    setting,
    recording: str | None = None,
    seed: int = 0,
    masses: tuple[float, ...] | None = None,
    lab: int | None = None,
) -> Robot:
    """A robot by backend name: stiff, kuka, ur10 (simulated), target (the sim-to-real
    target world, `masspush.target_world`; `lab` keeps one lab's constants) or replay (a
    recording)."""
    from masspush.pusher import PUSHERS

    if lab is not None and backend != "target":
        raise ValueError(f"a lab is one draw of the target world; backend {backend!r} has none")
    if backend in PUSHERS:
        return SimRobot(setting, backend, seed, masses)
    if backend == "target":
        from masspush.target_world import TargetWorldRobot

        return TargetWorldRobot(setting, seed=seed, masses=masses, lab=lab)
    if backend == "replay":
        if recording is None:
            raise ValueError("the replay backend needs --episodes FILE (a recording)")
        return ReplayRobot(recording)
    raise ValueError(f"unknown robot backend {backend!r}; known: {[*PUSHERS, *BACKENDS]}")


def fmt(values, digits: int = 3) -> str:
    """Numbers as a short signed list, for reports."""
    return "[" + ", ".join(f"{v:+.{digits}f}" for v in np.asarray(values, dtype=float)) + "]"
