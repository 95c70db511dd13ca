"""One chain, one push at a time: push, then simulate until the chain is at rest.

This is the reference path; `masspush.sim.batch` runs many chains at once through MuJoCo's
multi-threaded batch and must give the same rest poses (tests check it).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from masspush.config import PhysicsConfig
from masspush.sim.actions import PushSpec, action_to_push, push_geometry
from masspush.sim.chain import INITIAL_KEY, ChainLayout, ChainParams, compile_scene
from masspush.sim.pushers import ArmPusher, Pusher, StepHook, StiffPusher

FAILURES = ("nan", "unstable", "timeout", "arm_contact", "unreachable", "left_workspace")
"""Why a push can fail: the simulation diverged (NaN/inf); the chain flew off the table,
reached an absurd speed or came to rest tipped on its side; it still moved at the cap; an
arm part other than the end-effector touched the chain; the arm could not reach the push;
the chain came to rest outside a stationary robot's workspace, where its next push could
not be made (`masspush.sim.workspace`). New reasons go at the end: datasets store the index."""

REACH_FAILURES = ("unreachable", "left_workspace")
"""The failures after which the robot has lost the chain: it could not make the push, or
the chain came to rest out of its reach. The others are the chain's own."""

# Codes of `classify`, vectorised over many simulations.
OK, NAN, UNSTABLE = 0, 1, 2


@dataclass(frozen=True)
class PushOutcome:
    """What happened in one push."""

    push: PushSpec
    """The push that was executed (after the action was mapped)."""
    failure: str | None
    """None, or one of FAILURES."""
    settle_time: float
    """Simulated time from the end of the push until rest (or failure), s."""
    steps: int
    """Physics steps the push and the settling took."""
    executed_speed: float = 0.0
    """The push's speed as executed (`Pusher.executed_speed`), m/s."""


def classify(
    qpos: np.ndarray, qvel: np.ndarray, layout: ChainLayout, physics: PhysicsConfig
) -> tuple[np.ndarray, np.ndarray]:
    """(code, at_rest) for (nsim, nq) / (nsim, nv) states: code is OK, NAN or UNSTABLE.

    Links rock and bounce during impacts, so tilt is judged only at rest: a chain that
    comes to rest on its side is UNSTABLE. While moving, only divergence, an absurd speed
    or leaving the table (lift above `max_lift`) count.
    """
    qpos = np.atleast_2d(qpos)
    qvel = np.atleast_2d(qvel)
    chain_q = qpos[:, : layout.nq]
    chain_v = qvel[:, : layout.nv]
    finite = np.isfinite(qpos).all(axis=1) & np.isfinite(qvel).all(axis=1)
    with np.errstate(invalid="ignore"):
        speed = np.abs(chain_v).max(axis=1)
        r = layout.root_qpos
        x, y = chain_q[:, r + 4], chain_q[:, r + 5]
        # The z-axis of the root link has vertical component 1 - 2 (x^2 + y^2).
        tipped = 1 - 2 * (x * x + y * y) < math.cos(physics.max_tilt)
        lift = np.abs(chain_q[:, r + 2] - physics.link_height / 2)
        at_rest = speed < physics.rest_velocity
        unstable = (speed > physics.max_velocity) | (lift > physics.max_lift) | (at_rest & tipped)
    code = np.where(~finite, NAN, np.where(unstable, UNSTABLE, OK))
    return code, at_rest & (code == OK)


def classify_one(
    qpos: np.ndarray, qvel: np.ndarray, layout: ChainLayout, physics: PhysicsConfig
) -> tuple[int, bool]:
    """`classify` for one state, as plain numbers: the same tests in the same float64
    arithmetic, a tenth of the time (the one-chain settle runs it every few steps)."""
    if not (np.isfinite(qpos).all() and np.isfinite(qvel).all()):
        return NAN, False
    speed = float(np.abs(qvel[: layout.nv]).max())
    r = layout.root_qpos
    x, y, z = float(qpos[r + 4]), float(qpos[r + 5]), float(qpos[r + 2])
    at_rest = speed < physics.rest_velocity
    tipped = 1 - 2 * (x * x + y * y) < math.cos(physics.max_tilt)
    lift = abs(z - physics.link_height / 2)
    if speed > physics.max_velocity or lift > physics.max_lift or (at_rest and tipped):
        return UNSTABLE, False
    return OK, at_rest


def failure_name(code: int) -> str | None:
    return {OK: None, NAN: "nan", UNSTABLE: "unstable"}[int(code)]


def settle_cap_steps(physics: PhysicsConfig) -> int:
    """Settling steps before a 'timeout', rounded up to whole rest checks."""
    k = physics.rest_check_steps
    return k * math.ceil(physics.settle_time_cap / physics.timestep / k)


SETTLING_ANCHOR = "settling_anchor"


def add_settling_anchor(spec: mujoco.MjSpec, physics: PhysicsConfig) -> None:
    """A damped slide joint on a body below the table, touching nothing: the settling
    scene's stand-in for an arm's damped joints. MuJoCo's implicit integration solves
    for the accelerations again where any joint is damped, and skips that solve where none
    is; without the anchor the chain's accelerations would round differently (1e-16) from
    those of the arm's scene, and chaotic slides would carry that far."""
    body = spec.worldbody.add_body(name=SETTLING_ANCHOR, pos=[0.0, 0.0, -10.0])
    body.add_joint(
        name=SETTLING_ANCHOR, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[1.0, 0.0, 0.0], damping=1.0
    )
    body.add_geom(
        type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.01, 0.0, 0.0], mass=1.0, contype=0,
        conaffinity=0,
    )  # fmt: skip


def compile_settling_scene(chain: ChainParams, physics: PhysicsConfig) -> mujoco.MjModel:
    """The chain alone (with `add_settling_anchor`), where a chain pushed by an arm settles.

    Once the arm is parked it touches nothing, yet its joints cost a third of every step
    of the settling. Settling here gives the rest poses of the arm's scene exactly (tested),
    provided the first `rest_check_steps` after the push are stepped in the arm's scene:
    MuJoCo warm-starts its contact solver only if that beats a cold start over all joints,
    and at the first step after a push the arm's accelerations are still those of the push
    (afterwards they are the parked arm's, ~1e-14)."""
    return compile_scene(chain, physics, add_settling_anchor, reuse="settling")


def scene_name(pusher: Pusher) -> str | None:
    """The name under which `compile_scene` reuses a pusher's scene (`reuse`): the known
    pushers' scenes depend on their name and the physics alone; None for any other."""
    return pusher.name if isinstance(pusher, (StiffPusher, ArmPusher)) else None


def hand_over(source: mujoco.MjData, target: mujoco.MjData, layout: ChainLayout) -> None:
    """The chain's state (its joints come first in every scene) from one scene to the
    other: poses, velocities, the solver's warm start and the time."""
    target.qpos[: layout.nq] = source.qpos[: layout.nq]
    target.qvel[: layout.nv] = source.qvel[: layout.nv]
    target.qacc_warmstart[: layout.nv] = source.qacc_warmstart[: layout.nv]
    target.time = source.time


class ChainSim:
    """One chain in a MuJoCo scene with a pusher, always observed at rest."""

    def __init__(
        self,
        chain: ChainParams,
        physics: PhysicsConfig,
        pusher: Pusher | None = None,
        adjust: Callable[[mujoco.MjModel], None] | None = None,
        settle_alone: bool = True,
    ):
        """`adjust`, if given, edits the compiled model before anything is simulated (the
        sim-to-real target world changes solver and contact parameters this way).
        `settle_alone`: where an arm pushes, let the chain settle in a scene of its own
        (`compile_settling_scene`: the same rest poses, a tenth less time a push); False
        keeps the arm in every step, the reference the tests compare with. A model that
        `adjust` edits is always the one the chain settles in (the target world draws its
        edits at random and edits the model again between pushes)."""
        if chain.n_links != physics.n_links:
            raise ValueError(f"chain has {chain.n_links} links, physics config {physics.n_links}")
        self.chain = chain
        self.physics = physics
        self.pusher = pusher or StiffPusher()
        self.on_step: StepHook | None = None
        """Called after every physics step, if set (to record video)."""
        self.phase = "settle"
        """"push" while the pusher acts, "settle" while the chain slides to rest."""
        self.model = compile_scene(chain, physics, self.pusher.add_to, scene_name(self.pusher))
        if adjust is not None:
            adjust(self.model)
        self.data = mujoco.MjData(self.model)
        self.layout = ChainLayout.of(self.model, chain.n_links)
        self._alone: tuple[mujoco.MjModel, mujoco.MjData] | None = None
        if settle_alone and adjust is None and isinstance(self.pusher, ArmPusher):
            alone = compile_settling_scene(chain, physics)
            self._alone = (alone, mujoco.MjData(alone))
        mujoco.mj_resetDataKeyframe(self.model, self.data, INITIAL_KEY)
        mujoco.mj_forward(self.model, self.data)
        # The chain is built resting exactly on the table; let the soft contacts take
        # its weight so that even q_0 is a true rest pose.
        self.initial_failure, _ = self.settle()
        if self.initial_failure is None:
            self.initial_failure = self.reach_failure()

    def config(self) -> np.ndarray:
        """The chain's current configuration (x, y, yaw, joint angles), noiseless."""
        return self.layout.config(self.data.qpos)

    def push(self, action: np.ndarray, settle: bool = True) -> PushOutcome:
        """Execute the push an action stands for and simulate until rest (with `settle`
        False, only until the pusher is done: the chain may still be sliding).

        After a 'nan' failure the state is restored to before the push, so the
        configuration stays finite; other failures keep the state they ended in.
        """
        spec = action_to_push(action, self.chain.lengths, self.physics)
        geometry = push_geometry(spec, self.config(), self.chain.lengths, self.physics)
        saved = self._state()
        start_time = self.data.time
        self.phase = "push"
        failure = self.pusher.deliver(self.model, self.data, geometry, self.physics, self.on_step)
        self.phase = "settle"
        push_steps = round((self.data.time - start_time) / self.physics.timestep)
        settle_steps = 0
        if failure is None and settle:
            failure, settle_steps = self.settle()
            if failure is None:
                failure = self.reach_failure()
        if failure == "nan":
            self._restore(saved)
        return PushOutcome(
            push=spec,
            failure=failure,
            settle_time=settle_steps * self.physics.timestep,
            steps=push_steps + settle_steps,
            executed_speed=self.pusher.executed_speed,
        )

    def reach_failure(self) -> str | None:
        """'left_workspace' where a stationary robot could not make the next push on the
        chain as it lies now; None otherwise (and always for a pusher that follows)."""
        workspace = self.pusher.workspace
        if workspace is None:
            return None
        inside = workspace.holds(self.config(), self.chain.lengths, self.physics.joint_gap)
        return None if inside else "left_workspace"

    def settle(self) -> tuple[str | None, int]:
        """Step until the chain is at rest or fails: (failure or None, steps taken).

        Where an arm pushes, the steps after the first rest check run in the settling
        scene (`compile_settling_scene`) unless a step hook watches this scene."""
        k = self.physics.rest_check_steps
        cap = settle_cap_steps(self.physics)
        model, data = self.model, self.data
        steps = 0
        failure: str | None = "timeout"
        while steps < cap:
            if self.on_step is None:
                mujoco.mj_step(model, data, nstep=k)
            else:
                for _ in range(k):
                    mujoco.mj_step(model, data)
                    self.on_step()
            steps += k
            code, at_rest = classify_one(data.qpos, data.qvel, self.layout, self.physics)
            if code != OK:
                failure = failure_name(code)
                break
            if at_rest:
                failure = None
                break
            if data is self.data and self._alone is not None and self.on_step is None:
                model, data = self._alone
                hand_over(self.data, data, self.layout)
        if data is not self.data:
            hand_over(data, self.data, self.layout)
            mujoco.mj_forward(self.model, self.data)
        return failure, steps

    def _state(self) -> np.ndarray:
        spec = mujoco.mjtState.mjSTATE_INTEGRATION
        state = np.empty(mujoco.mj_stateSize(self.model, spec))
        mujoco.mj_getState(self.model, self.data, state, spec)
        return state

    def _restore(self, state: np.ndarray) -> None:
        mujoco.mj_setState(self.model, self.data, state, mujoco.mjtState.mjSTATE_INTEGRATION)
        mujoco.mj_forward(self.model, self.data)
