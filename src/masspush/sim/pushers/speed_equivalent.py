"""A push as the models read it, from the speed the robot reports it reached.

The models learned how a chain answers the pushes of their setting's pusher, each named by its
action. A real robot's push may be slower or faster than the action commands (a lab's speed
scaling, a controller's gain), and a robot that reports the speed it reached
(`masspush.real.robot.PushReport.speed`) says so. To the models that push is the action at which
their own pusher would have moved at that speed, from the same pose, on the same link and side:
`SpeedEquivalent.action`. Measured (docs/notebook/2026-12-04-executed-speed.md): in the
target world's labs this changes the protocol's accuracy by no more than its noise, because
the stationary UR10's pushes are mostly capped by its joints, whatever speed was commanded.

Defined only for pushers whose speed the push's plan sets: the stiff pusher (the commanded
speed) and an arm with joint speed limits (the stationary UR10, whose plan scales a push down
to what its joints allow). An arm limited by its torques alone reaches a speed its plan does
not know; there the reported speed is kept but not read (`speed_equivalent` gives None).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np

from masspush.config import PhysicsConfig
from masspush.sim.actions import action_to_push, check_action, push_geometry
from masspush.sim.chain import compile_scene, sample_chain
from masspush.sim.pushers.arm import ArmPusher
from masspush.sim.pushers.base import Pusher

AT_FULL_SPEED = 0.02
"""Relative tolerance within which a push counts as made at its pusher's top speed from
there: the speed the stationary UR10 reaches scatters about 1 % around its plan there
(measured in the training world, 85 pushes) [ours]."""


class SpeedEquivalent:
    """The speeds at which one pusher pushes from a pose, and the action a push made at a
    reported speed was to it."""

    def __init__(self, pusher: Pusher, physics: PhysicsConfig):
        if not self.reads(pusher):
            raise ValueError(f"the {pusher.name} pusher's speed is not set by its plan")
        self.pusher = pusher
        self.physics = physics
        self._scene: tuple | None = None

    @staticmethod
    def reads(pusher: Pusher) -> bool:
        """Whether the pusher's plan sets its speed (not an arm limited by torques alone)."""
        return not (isinstance(pusher, ArmPusher) and pusher.arm.joint_speed_limit is None)

    def speed(
        self, config: np.ndarray, lengths: Sequence[float], action: np.ndarray
    ) -> float | None:
        """The speed (m/s) at which the pusher would make `action` on a chain at rest in
        `config`; None where it cannot make it."""
        spec = action_to_push(check_action(action), lengths, self.physics)
        geometry = push_geometry(spec, np.asarray(config, float), lengths, self.physics)
        if geometry.speed <= 0.0 or not isinstance(self.pusher, ArmPusher):
            return geometry.speed
        model, data, handles = self._arm_scene()
        # The plan reads the push alone (not the chain), so one scratch scene serves all.
        if self.pusher.plan(model, data, handles, geometry, self.physics) is None:
            return None
        return float(self.pusher.trace.commanded_speed)

    def action(
        self,
        config: np.ndarray,
        lengths: Sequence[float],
        action: np.ndarray,
        speed: float | None,
    ) -> np.ndarray:
        """`action` with its speed component replaced by the one at which the pusher would
        have moved at `speed` (m/s) from `config`: unchanged where no speed is known, where
        the pusher cannot make the push, or where both it and the robot pushed at the top
        speed reachable from there (any faster command moves the pusher no faster)."""
        out = np.array(action, np.float32)
        if speed is None or not math.isfinite(speed) or speed < 0:
            return out
        side = 1.0 if out[0] >= 0 else -1.0
        top = self.speed(config, lengths, np.array([side, out[1]]))
        if top is None:
            return out
        vmax = self.physics.push_speed_max
        at_top = top * (1 - AT_FULL_SPEED)
        if vmax * abs(out[0]) >= at_top and speed >= at_top:
            return out
        out[0] = side * min(speed, top) / vmax
        return out

    def _arm_scene(self) -> tuple:
        if self._scene is None:
            # Any chain: the plan never reads it, only the arm's joints and base.
            chain = sample_chain(self.physics, np.random.default_rng(0))
            model = compile_scene(chain, self.physics, self.pusher.add_to, self.pusher.name)
            self._scene = (model, mujoco.MjData(model), self.pusher._h(model))
        return self._scene
