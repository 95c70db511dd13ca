"""The idealised stiff pusher: a velocity-servoed tip, fast and nearly blind to the mass
scale."""

from __future__ import annotations

import mujoco
import numpy as np

from masspush.config import PhysicsConfig
from masspush.sim.actions import PushGeometry
from masspush.sim.chain import PUSHER_CONTACT_BITS
from masspush.sim.pushers.base import StepHook

# Where the pusher waits between pushes: far off the chain's path (a push moves the chain
# at most v^2 / (2 mu g) ~ 2.6 m), so parking it is a retraction that never touches the chain.
PARK_XY = np.array([1000.0, 1000.0])


class StiffPusher:
    """An idealised, velocity-servoed tip that pushes the chain at exactly the target speed.

    The tip, a vertical capsule of radius `pusher_radius` centred at the links' mid-height,
    slides on two prismatic joints. A capsule rather than a ball: a ball can ride up the
    edge of a link that rocks under the impact and throw the chain; a vertical dowel keeps
    the contact normal horizontal (docs/simulation.md). It starts `pusher_clearance` from
    the pushed face, ramps linearly to the target speed over `push_ramp_time`, holds it
    for `push_hold_time`, and is then parked far away (an instant retraction).

    The pusher is 10^4 kg behind a velocity servo with a one-step time constant, so a
    chain's mass barely slows it: a common scale of the link masses changes the rest pose
    far less than their distribution does. The finite mass is what is left of the scale
    (docs/simulation.md has the measured size).
    """

    name = "stiff"
    workspace = None  # the idealised pusher reaches the chain wherever it lies
    executed_speed = 0.0  # velocity-controlled and 10^4 kg: it holds the commanded speed
    tool = "pusher_tip"

    def add_to(self, spec: mujoco.MjSpec, physics: PhysicsConfig) -> None:
        body = spec.worldbody.add_body(
            name="pusher", pos=[PARK_XY[0], PARK_XY[1], physics.link_height / 2]
        )
        body.explicitinertial = True
        body.mass = physics.pusher_mass
        body.inertia = [1.0, 1.0, 1.0]
        for axis, name in (([1, 0, 0], "pusher_x"), ([0, 1, 0], "pusher_y")):
            body.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis)
        contype, conaffinity = PUSHER_CONTACT_BITS
        body.add_geom(
            name=self.tool,
            type=mujoco.mjtGeom.mjGEOM_CAPSULE,
            size=[physics.pusher_radius, physics.link_height, 0],
            contype=contype,
            conaffinity=conaffinity,
            mass=0,
            friction=[physics.tool_friction, 0.005, 0.0001],
            rgba=[0.9, 0.3, 0.1, 1],
            # MuJoCo needs a contact time constant of at least two steps.
            solref=[max(physics.pusher_contact_time, 2 * physics.timestep), 1.0],
        )
        kv = physics.pusher_mass / physics.timestep
        for name in ("pusher_x", "pusher_y"):
            act = spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
            act.set_to_velocity(kv=kv)

    @staticmethod
    def speed_profile(physics: PhysicsConfig) -> np.ndarray:
        """Fraction of the target speed commanded at each physics step of a push."""
        ramp, hold = physics.push_steps
        rising = np.arange(1, ramp + 1) / ramp if ramp else np.empty(0)
        return np.concatenate([rising, np.ones(hold)])

    @staticmethod
    def start_qpos(push: PushGeometry, physics: PhysicsConfig) -> np.ndarray:
        """The pusher's joint positions (relative to its park) at the start of a push."""
        start = push.contact - push.direction * (physics.pusher_radius + physics.pusher_clearance)
        return start - PARK_XY

    def controls(self, push: PushGeometry, physics: PhysicsConfig) -> np.ndarray:
        """(steps, 2) velocity commands of one push."""
        return self.speed_profile(physics)[:, None] * (push.speed * push.direction)[None, :]

    def deliver(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        push: PushGeometry,
        physics: PhysicsConfig,
        on_step: StepHook | None = None,
    ) -> str | None:
        self.executed_speed = push.speed
        qadr, dadr = _pusher_addresses(model)
        data.qpos[qadr : qadr + 2] = self.start_qpos(push, physics)
        data.qvel[dadr : dadr + 2] = 0.0
        for u in self.controls(push, physics):
            data.ctrl[:2] = u
            mujoco.mj_step(model, data)
            if on_step is not None:
                on_step()
        park(model, data)
        return None


def _pusher_addresses(model: mujoco.MjModel) -> tuple[int, int]:
    joint = model.joint("pusher_x")
    return int(joint.qposadr[0]), int(joint.dofadr[0])


def park(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Retract the stiff pusher: back to its park position, at rest, no command."""
    qadr, dadr = _pusher_addresses(model)
    data.qpos[qadr : qadr + 2] = 0.0
    data.qvel[dadr : dadr + 2] = 0.0
    data.ctrl[:2] = 0.0
