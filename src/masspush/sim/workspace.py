"""Where a stationary robot can push: the part of the table around its base it reaches.

A robot whose base stands still, as the paper's real UR10 did, can push a chain only while
the chain lies within its reach: one hard push can carry it out ("with a stationary robot
... the object can be pushed out of the robot workspace easily with one wrong action",
paper, Sec. 5). The workspace is an annular sector around the base's vertical axis: every
link centre at a horizontal distance in [r_min, r_max] from it and within +-max_bearing of
the direction the base faces. Its bounds come from a reachability scan of the arm model
(experiments/arms/stationary_reach.py, docs/real-robot.md): from anywhere inside, every push
the action space allows can be placed by the arm.

The robot also keeps the chain in reach (`ReachGovernor`): before a push it lowers the
push's speed until the longest slide that speed gave in training would leave every link
centre inside, as a robot's safety controller limits speed near a boundary. The policy and
the predictor see the governed action: it is the push the robot was told to make.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from masspush.config import PhysicsConfig
from masspush.sim.actions import action_to_push, check_action, push_geometry
from masspush.sim.chain import link_poses, wrap_angle


@dataclass(frozen=True)
class Workspace:
    """A stationary base's pose on the table and the region its arm reaches."""

    base: tuple[float, float, float]
    """The base's axis (x, y) on the table, m, and the yaw it faces, rad."""
    r_min: float
    """Nearest a link centre may lie to the base's axis, m."""
    r_max: float
    """Farthest a link centre may lie from the base's axis, m."""
    max_bearing: float
    """Largest angle between the facing direction and the bearing of a link centre, rad."""
    slide_per_speed: float = 0.11
    """A link centre's longest slide along the push per m/s of commanded speed, s [ours:
    the 99th percentile of random pushes of the stationary UR10 in real-ur10's training
    world, 0.083 (`fit_slides`), rounded up; docs/notebook/2026-12-02-reach-governor.md]."""
    slide_max: float = 0.20
    """The longest slide at any speed, m: the arm's joint speed limits cap what a fast
    action delivers [ours, same measurement: 0.164, rounded up]."""
    slide_sideways: float = 0.45
    """The longest sideways slide, as a fraction of the slide along the push [ours, same
    measurement: 0.44]."""
    slide_base: float = 0.03
    """The longest slide of the slowest push, m, which `slide_per_speed` adds to: the
    tool's travel past the face and its hold move a chain even at low speed [ours: the 99th
    percentile of the slides of random pushes up to 0.5 m/s in real-ur10's training world,
    0.026-0.031 (`fit_slides`), rounded up. The shipped real-ur10 models were trained with
    0; with it the 4-push policy lost 4 of 40 chains over 8 runs in the training world, with
    0.03 none; docs/notebook/2026-12-02-reach-governor.md]."""

    def __post_init__(self) -> None:
        if not 0.0 <= self.r_min < self.r_max:
            raise ValueError(f"need 0 <= r_min < r_max, got {self.r_min}, {self.r_max}")
        if not 0.0 < self.max_bearing <= math.pi:
            raise ValueError(f"max_bearing must be in (0, pi], got {self.max_bearing}")
        if min(self.slide_per_speed, self.slide_max, self.slide_sideways, self.slide_base) < 0:
            raise ValueError("the slide bounds must be >= 0")

    def polar(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(distance from the base's axis, bearing from its facing direction) of (..., 2)
        table points."""
        d = np.asarray(points, float) - np.array(self.base[:2])
        bearing = wrap_angle(np.arctan2(d[..., 1], d[..., 0]) - self.base[2])
        return np.hypot(d[..., 0], d[..., 1]), bearing

    def holds(self, config: np.ndarray, lengths: Sequence[float], joint_gap: float) -> bool:
        """Whether every link centre of a chain in `config` lies in the workspace."""
        return bool(self.headroom(config, lengths, joint_gap) >= 0)

    def headroom(
        self, configs: np.ndarray, lengths: Sequence[float], joint_gap: float
    ) -> np.ndarray:
        """(...,) for (..., d) configurations: how far the chain's nearest link centre lies
        inside the workspace's boundary, m (negative outside): the longest slide, in the
        worst direction, that leaves every centre in reach. The inner and outer arcs count
        radially, the sides by the distance to their radial lines."""
        centres, _ = link_poses(configs, lengths, joint_gap)
        r, bearing = self.polar(centres)
        angle = self.max_bearing - np.abs(bearing)
        # Beyond a right angle past its side line, a point's nearest side is the base's axis.
        side = np.where(angle < math.pi / 2, r * np.sin(np.minimum(angle, math.pi / 2)), r)
        room = np.minimum(np.minimum(r - self.r_min, self.r_max - r), side)
        return room.min(axis=-1)

    def robot_frame(self, config: np.ndarray) -> np.ndarray:
        """(..., 4) float32: the root link's (x, y) in the base's frame and the cosine and
        sine of its yaw there; what a policy needs to know where the chain lies from it."""
        config = np.asarray(config, float)
        c, s = math.cos(self.base[2]), math.sin(self.base[2])
        dx, dy = config[..., 0] - self.base[0], config[..., 1] - self.base[1]
        yaw = config[..., 2] - self.base[2]
        out = np.stack([c * dx + s * dy, -s * dx + c * dy, np.cos(yaw), np.sin(yaw)], -1)
        return out.astype(np.float32)


GOVERNOR_BISECTIONS = 12
"""Halvings of the speed range when the governor searches the fastest safe push (a
resolution of 2.5e-4 of the action range) [ours]."""


@dataclass(frozen=True)
class ReachGovernor:
    """A stationary robot's speed governor: an action whose push could carry the chain out
    of reach is slowed (|a1| lowered; side, link and point kept) to the fastest that cannot.

    'Could' is the measured bound of the workspace (`slide_per_speed`, `slide_max`,
    `slide_sideways`): every link centre may slide up to that far along the push and a
    fraction of it sideways; the governor asks that all of that region lie inside. It
    judges from the pose the robot observed, so it is the same in training, in evaluation
    and on a real robot."""

    workspace: Workspace
    physics: PhysicsConfig

    def __call__(
        self, action: ArrayLike, config: np.ndarray, lengths: Sequence[float]
    ) -> np.ndarray:
        """The governed action (float32), `action` itself where its push is safe."""
        a = check_action(action)
        config, lengths = np.asarray(config, float), [float(v) for v in lengths]
        if self.safe(a, config, lengths):
            return a.astype(np.float32)
        lo, hi = 0.0, abs(a[0])
        for _ in range(GOVERNOR_BISECTIONS):
            mid = (lo + hi) / 2
            if self.safe(np.array([math.copysign(mid, a[0]), a[1]]), config, lengths):
                lo = mid
            else:
                hi = mid
        return np.array([math.copysign(lo, a[0]), a[1]], np.float32)

    def safe(self, action: np.ndarray, config: np.ndarray, lengths: Sequence[float]) -> bool:
        """Whether every link centre stays in the workspace over the push's longest slide."""
        ws, physics = self.workspace, self.physics
        push = action_to_push(action, lengths, physics)
        direction = push_geometry(push, config, lengths, physics).direction
        along = min(ws.slide_max, ws.slide_base + ws.slide_per_speed * push.speed)
        side = ws.slide_sideways * along * np.array([-direction[1], direction[0]])
        centres, _ = link_poses(config, lengths, physics.joint_gap)
        # The region each centre may reach, sampled: the sector's inner arc is not convex.
        s = np.linspace(0.0, 1.0, 5)[:, None, None]
        u = np.linspace(-1.0, 1.0, 3)[None, :, None]
        points = centres[:, None, None, :] + s * along * direction + u * side
        r, bearing = ws.polar(points.reshape(-1, 2))
        inside = (r >= ws.r_min) & (r <= ws.r_max) & (np.abs(bearing) <= ws.max_bearing)
        return bool(inside.all())


SATURATION_SPEED = 2.0
"""Pushes at or below this commanded speed, m/s, set `slide_per_speed` in `fit_slides`:
above it the UR10's joint speed limits cap the speed delivered [ours, the governor's
notebook]."""

LOW_SPEED = 0.5
"""Pushes at or below this commanded speed, m/s, set `slide_base` in `fit_slides` [ours:
in lab 5 of the target world their slides' 99th percentile, 0.054-0.068 m, was 2-3 times
what a bound through zero allowed them; the governor's notebook]."""

SPEED_BAND = 0.25
"""Width of the speed bands, m/s, whose slides set `slide_per_speed` in `fit_slides`
[ours: narrow enough that taking each band at its lowest speed costs little]."""


def push_slides(
    before: np.ndarray, after: np.ndarray, actions: np.ndarray, lengths: np.ndarray,
    physics: PhysicsConfig,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Per push, (commanded speed m/s, longest slide of a link centre along the push m,
    longest across it m), from the rest poses before and after each push, its action and
    the chain's link lengths (rows: pushes). What `fit_slides` reads."""
    speed, along, across = (np.zeros(len(actions)) for _ in range(3))
    for i, (q0, q1, a, lens) in enumerate(zip(before, after, actions, lengths, strict=True)):
        q0, q1, lens = np.asarray(q0, float), np.asarray(q1, float), list(map(float, lens))
        push = action_to_push(np.clip(np.asarray(a, float), -1.0, 1.0), lens, physics)
        d = push_geometry(push, q0, lens, physics).direction
        moved = (
            link_poses(q1, lens, physics.joint_gap)[0] - link_poses(q0, lens, physics.joint_gap)[0]
        )
        speed[i] = push.speed
        along[i] = float((moved @ d).max())
        across[i] = float(np.abs(moved @ np.array([-d[1], d[0]])).max())
    return speed, along, across


def fit_slides(
    speed: np.ndarray, along: np.ndarray, across: np.ndarray, quantile: float = 0.99
) -> dict[str, float]:
    """The governor's slide bounds (`Workspace.slide_*`) from measured pushes
    (`push_slides`): `slide_max` the `quantile` of the slides along the push; `slide_base`
    the `quantile` of the slides of pushes up to `LOW_SPEED`; `slide_per_speed` the least
    slope above it that holds, in every `SPEED_BAND` of speeds up to `SATURATION_SPEED`,
    the band's `quantile` at the band's lowest speed; `slide_sideways` the ratio of the two
    directions' quantiles. Pushes after which the chain was lost have no rest pose and are
    missing: the bounds are low by what they would add."""
    speed, along, across = (np.asarray(v, float) for v in (speed, along, across))
    if not 0.5 <= quantile < 1.0:
        raise ValueError(f"quantile must be in [0.5, 1), got {quantile}")
    low = (speed > 0.0) & (speed <= LOW_SPEED)
    slow = (speed > LOW_SPEED) & (speed <= SATURATION_SPEED)
    if low.sum() < 20 or slow.sum() < 20 or len(speed) < 50:
        raise ValueError(
            f"too few pushes to fit slide bounds: {len(speed)} ({low.sum()} up to {LOW_SPEED} "
            f"m/s, {slow.sum()} of {LOW_SPEED}-{SATURATION_SPEED} m/s); need 50 (20, 20)"
        )
    top = float(np.quantile(along, quantile))
    base = float(np.quantile(along[low], quantile))
    slope = 0.0
    for lo in np.arange(LOW_SPEED, SATURATION_SPEED, SPEED_BAND):
        band = (speed > lo) & (speed <= lo + SPEED_BAND)
        if band.sum() >= 5:
            slope = max(slope, (float(np.quantile(along[band], quantile)) - base) / lo)
    return {
        "slide_base": base,
        "slide_per_speed": float(slope),
        "slide_max": top,
        "slide_sideways": float(np.quantile(across, quantile)) / max(top, 1e-9),
    }


ROBOT_FRAME_DIM = 4
"""Length of `Workspace.robot_frame`'s vector."""
