"""Whether a stationary arm can make a push, asked before it is made.

A robot's motion planner knows before it moves whether it can put the tool where a push
starts: the inverse kinematics of the standoff pose, and whether the joints can move the tip
at a useful speed there. A push it cannot make fails as 'unreachable' and ends the episode
(`masspush.sim.pushers.arm`); a policy that chooses among candidates (the particle filter's
information-seeking pushes) can ask first and push the best one the arm can make.

`ReachCheck` runs the arm's own planning step (`ArmPusher.plan`, the part of a push before
the tool moves) on the pose the robot *sees*, in a scene of its own, so asking touches no
simulated chain. Pushes the planner accepts can still fail once under way (no contact
before the deadline, the arm touching the chain): the check is what a planner knows, no more.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from masspush.config import PhysicsConfig
from masspush.sim.actions import action_to_push, push_geometry
from masspush.sim.chain import compile_scene, sample_chain
from masspush.sim.pushers import ArmPusher, make_pusher, pusher_kind
from masspush.sim.simulate import scene_name


class ReachCheck:
    """`check(action, config, lengths)`: whether the arm `pusher` can make the push `action`
    on a chain seen in `config` with links `lengths`."""

    def __init__(self, pusher: str, physics: PhysicsConfig):
        arm = make_pusher(pusher)
        if not isinstance(arm, ArmPusher) or pusher_kind(pusher).workspace is None:
            raise ValueError(f"a reach check is for a stationary arm, not {pusher!r}")
        self.pusher, self.physics = arm, physics
        # Any chain will do: planning reads the push's geometry alone, never the chain.
        chain = sample_chain(physics, np.random.default_rng(0))
        self.model = compile_scene(chain, physics, arm.add_to, scene_name(arm))
        self.data = mujoco.MjData(self.model)
        self.handles = arm._h(self.model)

    def __call__(self, action: np.ndarray, config: np.ndarray, lengths: Sequence[float]) -> bool:
        push = action_to_push(np.asarray(action, float), list(lengths), self.physics)
        if push.speed <= 0.0:
            return True  # touches nothing: nothing to reach
        geometry = push_geometry(push, np.asarray(config, float), list(lengths), self.physics)
        trace = self.pusher.trace  # planning writes it; the robot's own pusher is not this one
        try:
            plan = self.pusher.plan(self.model, self.data, self.handles, geometry, self.physics)
        finally:
            self.pusher.trace = trace
        return plan is not None


def reach_check(pusher: str, physics: PhysicsConfig) -> ReachCheck | None:
    """The reach check of a stationary arm (`ReachCheck`), None for a pusher whose base
    follows the chain or that is no arm: it reaches every push."""
    kind = pusher_kind(pusher)
    return ReachCheck(pusher, physics) if kind.arm and kind.workspace is not None else None
