"""Robot-arm pushers: the KUKA KR 5 sixx R650 and the UR10 under operational-space control.

One push, as in the paper (Sec. 3.4) and the authors' setup:
1. The arm's base moves next to the chosen link, facing the push direction, at a fixed
   distance behind the contact point (the paper's base follows the object).
2. The arm is placed, by inverse kinematics, with its tip a short standoff before the
   contact point, oriented perpendicular to the pushed face, at rest. This replaces the
   slow free-space approach, which carries no information, with its end state.
3. Velocity phase: the target moves towards the face at the commanded speed and the OSC
   law tracks it; the standoff (3 / kd of travel, three time constants of the velocity
   loop) lets the tip reach that speed before it touches. From the first contact the
   target velocity is held for `push_hold_time` (the paper's 10 steps).
4. Retract: back towards the standoff point with zero target velocity, for 30 ms.
5. The base is parked far away; the chain slides to rest with no arm control to pay for.

A push in which any arm geometry other than the end-effector touches the chain is an
'arm_contact' failure; a pose the arm cannot reach is 'unreachable'.
"""

from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import mujoco
import numpy as np
from numpy.typing import ArrayLike

import masspush.sim.pushers.compiled as compiled
from masspush.config import PhysicsConfig
from masspush.sim.actions import PushGeometry
from masspush.sim.chain import wrap_angle
from masspush.sim.pushers.base import StepHook
from masspush.sim.pushers.osc import (
    KD,
    KP,
    TASK_DAMPING,
    desired_acceleration,
    rotation_error,
    scale_to_limits,
)
from masspush.sim.workspace import Workspace

ASSETS = Path(__file__).parent / "assets"
ARM_PARK = np.array([-1000.0, -1000.0, 0.0])
"""Where an arm's base waits between pushes: far from any chain."""
RETRACT_TIME = 0.030
"""Seconds of controlled retraction after the hold, before the arm is parked [ours]."""
STANDOFF_TIME = 0.030
"""The tip starts this many seconds of travel (at the commanded speed) before the face, up
to the arm's `max_standoff`, so that the torque-limited arm is near its target speed at
contact [ours]."""


@dataclass(frozen=True)
class ArmSpec:
    """An arm model and how it is placed for a push."""

    name: str
    xml: str
    """Model file in masspush/sim/pushers/assets (sources of its numbers are in the file)."""
    base_distance: float
    """Horizontal distance from the base to the contact point, m."""
    max_standoff: float
    """Longest run-up the arm can start from with its wrist above the table, m."""
    tool_pitch: float
    """How far the tip site's x-axis points below horizontal while pushing, rad. The KUKA's
    tool points 75 degrees down so that its wrist stays well above a 3 cm chain (a ball
    touches the same point at any tool angle); the UR10's dowel tilt is in its model."""
    workspace: Workspace | None = None
    """A stationary base: where it stands and what it reaches. None: the base follows the
    chain, placed `base_distance` behind each contact point."""
    joint_speed_limit: tuple[float, ...] | None = None
    """Each joint's top speed, rad/s: a push's speed is scaled down so that no joint must
    turn faster (a robot controller does the same); None: torque limits only."""


UR10_JOINT_SPEED = tuple(math.radians(v) for v in (120, 120, 180, 180, 180, 180))
"""The UR10's joint speed limits: base and shoulder 120 deg/s, elbow and wrists 180 deg/s
[UR10 (CB3) technical specifications]."""

# Base distances and pitches found by a reachability scan of the models (docs/arms.md):
# the KR 5's elbow (A3, +165 degrees) cannot fold far enough to push closer than ~0.55 m
# with its wrist above the table.
KR5 = ArmSpec(
    "kuka",
    "kuka_kr5_sixx_r650.xml",
    base_distance=0.60,
    max_standoff=0.08,
    tool_pitch=math.radians(75),
)
ARMS = {
    "kuka": KR5,
    # The same KR 5 a little farther back, so that its run-up can be longer: its tip's top
    # speed is set by how far its torques accelerate it before contact (v^2 = 2 a d), 2.6 m/s
    # from 8 cm, 3.2 m/s from 13 cm; 0.64 m is as far back as it reaches over that run-up
    # (docs/notebook/2026-12-01-arm-speed.md, "The run-up sets the arm's speed").
    "kuka-far": replace(KR5, name="kuka-far", base_distance=0.64, max_standoff=0.13),
    "ur10": ArmSpec("ur10", "ur10.xml", base_distance=0.75, max_standoff=0.15, tool_pitch=0.0),
    "ur10-stationary": ArmSpec(
        "ur10-stationary",
        "ur10.xml",
        base_distance=0.75,
        max_standoff=0.15,
        tool_pitch=0.0,
        workspace=Workspace(base=(0.0, -0.7, math.pi / 2), r_min=0.4, r_max=1.0, max_bearing=1.2),
        joint_speed_limit=UR10_JOINT_SPEED,
    ),
}
MIN_SPEED_SCALE = 0.05
"""A push whose joint speed limits leave it less than this fraction of its commanded speed is
'unreachable': the arm is near a singular pose for it (a controller would stop) [ours]."""
HOLD_TRAVEL = 0.02
"""How far past the face a push's tip is taken to travel during the hold, m (for the joint
speed limits) [ours: 10 ms at 2 m/s]."""
IK_TOLERANCE = 2e-3
"""Largest inverse-kinematics error (m, plus 0.1 m per rad) of a reachable pose [ours]."""
IK_CELL_DISTANCE, IK_CELL_ANGLE = 0.05, math.radians(15)
"""A stationary arm's inverse-kinematics cells: m from the base's axis, rad of push direction
relative to the bearing (`ArmPusher._ik_stationary`) [ours]."""
IK_CELL_MARGIN = 0.12
"""How far beyond the workspace's link centres a push's contact point may lie (half a link
plus the tool), m: the cells `build_ik_cells` solves [ours]."""
_CELLS: dict[tuple[str, float], dict[tuple[int, int], np.ndarray]] = {}
"""Each process's cell solutions, by (arm, push height)."""


def ik_cell_file(name: str) -> Path:
    """Where the cell solutions of a stationary arm ship."""
    return ASSETS / f"{name}-ik-cells.npz"


MIN_LINK_HEIGHT = 0.06
"""Inverse kinematics prefers poses whose arm links all stay this far above the table, m."""


@dataclass
class PushTrace:
    """What the arm did in its last push (for tests, plots and diagnostics)."""

    tip_speed: list[float] = field(default_factory=list)
    """Tip speed along the push direction at each step of the velocity phase, m/s."""
    contact_step: int | None = None
    """Step of the velocity phase at which the tip first touched the chain."""
    max_torque_ratio: float = 0.0
    """Largest |joint torque| / torque limit seen (1.0 means a limit was reached)."""
    ik_error: float = 0.0
    """Tip position error of the inverse kinematics at the start, m."""
    commanded_speed: float = 0.0
    """The tip speed the law was given, m/s: the push's, or less where joint speed limits
    scale it down (`ArmSpec.joint_speed_limit`)."""


@dataclass(frozen=True)
class PushPlan:
    """A push made ready (`ArmPusher.plan`): the arm at rest at the standoff, and the target
    of its velocity phase."""

    standoff: np.ndarray
    """Where the tip starts, m (the retraction's target too)."""
    target_r: np.ndarray
    """The tip's orientation throughout, 3x3."""
    velocity: np.ndarray
    """The tip's target velocity (linear, angular), the commanded speed along `direction`."""
    direction: np.ndarray
    """The push's direction (x, y, 0): velocity control along it, PD across it."""
    hold: int
    """Steps the velocity is held from the first contact."""
    deadline: int
    """Steps without contact after which the push is 'unreachable'."""


@dataclass(frozen=True)
class _Handles:
    qadr: np.ndarray
    dadr: np.ndarray
    act: np.ndarray
    site: int
    mocap: int
    ee: int
    arm_geoms: np.ndarray
    chain_geoms: np.ndarray
    is_arm: np.ndarray
    """(ngeom,) bool: the arm's geoms other than the end-effector (a lookup per contact is
    several times faster than `np.isin` at every control step)."""
    is_chain: np.ndarray
    links: np.ndarray
    low: np.ndarray
    high: np.ndarray
    torque_limit: np.ndarray
    dofs: slice
    """The arm's degrees of freedom, consecutive in every scene built here."""
    jac: np.ndarray
    """(6, nv) scratch: the tip's Jacobian (translation rows, then rotation rows)."""
    minv_jt: np.ndarray
    """(6, nv) scratch: the rows of M^-1 J^T."""


class ArmPusher:
    """Pushes with a simulated robot arm under the paper's operational-space control."""

    def __init__(self, arm: str, kp: float = KP, kd: float = KD):
        if arm not in ARMS:
            raise ValueError(f"unknown arm {arm!r}; known arms: {sorted(ARMS)}")
        self.arm = ARMS[arm]
        self.name = arm
        self.kp, self.kd = kp, kd
        self.prefix = f"{arm}/"
        self.tool = f"{self.prefix}ee"
        self.trace = PushTrace()
        self._on_step: StepHook | None = None
        self._model: mujoco.MjModel | None = None  # the model the handles belong to
        self._handles: _Handles | None = None
        self._reference_qs: dict[tuple[float, float], np.ndarray] = {}
        """The IK's start for a following base, by (reach, height) of its pose (`_ik`)."""
        self._compiled: tuple | None = None
        self._arm_spec: mujoco.MjSpec | None = None
        self.use_compiled = True
        """Run the control loop compiled where the library is there (`compiled`); False:
        the Python law, the reference."""
        self.executed_speed = 0.0
        """The last push's top tip speed along the push, m/s (`Pusher.executed_speed`)."""
        self.workspace = self.arm.workspace
        """Where a stationary base stands and what it reaches; None: the base follows."""

    # --- scene ------------------------------------------------------------------------
    @property
    def tool_radius(self) -> float:
        """The radius of the tool where it touches the chain (the ball, the dowel), m."""
        return float(self._spec().geom("ee").size[0])

    def _spec(self) -> mujoco.MjSpec:
        if self._arm_spec is None:
            self._arm_spec = mujoco.MjSpec.from_file(str(ASSETS / self.arm.xml))
        return self._arm_spec

    def add_to(self, spec: mujoco.MjSpec, physics: PhysicsConfig) -> None:
        # The arm's file is parsed once per pusher; attaching moves a body out of its spec,
        # so each scene gets a copy (the compiled models are byte-identical to a fresh
        # parse's, and a copy costs a tenth of one).
        frame = spec.worldbody.add_frame(pos=ARM_PARK.tolist())
        frame.attach_body(self._spec().copy().body("base"), self.prefix, "")
        spec.geom(self.tool).friction[0] = physics.tool_friction
        # Room for a push of the batch path's lockstep (`compiled.Userdata`); stepping
        # ignores it.
        spec.nuserdata = max(spec.nuserdata, compiled.Userdata.SIZE)

    def _h(self, model: mujoco.MjModel) -> _Handles:
        if self._model is not model:
            p = self.prefix
            joints = [model.joint(f"{p}joint{i}") for i in range(1, 7)]
            base = model.body(f"{p}base").id
            arm_bodies = {b for b in range(model.nbody) if _in_subtree(model, b, base)}
            ee = model.geom(self.tool).id
            arm_geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] in arm_bodies]
            chain_geoms = [g for g in range(model.ngeom) if model.geom(g).name.startswith("box")]
            self._model = model
            is_arm, is_chain = np.zeros(model.ngeom, bool), np.zeros(model.ngeom, bool)
            is_arm[[g for g in arm_geoms if g != ee]] = True
            is_chain[chain_geoms] = True
            dadr = np.array([j.dofadr[0] for j in joints])
            if not np.array_equal(dadr, np.arange(dadr[0], dadr[0] + 6)):
                raise ValueError(f"the arm's joints are not consecutive dofs: {dadr}")
            self._handles = _Handles(
                qadr=np.array([j.qposadr[0] for j in joints]),
                dadr=dadr,
                act=np.array([model.actuator(f"{p}joint{i}").id for i in range(1, 7)]),
                site=model.site(f"{p}tip").id,
                mocap=int(model.body_mocapid[base]),
                ee=ee,
                arm_geoms=np.array([g for g in arm_geoms if g != ee]),
                chain_geoms=np.array(chain_geoms),
                is_arm=is_arm,
                is_chain=is_chain,
                links=np.array(
                    [j.bodyid[0] for j in joints[2:]]
                    + [model.site_bodyid[model.site(f"{p}tip").id]]
                ),
                low=np.array([j.range[0] for j in joints]),
                high=np.array([j.range[1] for j in joints]),
                torque_limit=np.array([model.jnt_actfrcrange[j.id, 1] for j in joints]),
                dofs=slice(int(dadr[0]), int(dadr[0]) + 6),
                jac=np.zeros((6, model.nv)),
                minv_jt=np.zeros((6, model.nv)),
            )
        assert self._handles is not None
        return self._handles

    # --- one push ---------------------------------------------------------------------
    def deliver(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        push: PushGeometry,
        physics: PhysicsConfig,
        on_step: StepHook | None = None,
    ) -> str | None:
        self.trace = PushTrace()
        self.executed_speed = 0.0
        self._on_step = on_step
        if push.speed <= 0.0:
            return None  # a zero-speed push touches nothing
        h = self._h(model)
        plan = self.plan(model, data, h, push, physics)
        if plan is None:
            self.park(model, data)
            return "unreachable"
        standoff, target_r, direction = plan.standoff, plan.target_r, plan.direction
        # 3. Velocity phase, then the hold from first contact.
        hold, deadline, velocity = plan.hold, plan.deadline, plan.velocity
        lib = compiled.library() if self.use_compiled and on_step is None else None
        if lib is not None:
            failure = self._deliver_compiled(
                lib, model, data, h, standoff, target_r, velocity, direction, hold, deadline
            )
            self.executed_speed = max(self.trace.tip_speed, default=0.0)
            self.park(model, data)
            return failure
        failure = None
        step = 0
        while True:
            # Along the push: velocity control only (the paper's "hold the target velocity");
            # across it: the PD rule keeps the tip on the line through the contact point.
            tip_velocity, touching, arm_touch = self._control(
                model, data, h, standoff, target_r, velocity, free_axis=direction
            )
            self.trace.tip_speed.append(float(tip_velocity[:3] @ direction))
            if arm_touch:
                failure = "arm_contact"
                break
            if touching and self.trace.contact_step is None:
                self.trace.contact_step = step
            step += 1
            if self.trace.contact_step is not None and step >= self.trace.contact_step + hold:
                break
            if self.trace.contact_step is None and step >= deadline:
                failure = "unreachable"
                break
        self.executed_speed = max(self.trace.tip_speed, default=0.0)
        # 4. Retract towards the standoff point, no target velocity.
        if failure is None:
            for _ in range(self.retract_steps(model)):
                _, _, arm_touch = self._control(model, data, h, standoff, target_r, np.zeros(6))
                if arm_touch:
                    failure = "arm_contact"
                    break
        # 5. Out of the way.
        self.park(model, data)
        return failure

    @staticmethod
    def retract_steps(model: mujoco.MjModel) -> int:
        """Controlled steps of the retraction (step 4)."""
        return round(RETRACT_TIME / model.opt.timestep)

    def plan(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        h: _Handles,
        push: PushGeometry,
        physics: PhysicsConfig,
    ) -> PushPlan | None:
        """Steps 1 and 2 of `deliver`: the base placed and the arm set, at rest, at the
        standoff (the state's mocap pose and arm joints written, nothing else), and the
        velocity phase's target; None where the arm cannot reach the push. A function of
        the push alone: the chain's state is not read (`masspush.sim.batch` plans every
        chain's push in one scratch `MjData`)."""
        direction = np.array([push.direction[0], push.direction[1], 0.0])
        target_r = tool_rotation(direction, self.arm.tool_pitch)
        contact = np.array([push.contact[0], push.contact[1], physics.link_height / 2])
        tip_radius = float(model.geom_size[h.ee][0])
        touch = contact - direction * (tip_radius + physics.pusher_clearance)
        run_up = min(push.speed * STANDOFF_TIME, self.arm.max_standoff)
        standoff = touch - direction * run_up

        # 1. Base next to the link, facing the push direction, on the table (or where the
        # stationary robot stands).
        if self.workspace is None:
            yaw = math.atan2(direction[1], direction[0])
            self.place_base(model, data, contact - direction * self.arm.base_distance, yaw)
            # 2. Tip at the standoff point, at rest.
            q, error = self._ik(model, data, h, standoff, target_r, touch, direction)
        else:
            self.place_base(model, data, self.workspace.base[:2], self.workspace.base[2])
            q, error = self._ik_stationary(model, data, h, standoff, target_r, touch, direction)
        speed = push.speed
        if error <= IK_TOLERANCE and self.arm.joint_speed_limit is not None:
            # Where the run-up starts, and where the hold ends (a push moves the tip ~1 cm
            # past the face): the joint rates a tip speed needs change along the way.
            end = touch + HOLD_TRAVEL * direction
            q_end, _, _ = self._solve_ik(model, data, h, end, target_r, q, 50)
            speed = min(
                self._speed_within_joint_limits(model, data, h, qq, direction, speed)
                for qq in (q, q_end)
            )
            if speed < MIN_SPEED_SCALE * push.speed:
                error = math.inf  # near a singular pose: this push cannot be made from here
            elif speed < push.speed:  # the run-up for the speed the arm will move at
                run_up = min(speed * STANDOFF_TIME, self.arm.max_standoff)
                standoff = touch - direction * run_up
                q, error, _ = self._solve_ik(model, data, h, standoff, target_r, q, 150)
        self.trace.ik_error = error
        self.trace.commanded_speed = speed
        if error > IK_TOLERANCE:
            return None
        data.qpos[h.qadr] = q
        data.qvel[h.dadr] = 0.0
        # A torque-limited arm may be slower than commanded: allow it twice the time.
        to_face = run_up + physics.pusher_clearance
        dt = model.opt.timestep
        return PushPlan(
            standoff=standoff,
            target_r=target_r,
            velocity=np.concatenate([direction * speed, np.zeros(3)]),
            direction=direction,
            hold=physics.push_steps[1],
            deadline=math.ceil((2 * to_face / speed + 0.05) / dt),
        )

    def _speed_within_joint_limits(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        h: _Handles,
        q: np.ndarray,
        direction: np.ndarray,
        speed: float,
    ) -> float:
        """The push speed scaled down, as a robot controller scales a tool motion, so that
        no joint would turn faster than its limit to move the tip at it in pose `q`."""
        saved = data.qpos[h.qadr].copy()
        data.qpos[h.qadr] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        try:
            joint_rates = np.linalg.solve(
                self._jacobian(model, data, h), np.concatenate([direction * speed, np.zeros(3)])
            )
        except np.linalg.LinAlgError:
            joint_rates = None  # exactly singular (seen once in 800k training pushes)
        data.qpos[h.qadr] = saved  # as `_solve_ik`: the next step recomputes the rest
        if joint_rates is None:
            return 0.0  # no tip speed can be had in this pose: the push is unreachable
        limit = np.asarray(self.arm.joint_speed_limit)
        return speed * min(1.0, float(np.min(limit / np.maximum(np.abs(joint_rates), 1e-12))))

    def _deliver_compiled(
        self, lib: ctypes.CDLL, model: mujoco.MjModel, data: mujoco.MjData, h: _Handles,
        standoff: np.ndarray, target_r: np.ndarray, velocity: np.ndarray, direction: np.ndarray,
        hold: int, deadline: int,
    ) -> str | None:  # fmt: skip
        """Steps 3 and 4 of `deliver` in compiled code (`compiled`, osc_law.c): the same law
        and the same steps, without a return to Python between them."""
        arm = self._compiled_arm(h)
        ratio = ctypes.c_double(self.trace.max_torque_ratio)
        speeds = np.zeros(deadline + hold + 1)
        contact, steps = ctypes.c_int(), ctypes.c_int()
        m, d = ctypes.c_void_p(model._address), ctypes.c_void_p(data._address)
        push = compiled.target(standoff, target_r, velocity, free_axis=direction)
        code = lib.masspush_velocity_phase(
            m, d, ctypes.byref(arm), ctypes.byref(push), hold, deadline,
            speeds.ctypes.data, ctypes.byref(contact), ctypes.byref(steps), ctypes.byref(ratio),
        )  # fmt: skip
        self.trace.tip_speed = speeds[: steps.value].tolist()
        self.trace.contact_step = contact.value if contact.value >= 0 else None
        if code == 0:
            back = compiled.target(standoff, target_r, np.zeros(6))
            retract = round(RETRACT_TIME / model.opt.timestep)
            code = lib.masspush_retract(m, d, ctypes.byref(arm), ctypes.byref(back), retract,
                                        ctypes.byref(ratio))  # fmt: skip
        self.trace.max_torque_ratio = ratio.value
        return {0: None, 1: "arm_contact", 2: "unreachable"}[code]

    def _compiled_arm(self, h: _Handles) -> compiled.Arm:
        if self._compiled is None or self._compiled[0] is not h:
            arm = compiled.Arm()
            arm.dof0 = h.dofs.start
            arm.act[:] = h.act.tolist()
            arm.site, arm.ee = h.site, h.ee
            flags = (h.is_arm.astype(np.uint8), h.is_chain.astype(np.uint8))
            arm.is_arm, arm.is_chain = flags[0].ctypes.data, flags[1].ctypes.data
            arm.torque_limit[:] = h.torque_limit.tolist()
            arm.kp, arm.kd, arm.task_damping = self.kp, self.kd, TASK_DAMPING
            arm.jac, arm.minv_jt = h.jac.ctypes.data, h.minv_jt.ctypes.data
            self._compiled = (h, arm, flags)  # the arrays live as long as the struct
        return self._compiled[1]

    def place_base(
        self, model: mujoco.MjModel, data: mujoco.MjData, pos: ArrayLike, yaw: float
    ) -> None:
        """Put the arm's base at `pos` on the table, facing `yaw`."""
        h = self._h(model)
        data.mocap_pos[h.mocap] = [pos[0], pos[1], 0.0]
        data.mocap_quat[h.mocap] = [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]

    def move_to(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        target: np.ndarray,
        target_r: np.ndarray,
        duration: float,
    ) -> tuple[float, float]:
        """Drive the tip to a pose under OSC with zero target velocity for `duration` s;
        return the remaining (position error in m, orientation error in rad)."""
        h = self._h(model)
        for _ in range(round(duration / model.opt.timestep)):
            self._control(model, data, h, target, target_r, np.zeros(6))
        mujoco.mj_forward(model, data)
        pos_err = float(np.linalg.norm(target - data.site_xpos[h.site]))
        rot_err = float(
            np.linalg.norm(rotation_error(target_r, data.site_xmat[h.site].reshape(3, 3)))
        )
        return pos_err, rot_err

    def park(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Move the base far from the chain and stop the arm there."""
        h = self._h(model)
        data.mocap_pos[h.mocap] = ARM_PARK
        data.mocap_quat[h.mocap] = [1.0, 0.0, 0.0, 0.0]
        data.qvel[h.dadr] = 0.0
        data.ctrl[h.act] = 0.0

    # --- control ----------------------------------------------------------------------
    def _control(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        h: _Handles,
        x_des: np.ndarray,
        r_des: np.ndarray,
        v_des: np.ndarray,
        free_axis: np.ndarray | None = None,
    ) -> tuple[np.ndarray, bool, bool]:
        """One OSC step: (tip velocity, tip touches chain, other arm part touches chain).

        With `free_axis`, position errors along that axis are ignored (velocity control)."""
        mujoco.mj_step1(model, data)  # positions, velocities, contacts, mass matrix: now
        tau, tip_velocity = self._torque(model, data, h, x_des, r_des, v_des, free_axis)
        headroom = h.torque_limit - np.abs(data.qfrc_gravcomp[h.dofs])
        data.ctrl[h.act] = scale_to_limits(tau, headroom)
        touching, arm_touch = self._contacts(data, h)
        mujoco.mj_step2(model, data)
        if self._on_step is not None:
            self._on_step()
        ratio = float((np.abs(data.qfrc_actuator[h.dofs]) / h.torque_limit).max())
        if ratio > self.trace.max_torque_ratio:
            self.trace.max_torque_ratio = ratio
        return tip_velocity, touching, arm_touch

    def _torque(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        h: _Handles,
        x_des: np.ndarray,
        r_des: np.ndarray,
        v_des: np.ndarray,
        free_axis: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The OSC law's joint torques (before the limits) and the tip velocity, for the
        state after `mj_step1`. `osc.osc_torque`'s law, computed with what the step already
        has: M^-1 J^T from MuJoCo's factorised mass matrix (`mj_solveM`), one linear solve
        for M_x xdd, and no temporaries that the law runs at every step would allocate
        (the arm's pushes spend most of their time here; tests/test_arm.py holds it to the
        reference law)."""
        jac_full = h.jac
        mujoco.mj_jacSite(model, data, jac_full[:3], jac_full[3:], h.site)
        jac = jac_full[:, h.dofs]
        tip_velocity = jac @ data.qvel[h.dofs]
        # The arm is a tree of its own: J is zero off its dofs and M block-diagonal, so
        # J M^-1 J^T needs only the arm's columns of M^-1 J^T.
        mujoco.mj_solveM(model, data, h.minv_jt, jac_full)
        inv_lambda = jac @ h.minv_jt[:, h.dofs].T
        inv_lambda.flat[::7] += TASK_DAMPING
        pos_err = x_des - data.site_xpos[h.site]
        if free_axis is not None:
            pos_err = pos_err - (pos_err @ free_axis) * free_axis
        xdd = desired_acceleration(
            pos_err,
            rotation_error(r_des, data.site_xmat[h.site].reshape(3, 3)),
            tip_velocity,
            v_des,
            self.kp,
            self.kd,
        )
        # inv_lambda is symmetric positive definite: MuJoCo's Cholesky costs a fraction of
        # NumPy's general solver's call overhead at this size.
        mujoco.mju_cholFactor(inv_lambda, 0.0)
        task_force = np.empty(6)
        mujoco.mju_cholSolve(task_force, inv_lambda, xdd)
        return jac.T @ task_force, tip_velocity

    @staticmethod
    def _jacobian(model: mujoco.MjModel, data: mujoco.MjData, h: _Handles) -> np.ndarray:
        jacp = np.zeros((3, model.nv))
        jacr = np.zeros((3, model.nv))
        mujoco.mj_jacSite(model, data, jacp, jacr, h.site)
        return np.vstack([jacp[:, h.dadr], jacr[:, h.dadr]])

    @staticmethod
    def _contacts(data: mujoco.MjData, h: _Handles) -> tuple[bool, bool]:
        if data.ncon == 0:
            return False, False
        pairs = data.contact.geom[: data.ncon]
        chain = h.is_chain[pairs]
        with_chain = chain[:, 0] | chain[:, 1]
        ee = (pairs == h.ee).any(axis=1) & with_chain
        arm = h.is_arm[pairs].any(axis=1) & with_chain
        return bool(ee.any()), bool(arm.any())

    def _ik(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        h: _Handles,
        target: np.ndarray,
        target_r: np.ndarray,
        touch: np.ndarray,
        direction: np.ndarray,
    ) -> tuple[np.ndarray, float]:
        """Joint angles that put the tip at `target` with orientation `target_r`, and the
        remaining error (position in m plus 0.1 m per radian of orientation).

        Every push asks for nearly the same pose relative to the base: the tip 3 cm before
        the face at `touch`. One careful solution of that pose from several seeds, elbow
        above the table, starts every solve. It is solved with the base at the origin,
        facing +x, so that it depends on the geometry alone: solved at the first push's
        base instead, it would carry that push's rounding into every later push, and an
        episode would depend on which episodes ran before it in the same process."""
        # (reach, height) of that pose from the base, rounded off the push's own rounding.
        reach = float(np.linalg.norm(touch[:2] - data.mocap_pos[h.mocap, :2])) - 0.03
        key = (round(reach, 9), round(float(touch[2]), 9))
        if key not in self._reference_qs:
            pos, quat = data.mocap_pos[h.mocap].copy(), data.mocap_quat[h.mocap].copy()
            self.place_base(model, data, (0.0, 0.0), 0.0)
            facing = tool_rotation(np.array([1.0, 0.0, 0.0]), self.arm.tool_pitch)
            start = self._careful_ik(model, data, h, np.array([key[0], 0.0, key[1]]), facing)
            data.mocap_pos[h.mocap], data.mocap_quat[h.mocap] = pos, quat
            self._reference_qs[key] = start
        q, error, _ = self._solve_ik(model, data, h, target, target_r, self._reference_qs[key], 150)
        return q, error

    def _ik_stationary(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        h: _Handles,
        target: np.ndarray,
        target_r: np.ndarray,
        touch: np.ndarray,
        direction: np.ndarray,
    ) -> tuple[np.ndarray, float]:
        """`_ik` for a base that stands still: the poses asked for vary with where the chain
        lies. The base's first joint turns about its vertical axis, so a push rotated about
        that axis is solved by the same joints with the first one turned by the rotation:
        pushes are sorted into cells of (distance from the axis, push direction relative
        to the bearing), each cell's pose at bearing 0 solved carefully once from several
        seeds, and a push starts from its cell's solution, turned to its bearing. Each
        push's joints are thus a function of the push alone, whatever came before."""
        assert self.workspace is not None
        bx, by, byaw = self.workspace.base
        rel = touch[:2] - np.array([bx, by])
        r = float(np.hypot(*rel))
        bearing = math.atan2(rel[1], rel[0])
        psi = float(wrap_angle(math.atan2(direction[1], direction[0]) - bearing))
        cell = (round(r / IK_CELL_DISTANCE), round(psi / IK_CELL_ANGLE))
        cells = self._cells(float(touch[2]))
        seed = cells.get(cell)
        if seed is None:
            seed = cells[cell] = self._cell_solution(model, data, h, cell, float(touch[2]))
        start = seed.copy()
        start[0] += float(wrap_angle(bearing - byaw))
        start = np.clip(start, h.low, h.high)
        q, error, _ = self._solve_ik(model, data, h, target, target_r, start, 150)
        if error > IK_TOLERANCE:
            # The cell's solution lies on another branch for this push: solve it afresh.
            q = self._careful_ik(model, data, h, target, target_r)
            q, error, _ = self._solve_ik(model, data, h, target, target_r, q, 150)
        return q, error

    def _cell_solution(
        self, model: mujoco.MjModel, data: mujoco.MjData, h: _Handles, cell: tuple[int, int],
        height: float,
    ) -> tuple[np.ndarray, float]:  # fmt: skip
        """The careful solution for a cell's centre (`_ik_stationary`), at bearing 0."""
        assert self.workspace is not None
        bx, by, byaw = self.workspace.base
        r_c, psi_c = cell[0] * IK_CELL_DISTANCE, cell[1] * IK_CELL_ANGLE
        axis = np.array([math.cos(byaw), math.sin(byaw), 0.0])
        d_c = np.array([math.cos(byaw + psi_c), math.sin(byaw + psi_c), 0.0])
        point = np.array([bx, by, height]) + r_c * axis - 0.03 * d_c
        rot = tool_rotation(d_c, self.arm.tool_pitch)
        return self._careful_ik(model, data, h, point, rot)

    def _cells(self, height: float) -> dict[tuple[int, int], np.ndarray]:
        """This process's cell solutions for pushes at `height`: those shipped with the arm
        (`ik_cell_file`, computed by `build_ik_cells`) where they are for this height, and
        any others as they are solved."""
        key = (self.name, height)
        if key not in _CELLS:
            _CELLS[key] = {}
            path = ik_cell_file(self.name)
            if path.exists():
                with np.load(path) as table:
                    if float(table["height"]) == height:
                        for (i, j), q in zip(table["cells"], table["q"], strict=True):
                            _CELLS[key][(int(i), int(j))] = q
        return _CELLS[key]

    def build_ik_cells(self, height: float) -> dict[tuple[int, int], np.ndarray]:
        """Every cell a push inside the workspace can fall in, solved: the table
        `ik_cell_file` ships (written by `main`: `python -c "from masspush.sim.pushers.arm
        import main; main(['ur10-stationary'])"`, 2 min). In a scene of the arm alone: its
        joints' solutions are those of any scene (tested)."""
        assert self.workspace is not None
        spec = mujoco.MjSpec()
        self.add_to(spec, PhysicsConfig())
        model = spec.compile()
        data = mujoco.MjData(model)
        h = self._h(model)
        self.place_base(model, data, self.workspace.base[:2], self.workspace.base[2])
        reach = self.workspace.r_max + IK_CELL_MARGIN
        rows = range(
            math.floor((self.workspace.r_min - IK_CELL_MARGIN) / IK_CELL_DISTANCE),
            math.ceil(reach / IK_CELL_DISTANCE) + 1,
        )
        turns = range(-round(math.pi / IK_CELL_ANGLE), round(math.pi / IK_CELL_ANGLE) + 1)
        return {
            (i, j): self._cell_solution(model, data, h, (i, j), height) for i in rows for j in turns
        }

    def _careful_ik(
        self, model: mujoco.MjModel, data: mujoco.MjData, h: _Handles, target: np.ndarray,
        target_r: np.ndarray,
    ) -> np.ndarray:  # fmt: skip
        """The best of solutions from 25 seeds (zero and random, fixed), preferring those
        whose arm links stay `MIN_LINK_HEIGHT` above the table."""
        seeds = [np.zeros(6), *np.random.default_rng(0).uniform(h.low / 2, h.high / 2, (24, 6))]
        solutions = [self._solve_ik(model, data, h, target, target_r, s, 200) for s in seeds]
        return min(solutions, key=lambda r: r[1] + (r[2] < MIN_LINK_HEIGHT))[0]

    def _solve_ik(
        self, model: mujoco.MjModel, data: mujoco.MjData, h: _Handles, target: np.ndarray,
        target_r: np.ndarray, q0: np.ndarray, iterations: int,
    ) -> tuple[np.ndarray, float, float]:  # fmt: skip
        """Damped least squares with steps of at most 0.2 rad: (q, error, lowest link height)."""
        q = q0.copy()
        saved = data.qpos[h.qadr].copy()
        for _ in range(iterations + 1):
            data.qpos[h.qadr] = q
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            err = np.concatenate(
                [
                    target - data.site_xpos[h.site],
                    rotation_error(target_r, data.site_xmat[h.site].reshape(3, 3)),
                ]
            )
            error = float(np.linalg.norm(err[:3]) + 0.1 * np.linalg.norm(err[3:]))
            if error < 1e-5:
                break
            jac = self._jacobian(model, data, h)
            dq = jac.T @ np.linalg.solve(jac @ jac.T + 1e-4 * np.eye(6), err)
            q = np.clip(q + dq * min(1.0, 0.2 / np.abs(dq).max()), h.low, h.high)
        lowest = float(data.xpos[h.links, 2].min())
        data.qpos[h.qadr] = saved
        return q, error, lowest


def tool_rotation(direction: np.ndarray, pitch: float) -> np.ndarray:
    """Target orientation of the tip site: x along the push direction tilted down by pitch,
    y horizontal, z completing the frame (up when pitch is 0)."""
    up = np.array([0.0, 0.0, 1.0])
    lateral = _cross(up, direction)
    x = math.cos(pitch) * direction - math.sin(pitch) * up
    z = _cross(x, lateral)
    return np.column_stack([x, lateral, z])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """`np.cross` of two 3-vectors, the same bits at a fifteenth of its cost (every push
    plans with it; NumPy's per-call overhead dwarfs six products)."""
    (a0, a1, a2), (b0, b1, b2) = a.tolist(), b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _in_subtree(model: mujoco.MjModel, body: int, root: int) -> bool:
    while body > 0:
        if body == root:
            return True
        body = int(model.body_parentid[body])
    return False


def main(argv: list[str] | None = None) -> None:
    """Write a stationary arm's inverse-kinematics cells (`ArmPusher.build_ik_cells`) for the
    default chain's push height into the package's assets."""
    import sys

    name = (argv if argv is not None else sys.argv[1:])[0]
    height = PhysicsConfig().link_height / 2
    cells = ArmPusher(name).build_ik_cells(height)
    keys = sorted(cells)
    np.savez(
        ik_cell_file(name),
        height=height,
        cells=np.array(keys, np.int64),
        q=np.array([cells[k] for k in keys]),
    )
    print(f"{ik_cell_file(name)}: {len(keys)} cells")


if __name__ == "__main__":
    main()
