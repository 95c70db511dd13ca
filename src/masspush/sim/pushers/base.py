"""The pusher protocol: what physically delivers a push to the chain.

A pusher adds its bodies to the scene (`add_to`) and executes one push from the chain's
rest state (`deliver`), leaving the scene with the pusher out of the way; the simulator
then lets the chain slide to rest without it. The robot arms of a later issue implement
the same protocol, so the environment and everything downstream take any of them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import mujoco

from masspush.config import PhysicsConfig
from masspush.sim.actions import PushGeometry
from masspush.sim.workspace import Workspace

StepHook = Callable[[], None]


class Pusher(Protocol):
    """Delivers pushes in a MuJoCo scene that also holds the chain."""

    name: str
    workspace: Workspace | None
    """A stationary robot's reach (`masspush.sim.workspace`); None: it reaches the chain
    wherever it lies."""
    executed_speed: float
    """The last push's speed as executed: the tool's top speed along the push before the
    hold ended, m/s (below the commanded one where the robot could not reach it)."""
    tool: str
    """The name, in a scene, of the geom that touches the chain (its friction is
    `PhysicsConfig.tool_friction`)."""

    def add_to(self, spec: mujoco.MjSpec, physics: PhysicsConfig) -> None:
        """Add the pusher's bodies, joints and actuators to a scene being built."""

    def deliver(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        push: PushGeometry,
        physics: PhysicsConfig,
        on_step: StepHook | None = None,
    ) -> str | None:
        """Execute one push on a chain at rest; return None, or a failure reason.

        `on_step`, if given, is called after every physics step (to record video)."""


@dataclass(frozen=True)
class PusherKind:
    """A pusher's name and what it can do, so that no module compares pusher names.

    `masspush.sim.pushers.PUSHER_KINDS` holds one per known pusher."""

    name: str
    label: str
    """How figures and tables name it."""
    make: Callable[[], Pusher]
    """A new pusher of this kind."""
    batch: bool
    """Runs on the batch path (`masspush.sim.batch.ChainBatch`): many chains in lockstep
    (an arm there needs its compiled law: `masspush.sim.pushers.on_batch_path`)."""
    arm: bool
    """A robot arm under operational-space control (its scene holds the arm; the mass scale
    matters, as on a real robot). The stiff pusher is not one: a chain's mass barely slows it."""
    camera_distance: float
    """How far back a rendering camera stands to see the pusher and the chain, m [ours]."""
    workspace: Workspace | None = None
    """A stationary robot's reach; None: the pusher reaches the chain wherever it lies."""
