"""Where a stationary robot can push: the part of the table around its base it reaches.

A robot whose base stands still, as the paper's real UR10 did, can push a chain only while
the chain lies within its reach: one hard push can carry it out ("with a stationary robot
... the object can be pushed out of the robot workspace easily with one wrong action",
paper, Sec. 5). The workspace is an annular sector around the base's vertical axis: every
link centre at a horizontal distance in [r_min, r_max] from it and within +-max_bearing of
the direction the base faces. Its bounds come from a reachability scan of the arm model
(experiments/arms/stationary_reach.py, docs/real-robot.md): from anywhere inside, every push
the action space allows can be placed by the arm.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

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

    def __post_init__(self) -> None:
        if not 0.0 <= self.r_min < self.r_max:
            raise ValueError(f"need 0 <= r_min < r_max, got {self.r_min}, {self.r_max}")
        if not 0.0 < self.max_bearing <= math.pi:
            raise ValueError(f"max_bearing must be in (0, pi], got {self.max_bearing}")

    def polar(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(distance from the base's axis, bearing from its facing direction) of (..., 2)
        table points."""
        d = np.asarray(points, float) - np.array(self.base[:2])
        bearing = wrap_angle(np.arctan2(d[..., 1], d[..., 0]) - self.base[2])
        return np.hypot(d[..., 0], d[..., 1]), bearing

    def holds(self, config: np.ndarray, lengths: Sequence[float], joint_gap: float) -> bool:
        """Whether every link centre of a chain in `config` lies in the workspace."""
        centres, _ = link_poses(config, lengths, joint_gap)
        r, bearing = self.polar(centres)
        inside = (r >= self.r_min) & (r <= self.r_max) & (np.abs(bearing) <= self.max_bearing)
        return bool(inside.all())

    def robot_frame(self, config: np.ndarray) -> np.ndarray:
        """(..., 4) float32: the root link's (x, y) in the base's frame and the cosine and
        sine of its yaw there; what a policy needs to know where the chain lies from it."""
        config = np.asarray(config, float)
        c, s = math.cos(self.base[2]), math.sin(self.base[2])
        dx, dy = config[..., 0] - self.base[0], config[..., 1] - self.base[1]
        yaw = config[..., 2] - self.base[2]
        out = np.stack([c * dx + s * dy, -s * dx + c * dy, np.cos(yaw), np.sin(yaw)], -1)
        return out.astype(np.float32)


ROBOT_FRAME_DIM = 4
"""Length of `Workspace.robot_frame`'s vector."""
