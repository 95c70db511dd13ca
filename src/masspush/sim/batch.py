"""Many chains, pushed together on every core through MuJoCo's native batch.

Each chain gets its own compiled model (masses, friction and lengths differ; the models
share one layout, as `mujoco.batch.Batch.set_models` requires). The stiff pusher's push
runs its open-loop velocity commands as one `rollout`. An arm's push is planned (inverse
kinematics) chain by chain in Python, then every chain's arm runs its operational-space
law in lockstep: the compiled law as MuJoCo's control callback (`osc_law.c`,
`masspush_control`), each chain's push and phase in its `mjData.userdata`, each batch call
as many steps as no arm can end its push in, so that every arm is parked at the step it
finished. Then all still-moving chains are stepped, dropping each as it
comes to rest. The rest and failure checks are the same code at the same steps as the
one-at-a-time `ChainSim`, so the two paths give the same rest poses (tested, arms
included).
"""

from __future__ import annotations

import ctypes
from collections.abc import Mapping, Sequence
from functools import cache

import mujoco
import mujoco.batch
import numpy as np

from masspush.config import PhysicsConfig
from masspush.sim.actions import PushGeometry, PushSpec, action_to_push, push_geometry
from masspush.sim.chain import INITIAL_KEY, ChainLayout, ChainParams, compile_scene
from masspush.sim.pushers import IDEAL_PUSHER, ArmPusher, Pusher, make_pusher
from masspush.sim.pushers import compiled as compiled_law
from masspush.sim.pushers.arm import ARM_PARK, PushPlan
from masspush.sim.simulate import (
    OK,
    PushOutcome,
    classify,
    compile_settling_scene,
    failure_name,
    scene_name,
    settle_cap_steps,
)


@cache
def _shared_pusher(name: str) -> Pusher:
    """One pusher of each kind for all batches of this process: an arm keeps the start
    poses its inverse kinematics solved (each a function of the push's geometry alone, so
    sharing them changes no result), which a new batch per episode would solve again."""
    return make_pusher(name)


class ChainBatch:
    """A batch of chains, each at rest between pushes, pushed by the stiff pusher or an arm."""

    def __init__(
        self,
        chains: Sequence[ChainParams],
        physics: PhysicsConfig,
        nthread: int = 0,
        pusher: str = IDEAL_PUSHER,
    ):
        if not chains:
            raise ValueError("ChainBatch needs at least one chain")
        for chain in chains:
            if chain.n_links != physics.n_links:
                raise ValueError(
                    f"every chain must have physics.n_links = {physics.n_links} links, "
                    f"got one with {chain.n_links}"
                )
        self.pusher = _shared_pusher(pusher)
        if isinstance(self.pusher, ArmPusher):
            _compiled_law(pusher)  # refused before anything is compiled
        self.chains = list(chains)
        self.physics = physics
        name = scene_name(self.pusher)
        self.models = [compile_scene(c, physics, self.pusher.add_to, name) for c in chains]
        self.batch = mujoco.batch.Batch(self.models[0], len(chains), nthread)
        self.batch.set_models(self.models)
        self.batch.reset(keyframe=INITIAL_KEY)
        self.layout = ChainLayout.of(self.models[0], physics.n_links)
        self._qpos = self.batch.bind("qpos")
        self._qvel = self.batch.bind("qvel")
        self._ctrl = self.batch.bind("ctrl")
        self._arms: ArmLockstep | None = None
        self._alone: mujoco.batch.Batch | None = None
        if isinstance(self.pusher, ArmPusher):
            self._arms = ArmLockstep(self.batch, self.pusher, self.models[0], physics)
            # Where the chains settle once the first rest check is past (`ChainSim.settle`).
            alone = [compile_settling_scene(c, physics) for c in chains]
            self._alone = mujoco.batch.Batch(alone[0], len(chains), nthread)
            self._alone.set_models(alone)
            self._alone.reset(keyframe=INITIAL_KEY)
        else:
            pusher_joint = self.models[0].joint("pusher_x")
            self._pusher_q = int(pusher_joint.qposadr[0])
            self._pusher_v = int(pusher_joint.dofadr[0])
        self.failed = np.zeros(len(chains), dtype=bool)
        """Chains whose simulation has failed; they are not pushed again."""
        initial, _ = self.settle(np.arange(len(chains)))
        self.initial_failures = [
            f if f is not None else self._reach_failure(i) for i, f in enumerate(initial)
        ]

    def initial_failures_mask(self) -> np.ndarray:
        """(nsim,) bool: chains that failed already while settling before the first push."""
        return np.array([f is not None for f in self.initial_failures])

    @property
    def nsim(self) -> int:
        return len(self.chains)

    def configs(self) -> np.ndarray:
        """(nsim, 3 + n - 1) noiseless configurations of all chains."""
        return self.layout.config(self._qpos)

    def push(self, actions: np.ndarray) -> list[PushOutcome | None]:
        """Push every chain that has not failed with its action; simulate all to rest.

        Returns one outcome per chain, None for chains skipped after an earlier failure.
        """
        if self._arms is not None:
            return self._push_arms(actions)
        ids, specs, controls = self.prepare_push(actions)
        if ids.size == 0:
            return [None] * self.nsim
        saved = self.batch.state[ids].copy()
        self.deliver(ids, controls)
        failures, steps = self.settle(ids)
        return self._outcomes(
            ids, saved, dict(zip(ids, specs, strict=True)), failures,
            np.full(self.nsim, controls.shape[1]), steps,
            np.array([s.speed for s in specs]),  # the stiff pusher holds its speed
        )  # fmt: skip

    def _outcomes(
        self, ids: np.ndarray, saved: np.ndarray,
        specs: Mapping[int, PushSpec] | Sequence[PushSpec],
        failures: Mapping[int, str | None] | Sequence[str | None], push_steps: np.ndarray,
        settle_steps: np.ndarray, speeds: np.ndarray,
    ) -> list[PushOutcome | None]:  # fmt: skip
        """The pushes' outcomes, the failed chains marked and those that went NaN put back
        where they were before the push (`ChainSim.push`). `speeds` is by row of `ids`."""
        nan = [i for i in ids if failures[i] == "nan"]
        if nan:
            self.batch.state[nan] = saved[np.isin(ids, nan)]
        outcomes: list[PushOutcome | None] = [None] * self.nsim
        for row, i in enumerate(ids):
            if failures[i] is not None:
                self.failed[i] = True
            outcomes[i] = PushOutcome(
                push=specs[i],
                failure=failures[i],
                settle_time=settle_steps[i] * self.physics.timestep,
                steps=int(push_steps[i] + settle_steps[i]),
                executed_speed=float(speeds[row]),
            )
        return outcomes

    def _push_arms(self, actions: np.ndarray) -> list[PushOutcome | None]:
        """`push` for an arm: each push planned, then the arms and chains in lockstep.
        Step for step what `ChainSim.push` does with `ArmPusher.deliver` (compiled)."""
        assert self._arms is not None
        ids, specs, geometries = self._pushes(actions)
        saved = self.batch.state[ids].copy()
        failures, push_steps, speeds = self._arms.deliver(geometries)
        settling = np.array(sorted(i for i in ids if failures[i] is None), dtype=int)
        settle_steps = np.zeros(self.nsim, dtype=int)
        if settling.size:
            settled, settle_steps = self.settle(settling)
            for i in settling:
                failures[i] = settled[i] if settled[i] is not None else self._reach_failure(i)
        return self._outcomes(ids, saved, specs, failures, push_steps, settle_steps, speeds[ids])

    def _reach_failure(self, i: int) -> str | None:
        """`ChainSim.reach_failure` for chain i."""
        workspace = self.pusher.workspace
        if workspace is None:
            return None
        config = self.layout.config(self._qpos[i : i + 1])[0]
        inside = workspace.holds(config, self.chains[i].lengths, self.physics.joint_gap)
        return None if inside else "left_workspace"

    def prepare_push(self, actions: np.ndarray) -> tuple[np.ndarray, list[PushSpec], np.ndarray]:
        """Place the pusher for each live chain's push: (chain ids, pushes, (ids, steps, nu)
        velocity commands). The first phase of `push`, public for benchmarks."""
        ids, specs, geometries = self._pushes(actions)
        profile = self.pusher.speed_profile(self.physics)
        controls = np.zeros((ids.size, profile.size, self._ctrl.shape[1]))
        for row, i in enumerate(ids):
            self._qpos[i, self._pusher_q : self._pusher_q + 2] = self.pusher.start_qpos(
                geometries[i], self.physics
            )
            self._qvel[i, self._pusher_v : self._pusher_v + 2] = 0.0
            controls[row, :, :2] = self.pusher.controls(geometries[i], self.physics)
        return ids, [specs[i] for i in ids], controls

    def _pushes(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, dict[int, PushSpec], dict[int, PushGeometry]]:
        """The live chains and, by chain, the push each action stands for and where it
        meets the chain as it lies now."""
        actions = np.asarray(actions, dtype=float)
        if actions.shape != (self.nsim, 2):
            raise ValueError(f"actions must have shape ({self.nsim}, 2), got {actions.shape}")
        ids = np.flatnonzero(~self.failed)
        configs = self.configs()
        specs, geometries = {}, {}
        for i in ids:
            lengths = self.chains[i].lengths
            specs[i] = action_to_push(actions[i], lengths, self.physics)
            geometries[i] = push_geometry(specs[i], configs[i], lengths, self.physics)
        return ids, specs, geometries

    def deliver(self, ids: np.ndarray, controls: np.ndarray) -> None:
        """Run the pushes' open-loop commands in one rollout, then retract the pusher."""
        self.batch.rollout(
            controls.shape[1], control=controls, record=(mujoco.mjtState.mjSTATE_TIME,), ids=ids
        )
        self._qpos[ids, self._pusher_q : self._pusher_q + 2] = 0.0
        self._qvel[ids, self._pusher_v : self._pusher_v + 2] = 0.0
        self._ctrl[ids] = 0.0

    def settle(self, ids: np.ndarray) -> tuple[list[str | None], np.ndarray]:
        """Step the chains `ids` until each is at rest or fails; (failure per chain, steps).
        Where an arm pushes, as `ChainSim.settle`: after the first rest check the chains
        still moving settle in the settling scenes, without the arm."""
        if self._alone is None:
            return settle(self.batch, ids, self.layout, self.physics)
        ph = self.physics
        k = ph.rest_check_steps
        failures, steps, moving = settle_steps(self.batch, ids, self.layout, ph, stop=k)
        if moving.size:
            hand_over_batch(self.batch, self._alone, moving, self.layout)
            later, later_steps, left = settle_steps(self._alone, moving, self.layout, ph, start=k)
            hand_over_batch(self._alone, self.batch, moving, self.layout)
            self.batch.forward(moving)
            for i in moving:
                failures[i], steps[i] = later[i], later_steps[i]
            for i in left:
                failures[i] = "timeout"
        return failures, steps


def step_batch(batch: mujoco.batch.Batch, ids: np.ndarray, nstep: int) -> list[int]:
    """Step the simulations `ids`; the ones whose simulation failed (NaN, instability)."""
    try:
        batch.step(ids, nstep=nstep)
    except mujoco.batch.SimulationError as err:
        return [int(i) for i in err.ids]
    return []


def settle(
    batch: mujoco.batch.Batch, ids: np.ndarray, layout: ChainLayout, physics: PhysicsConfig
) -> tuple[list[str | None], np.ndarray]:
    """Step the chains `ids` of `batch` until each is at rest or fails, checking as
    `ChainSim.settle` does and at the same steps: (failure per simulation, steps taken)."""
    failures, steps, moving = settle_steps(batch, ids, layout, physics)
    for i in moving:
        failures[int(i)] = "timeout"
    return failures, steps


def settle_steps(
    batch: mujoco.batch.Batch, ids: np.ndarray, layout: ChainLayout, physics: PhysicsConfig,
    start: int = 0, stop: int | None = None,
) -> tuple[list[str | None], np.ndarray, np.ndarray]:  # fmt: skip
    """`settle` from `start` settling steps already taken until `stop` (the cap by
    default): (failure per simulation, steps taken, the ids still moving at `stop`)."""
    k = physics.rest_check_steps
    cap = settle_cap_steps(physics) if stop is None else stop
    qpos, qvel = batch.bind("qpos"), batch.bind("qvel")
    failures: list[str | None] = [None] * batch.nsim
    steps = np.zeros(batch.nsim, dtype=int)
    moving = np.asarray(ids, dtype=int)
    taken = start
    steps[moving] = taken
    while moving.size and taken < cap:
        nan = step_batch(batch, moving, k)
        for i in nan:
            failures[i] = "nan"
        moving = moving[~np.isin(moving, nan)]
        taken += k
        steps[moving] = taken
        code, at_rest = classify(qpos[moving], qvel[moving], layout, physics)
        for i, c in zip(moving[code != OK], code[code != OK], strict=True):
            failures[int(i)] = failure_name(c)
        moving = moving[(code == OK) & ~at_rest]
    return failures, steps, moving


def hand_over_batch(
    source: mujoco.batch.Batch, target: mujoco.batch.Batch, ids: np.ndarray, layout: ChainLayout
) -> None:
    """`masspush.sim.simulate.hand_over` for simulations `ids` of two batches."""
    for name, n in (("qpos", layout.nq), ("qvel", layout.nv), ("qacc_warmstart", layout.nv)):
        target.bind(name)[ids, :n] = source.bind(name)[ids, :n]
    target.bind("time")[ids] = source.bind("time")[ids]


def _compiled_law(pusher: str) -> ctypes.CDLL:
    law = compiled_law.library()
    if law is None:
        # The lockstep runs the compiled law only; the Python law, one chain at a time.
        raise RuntimeError(
            f"the batch path runs {pusher!r} with the compiled control law, which is "
            "not available here; simulate its pushes one chain at a time (ChainSim)"
        )
    return law


class ArmLockstep:
    """An arm's pushes for many simulations of one batch at once: each push planned in
    Python, then every arm's compiled law as MuJoCo's control callback, stepped together
    while any arm acts (`osc_law.c`, `masspush_control`; `_act`). Every simulation's model
    has the layout of `model` (one scene, other masses, lengths or friction)."""

    def __init__(
        self, batch: mujoco.batch.Batch, pusher: ArmPusher, model: mujoco.MjModel,
        physics: PhysicsConfig,
    ):  # fmt: skip
        self.batch, self.pusher, self.model, self.physics = batch, pusher, model, physics
        self.law = _compiled_law(pusher.name)
        self._qpos, self._qvel = batch.bind("qpos"), batch.bind("qvel")
        self._ctrl, self._userdata = batch.bind("ctrl"), batch.bind("userdata")
        self._mocap_pos = batch.bind("mocap_pos")
        self._mocap_quat = batch.bind("mocap_quat")
        self._scratch = mujoco.MjData(model)  # where pushes are planned
        self.arm = pusher._h(model)  # one layout: the same ids everywhere

    def deliver(
        self, geometries: dict[int, PushGeometry]
    ) -> tuple[dict[int, str | None], np.ndarray, np.ndarray]:
        """`ArmPusher.deliver` for each simulation i of `geometries` (the chains at rest):
        the failures (None: the arm is parked, the chain may slide on), the controlled
        steps and the executed speeds, (nsim,) each."""
        failures: dict[int, str | None] = {}
        acting = []
        for i, geometry in geometries.items():
            if geometry.speed <= 0.0:
                failures[i] = None  # a zero-speed push touches nothing: no arm, no parking
                continue
            plan = self.pusher.plan(self.model, self._scratch, self.arm, geometry, self.physics)
            if plan is None:
                failures[i] = "unreachable"
                self.park(i)
                continue
            self._set_push(i, plan)
            acting.append(i)
        push_steps = np.zeros(self.batch.nsim, dtype=int)
        speeds = np.zeros(self.batch.nsim)
        if acting:
            with compiled_law.lockstep_law(self.law, self.pusher._compiled_arm(self.arm)):
                self._act(np.array(acting, dtype=int), failures, push_steps, speeds)
        return failures, push_steps, speeds

    def _act(
        self, acting_ids: np.ndarray, failures: dict, push_steps: np.ndarray, speeds: np.ndarray
    ) -> None:
        """Step the acting simulations until every arm is done; park each as it finishes,
        recording its failure, steps and executed speed.

        Each call steps as many steps as no arm can finish in (`_steps_to_finish`), so that
        every arm is parked at the step it finished, as one step at a time would; an arm
        that touched the chain (`arm_contact`) or a simulation that failed inside such a
        call is the exception no bound foresees: the call is undone and stepped again one
        step at a time."""
        while acting_ids.size:
            n = self._steps_to_finish(acting_ids)
            if n > 1:
                saved = self.batch.state[acting_ids].copy()
                nan = step_batch(self.batch, acting_ids, n)
                if not nan and not self._ended_early(acting_ids):
                    push_steps[acting_ids] += n
                    acting_ids = self._finish(acting_ids, [], failures, speeds)
                    continue
                self.batch.state[acting_ids] = saved
            for _ in range(n):
                nan = step_batch(self.batch, acting_ids, 1)
                push_steps[acting_ids] += 1
                acting_ids = self._finish(acting_ids, nan, failures, speeds)
                if not acting_ids.size:
                    break

    def _finish(
        self, acting_ids: np.ndarray, nan: list[int], failures: dict, speeds: np.ndarray
    ) -> np.ndarray:
        """Park the simulations whose arm is done (or whose simulation failed), recording
        their failure and executed speed; the ones still acting."""
        u, phase = self._userdata, compiled_law.Userdata
        for i in nan:
            failures[i] = "nan"
        done = [i for i in acting_ids if u[i, phase.PHASE] >= phase.DONE or i in nan]
        for i in done:
            speeds[i] = u[i, phase.SPEED]
            if i not in failures:
                failures[i] = phase.FAILURES[int(u[i, phase.PHASE])]
            u[i, phase.PHASE] = phase.OFF
            self.park(i)
        return acting_ids[~np.isin(acting_ids, done)]

    def _steps_to_finish(self, acting_ids: np.ndarray) -> int:
        """The fewest steps in which one of the acting arms may end its push, read off the
        phases `masspush_control` keeps: a contact may come at the next step, the hold then
        lasts its steps and the retraction its own; without contact the deadline ends it."""
        u, phase = self._userdata[acting_ids], compiled_law.Userdata
        step, contact = u[:, phase.STEP], u[:, phase.CONTACT]
        retract = np.maximum(u[:, phase.RETRACT], 0.0)
        hold_end = np.where(contact >= 0, contact + u[:, phase.HOLD], step + u[:, phase.HOLD])
        velocity = np.maximum(hold_end - step, 1.0) + retract
        velocity = np.where(
            contact >= 0,
            velocity,
            np.minimum(velocity, np.maximum(u[:, phase.DEADLINE] - step, 1.0)),
        )
        steps = np.where(u[:, phase.PHASE] == phase.RETRACTING, np.maximum(retract, 1.0), velocity)
        return int(steps.min())

    def _ended_early(self, acting_ids: np.ndarray) -> bool:
        """Whether an arm ended its push in a way `_steps_to_finish` cannot foresee."""
        u, phase = self._userdata, compiled_law.Userdata
        return bool(np.any(u[acting_ids, phase.PHASE] == phase.ARM_CONTACT))

    def _set_push(self, i: int, plan: PushPlan) -> None:
        """Simulation i's arm where the plan put it (in the scratch data), its push in
        userdata."""
        h, scratch, phase = self.arm, self._scratch, compiled_law.Userdata
        self._qpos[i, h.qadr] = scratch.qpos[h.qadr]
        self._qvel[i, h.dadr] = 0.0
        self._mocap_pos[i, h.mocap] = scratch.mocap_pos[h.mocap]
        self._mocap_quat[i, h.mocap] = scratch.mocap_quat[h.mocap]
        u = self._userdata[i]
        u[:] = 0.0
        u[phase.PHASE] = phase.VELOCITY
        u[phase.CONTACT] = -1
        u[phase.HOLD], u[phase.DEADLINE] = plan.hold, plan.deadline
        u[phase.RETRACT] = self.pusher.retract_steps(self.model)
        u[phase.SPEED] = -np.inf
        u[phase.X : phase.X + 3] = plan.standoff
        u[phase.R : phase.R + 9] = plan.target_r.ravel()
        u[phase.V : phase.V + 6] = plan.velocity
        u[phase.AXIS : phase.AXIS + 3] = plan.direction
        u[phase.USE_AXIS] = 1.0

    def park(self, i: int) -> None:
        """`ArmPusher.park` for simulation i."""
        h = self.arm
        self._mocap_pos[i, h.mocap] = ARM_PARK
        self._mocap_quat[i, h.mocap] = [1.0, 0.0, 0.0, 0.0]
        self._qvel[i, h.dadr] = 0.0
        self._ctrl[i, h.act] = 0.0
