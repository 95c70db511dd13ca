"""The robot interface: what a lab implements to run masspush on its own arm.

A `Robot` starts an episode with a chain lying still on the table and reports its rest
configuration, then executes pushes one at a time, each followed by waiting for the chain
to come to rest and observing it again. masspush owns everything else: which push to make
(a policy), what the pushes say about the masses (a predictor), and the record of it all.

Backends (`masspush.real.backends`): `SimRobot` (the simulated stiff pusher, KUKA or
UR10), `TargetWorldRobot` (a simulated world unlike training, `masspush.real.target_world`)
and `ReplayRobot` (plays back a recorded session, `masspush.data.recording`). A hardware
backend is a class with the same three methods; docs/real-robot.md shows one.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from masspush.config import ChainGeometry, PhysicsConfig
from masspush.data.recording import SpeedReader
from masspush.data.rollout import Episodes, Policy


class GeometryWarning(UserWarning):
    """A chain (or tool) of another geometry than the model was trained for."""


def model_physics(meta: dict[str, Any]) -> PhysicsConfig:
    """The physics a model (its metadata) was trained in."""
    from masspush.settings import Setting

    known = {"name", "n_links", "mass_range", "overrides"}
    return Setting(**{k: v for k, v in meta["setting"].items() if k in known}).physics()


def model_geometry(meta: dict[str, Any]) -> ChainGeometry:
    """The chain geometry and tool radius a model (its metadata) was trained for."""
    from masspush.sim.pushers import tool_radius

    physics = model_physics(meta)
    return ChainGeometry(
        physics.link_width,
        physics.link_height,
        physics.joint_gap,
        tool_radius(meta.get("pusher", "stiff"), physics),
    )


def speed_reader(pusher: str, physics: PhysicsConfig) -> SpeedReader | None:
    """How models trained with `pusher` in `physics` read a push the robot reports the speed
    of: as the action at which their pusher would have moved at that speed
    (`masspush.sim.SpeedEquivalent.action`); None where that pusher's plan does not set its
    speed (an arm limited by its torques alone)."""
    from masspush.sim.pushers import speed_equivalent

    equivalent = speed_equivalent(pusher, physics)
    return None if equivalent is None else equivalent.action


def model_speed_reader(meta: dict[str, Any]) -> SpeedReader | None:
    """`speed_reader` for the model of metadata `meta`: its pusher, its physics."""
    return speed_reader(meta.get("pusher", "stiff"), model_physics(meta))


def check_geometry(meta: dict[str, Any], geometry: ChainGeometry, tolerance: float = 1e-3) -> None:
    """Warn (`GeometryWarning`) where a lab's measured chain and tool differ from what the
    model was trained for by more than `tolerance` m: its pushes land where the model
    expects, but the chain answers as another chain would."""
    differences = model_geometry(meta).differences(geometry, tolerance)
    if differences:
        warnings.warn(
            "the model was trained for another chain geometry (model vs yours): "
            + "; ".join(differences)
            + " (docs/real-robot.md, 'Your chain's geometry')",
            GeometryWarning,
            stacklevel=2,
        )


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
    speed: float | None = None
    """The push's speed as executed, m/s, where the robot knows it: the tool's top speed
    along the push before the hold ended (docs/real-robot.md, "The push as executed")."""


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

    # Optional: `governor`, a callable (action, observed config, lengths) -> action that
    # slows pushes which could carry the chain out of a stationary robot's reach
    # (`masspush.sim.ReachGovernor`; `reach_governor(pusher, physics)` makes the simulated
    # UR10's). `run_estimation` passes every action through it before `push`.


@dataclass
class EstimationEpisode:
    """One episode run through a robot: what was seen, done and estimated."""

    start: RestPose
    actions: list[np.ndarray] = field(default_factory=list)
    reports: list[PushReport] = field(default_factory=list)
    estimates: list[np.ndarray] = field(default_factory=list)
    run_estimates: list[np.ndarray] = field(default_factory=list)
    """Each run's last estimate, when the episode is runs of the policy (`run_segments`)."""
    read_speed: SpeedReader | None = None
    """How the predictor reads a push the robot reported the speed of (`speed_reader`);
    None: as the action commanded."""
    _read: list[np.ndarray] = field(default_factory=list, init=False, repr=False)

    @property
    def failure(self) -> str | None:
        return self.reports[-1].failure if self.reports else None

    def recorded(self, **fields: Any) -> dict[str, Any]:
        """The episode as a recording's episode (`masspush.data.recording`): its successful
        pushes and rest poses, plus `fields` (id, label, masses...)."""
        kept = [r for r in self.reports if r.config is not None]
        episode = {
            **fields,
            "lengths": self.start.lengths,
            "observations": [self.start.config, *(r.config for r in kept)],
            "actions": self.actions[: len(kept)],
        }
        if kept and all(r.speed is not None for r in kept):
            episode["speeds"] = [r.speed for r in kept]
        if kept and len(self.estimates) == len(kept):
            episode["estimates"] = self.estimates
        if self.failure is not None:
            episode["failure"] = self.failure
        return episode

    def history(self) -> Episodes:
        """The successful pushes so far, in the predictor's input format."""
        configs = [self.start.config] + [r.config for r in self.reports if r.config is not None]
        k = len(configs) - 1
        actions = np.asarray(self.actions[:k], np.float32).reshape(1, k, 2)
        if self.read_speed is not None:
            for j in range(len(self._read), k):  # each push read once, as it comes
                self._read.append(self.read_speed(
                    configs[j], self.start.lengths, actions[0, j], self.reports[j].speed
                ))  # fmt: skip
            actions[0] = np.reshape(self._read[:k], (k, 2))
        return Episodes.history(
            np.asarray(configs, np.float32)[None], actions,
            self.start.lengths[None].astype(np.float32),
        )  # fmt: skip


PushCallback = Callable[[int, np.ndarray, PushReport, "np.ndarray | None"], None]


class HistoryPredictor(Protocol):
    """Estimates the mass distribution after each push of a history: a predictor
    (`masspush.learn.predictor.Predictor`) or the particle filter's arm (`FilterArm`)."""

    def predict(self, episodes: Episodes) -> np.ndarray: ...


def run_estimation(
    robot: Robot,
    predictor: HistoryPredictor,
    policy: Policy,
    pushes: int,
    on_push: PushCallback | None = None,
    start: RestPose | None = None,
    seed: int = 0,
    fresh: bool = True,
    read_speed: SpeedReader | None = None,
) -> EstimationEpisode:
    """One episode: the policy picks each push from what has been seen, the robot executes
    it, and the predictor estimates the mass distribution after it. `on_push(k, action,
    report, estimate)` hears of every push as it happens (estimate None for a failed push);
    `start` is the episode's first rest pose when the caller has started the robot; `fresh`
    False keeps the policy's memory of the run before (`run_segments`); `read_speed`: how the
    predictor reads a push the robot reports the speed of (`speed_reader`), None: as
    commanded."""
    rest = start if start is not None else robot.start()
    episode = EstimationEpisode(rest, read_speed=read_speed)
    d = len(rest.config)
    observed = np.full((1, pushes + 1, d), np.nan, np.float32)
    chosen = np.full((1, pushes, 2), np.nan, np.float32)
    observed[0, 0] = rest.config
    lengths = rest.lengths[None].astype(np.float32)
    if fresh:
        policy.reset(np.array([seed], np.uint64))
    governor = getattr(robot, "governor", None)
    for k in range(pushes):
        action = np.asarray(policy.act(observed, chosen, k, lengths)[0], np.float32)
        if governor is not None:  # the push the robot is told to make, as in training
            action = governor(action, observed[0, k], lengths[0])
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
    predictor: HistoryPredictor,
    policy: Policy,
    pushes: int,
    segments: int,
    on_push: PushCallback | None = None,
    seed: int = 0,
    read_speed: SpeedReader | None = None,
) -> EstimationEpisode:
    """`segments` episodes of `pushes` pushes in a row on the same chain, each starting where
    the last one left it, the policy and the predictor starting afresh each time: one
    episode of up to segments x pushes pushes (`masspush.real.classifier.segments_of` cuts it back).
    Its estimates are each segment's own. With one segment this is `run_estimation`.

    A policy trained on episodes of several runs (its `runs`, `PolicyConfig.runs`) keeps its
    memory across that many runs, as in its training; others start afresh every run."""
    if segments < 1:
        raise ValueError(f"segments must be >= 1, got {segments}")
    runs = getattr(policy, "runs", 1)
    rest = robot.start()
    whole = EstimationEpisode(rest, read_speed=read_speed)
    for s in range(segments):
        told = None if on_push is None else _numbered_from(s * pushes, on_push)
        part = run_estimation(
            robot,
            predictor,
            policy,
            pushes,
            told,
            start=rest,
            seed=seed * segments + s,
            fresh=s % runs == 0,
            read_speed=read_speed,
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

    def told(k: int, action: np.ndarray, report: PushReport, estimate: np.ndarray | None) -> None:
        on_push(first + k, action, report, estimate)

    return told


def print_push(k: int, action: np.ndarray, result: PushReport, estimate: np.ndarray | None) -> None:
    """The plain report of a push, for `masspush run`."""
    if result.failure is not None:
        print(f"push {k + 1}: a={fmt(action, 2)} failed ({result.failure})")
        return
    print(f"push {k + 1}: a={fmt(action, 2)} -> at rest q{k + 1} = {fmt(result.config)}")
    print(f"  estimate {fmt(estimate)}")


def fmt(values: np.ndarray | Sequence[float], digits: int = 3) -> str:
    """Numbers as a short signed list, for reports."""
    return "[" + ", ".join(f"{v:+.{digits}f}" for v in np.asarray(values, dtype=float)) + "]"
