"""Arm pushes for many candidate chains: the particle filter's simulator where an arm pushes.

Compiling a scene per candidate costs more than the push
(~25 ms) and the arm's inverse kinematics from its home pose ~150 ms, so `ArmScene` compiles
one scene per chain geometry and reuses it: each candidate's masses, inertias and table
friction are written into the model (`mj_setConst` recomputes what depends on them), the
chain is placed at the start pose and settled, and the arm starts every push from the same
ready pose (its joints after one push: the base is placed behind each push facing along
it, so the inverse kinematics of any push starts close to its solution). Every candidate's
outcome is thus a function of its own inputs alone, whatever else the scene simulated
before. `LockstepScenes` runs the same two scenes for all candidates at once on MuJoCo's
batch (the arms' compiled law as its control callback, `masspush.sim.batch.ArmLockstep`),
with the same outcomes; `ArmSimulator` uses it, or, without the compiled law, spreads
`ArmScene`s over worker processes.

Once the arm is parked it no longer touches the chain, but its six joints would still be
simulated at every step of the settling, which takes as long as the push: the chain
settles, before and after the push, in a second scene of the chain alone (the same masses,
inertias and friction), about half the cost per step.
"""

from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import mujoco
import mujoco.batch
import numpy as np

from masspush.config import PhysicsConfig
from masspush.sim.actions import action_to_push, push_geometry
from masspush.sim.batch import ArmLockstep, hand_over_batch, settle
from masspush.sim.chain import ChainParams, box_inertia
from masspush.sim.pushers import make_pusher, on_batch_path
from masspush.sim.simulate import ChainSim, hand_over

READY_ACTION = np.array([0.3, 0.0])
"""The push after which the arm's joints are its ready pose [ours: a middling push]."""


class ArmScene:
    """One compiled chain-and-arm scene for chains of these link lengths."""

    def __init__(self, physics: PhysicsConfig, pusher: str, lengths: tuple[float, ...]):
        n = len(lengths)
        chain = ChainParams((0.5,) * n, 0.75, tuple(lengths), (0.0,) * (n - 1), (0.0, 0.0, 0.0))
        self.physics = physics
        self.lengths = tuple(lengths)
        self.sim = ChainSim(chain, physics, make_pusher(pusher))
        self.settler = ChainSim(chain, physics)
        self.spec = mujoco.mjtState.mjSTATE_INTEGRATION
        self.homes = []
        for sim in (self.sim, self.settler):
            home = np.empty(mujoco.mj_stateSize(sim.model, self.spec))
            mujoco.mj_getState(sim.model, sim.data, home, self.spec)
            self.homes.append(home)
        # Each scene's ids of the links and the table (the pushers' bodies come after them).
        self.ids = [
            ([s.model.body(f"link{i}").id for i in range(n)], s.model.geom("table").id)
            for s in (self.sim, self.settler)
        ]
        for s in (self.sim, self.settler):
            if s.layout.root_qpos != 0 or s.layout.root_dof != 0:
                raise ValueError("the chain's joints must come first in both scenes")
        self.nq = self.sim.layout.nq
        self.ready = None
        self.ready = self.push(self.sim.config(), READY_ACTION, chain.masses, chain.friction)[2]

    def push(
        self, start: np.ndarray, action: np.ndarray, masses: np.ndarray, friction: float
    ) -> tuple[np.ndarray, str | None, np.ndarray]:
        """The rest configuration after pushing a chain of these masses and table friction
        from `start` with `action`, the failure (None, or one of simulate.FAILURES), and the
        arm's joints after the push."""
        sim, settler, ph = self.sim, self.settler, self.physics
        for scene, (bodies, table) in zip((sim, settler), self.ids, strict=True):
            model = scene.model
            for body, mass, length in zip(bodies, masses, self.lengths, strict=True):
                model.body_mass[body] = mass
                model.body_inertia[body] = box_inertia(float(mass), (length, ph.link_width,
                                                                      ph.link_height))  # fmt: skip
            model.geom_friction[table, 0] = friction
            mujoco.mj_setConst(model, scene.data)
        # Settle at the start pose in the chain-only scene, push in the arm's, settle again.
        mujoco.mj_setState(settler.model, settler.data, self.homes[1], self.spec)
        settler.layout.set_config(settler.data.qpos, np.asarray(start, float), ph.link_height / 2)
        settler.data.qvel[:] = 0.0
        mujoco.mj_forward(settler.model, settler.data)
        failure, _ = settler.settle()
        mujoco.mj_setState(sim.model, sim.data, self.homes[0], self.spec)
        hand_over(settler.data, sim.data, sim.layout)
        if self.ready is not None:
            sim.data.qpos[self.nq :] = self.ready
        mujoco.mj_forward(sim.model, sim.data)
        if failure is not None:
            return settler.config(), failure, sim.data.qpos[self.nq :].copy()
        failure = sim.push(np.asarray(action, float), settle=False).failure
        arm_q = sim.data.qpos[self.nq :].copy()
        if failure is not None:
            return sim.config(), failure, arm_q
        mujoco.mj_setState(settler.model, settler.data, self.homes[1], self.spec)
        hand_over(sim.data, settler.data, sim.layout)
        mujoco.mj_forward(settler.model, settler.data)
        failure, _ = settler.settle()
        return settler.config(), failure, arm_q


class LockstepScenes:
    """`ArmScene.push` for many candidates at once on MuJoCo's batch: the same two scenes,
    each candidate's masses, inertias and friction written into its simulation's model
    (`Batch.expand`, then `set_const`), the settling of all candidates together, and the
    arms in lockstep (`masspush.sim.batch.ArmLockstep`). The same rest poses and failures
    as `ArmScene`, candidate for candidate (tested)."""

    def __init__(self, physics: PhysicsConfig, pusher: str, lengths: tuple[float, ...],
                 nthread: int = 0):  # fmt: skip
        self.scene = ArmScene(physics, pusher, lengths)
        self.physics, self.nthread = physics, nthread

    def simulate(
        self, starts: np.ndarray, actions: np.ndarray, masses: np.ndarray, friction: np.ndarray
    ) -> tuple[np.ndarray, list[str | None]]:
        """Rest configurations (m, d) and failures of the candidates, as `ArmScene.push`."""
        scene, ph = self.scene, self.physics
        m = len(masses)
        batches = []
        for sim, (bodies, table) in zip((scene.sim, scene.settler), scene.ids, strict=True):
            batch = mujoco.batch.Batch(sim.model, m, self.nthread)
            mass, inertia = batch.expand("body_mass"), batch.expand("body_inertia")
            batch.expand("geom_friction")[:, table, 0] = friction
            for j, (body, length) in enumerate(zip(bodies, scene.lengths, strict=True)):
                mass[:, body] = masses[:, j]
                size = (length, ph.link_width, ph.link_height)
                for i in range(m):
                    inertia[i, body] = box_inertia(float(masses[i, j]), size)
            batch.set_const()
            batches.append(batch)
        arm, chain = batches
        everyone = np.arange(m)
        # Settle at the start pose in the chain-only scene, push in the arm's, settle again.
        chain.state[:] = scene.homes[1]
        qpos = chain.bind("qpos")
        for i in everyone:
            scene.settler.layout.set_config(qpos[i], np.asarray(starts[i], float),
                                            ph.link_height / 2)  # fmt: skip
        chain.bind("qvel")[:] = 0.0
        chain.forward()
        failures, _ = settle(chain, everyone, scene.settler.layout, ph)
        arm.state[:] = scene.homes[0]
        hand_over_batch(chain, arm, everyone, scene.sim.layout)
        arm.bind("qpos")[:, scene.nq :] = scene.ready
        arm.forward()
        configs = scene.settler.layout.config(chain.bind("qpos")).copy()
        pushing = [i for i in everyone if failures[i] is None]
        if not pushing:
            return configs, failures
        layout = scene.sim.layout
        start_configs = layout.config(arm.bind("qpos"))
        geometries = {}
        for i in pushing:
            spec = action_to_push(np.asarray(actions[i], float), scene.lengths, ph)
            geometries[i] = push_geometry(spec, start_configs[i], scene.lengths, ph)
        saved = arm.state.copy()
        lockstep = ArmLockstep(arm, scene.sim.pusher, scene.sim.model, ph)
        pushed, _, _ = lockstep.deliver(geometries)
        nan = [i for i in pushing if pushed[i] == "nan"]
        if nan:
            arm.state[nan] = saved[nan]
        after = layout.config(arm.bind("qpos"))
        for i in pushing:
            if pushed[i] is not None:
                failures[i], configs[i] = pushed[i], after[i]
        sliding = np.array([i for i in pushing if pushed[i] is None], dtype=int)
        if sliding.size:
            chain.state[sliding] = scene.homes[1]
            hand_over_batch(arm, chain, sliding, scene.sim.layout)
            chain.forward(sliding)
            settled, _ = settle(chain, sliding, scene.settler.layout, ph)
            final = scene.settler.layout.config(chain.bind("qpos"))
            for i in sliding:
                failures[i], configs[i] = settled[i], final[i]
        return configs, failures


@dataclass(frozen=True)
class _Job:
    physics: PhysicsConfig
    pusher: str
    lengths: tuple[float, ...]
    starts: np.ndarray
    actions: np.ndarray
    masses: np.ndarray
    friction: np.ndarray


_SCENES: dict[tuple, ArmScene] = {}
"""Each process's scenes, by (physics, pusher, lengths); the latest few are kept."""


def _run(job: _Job) -> tuple[np.ndarray, list[str | None]]:
    key = (job.physics, job.pusher, job.lengths)
    scene = _SCENES.get(key)
    if scene is None:
        if len(_SCENES) >= 4:
            _SCENES.pop(next(iter(_SCENES)))
        scene = _SCENES[key] = ArmScene(job.physics, job.pusher, job.lengths)
    configs, failures = [], []
    for start, action, masses, mu in zip(
        job.starts, job.actions, job.masses, job.friction, strict=True
    ):
        config, failure, _ = scene.push(start, action, masses, float(mu))
        configs.append(config)
        failures.append(failure)
    return np.array(configs), failures


class ArmSimulator:
    """Arm pushes of many candidate chains: in lockstep on MuJoCo's batch on `workers`
    threads (`LockstepScenes`) where the arm runs there (its compiled law is built), else
    spread over `workers` processes (1: here). Both give the same outcomes."""

    def __init__(self, physics: PhysicsConfig, pusher: str, workers: int = 0):
        self.physics = physics
        self.pusher = pusher
        self.workers = workers or os.cpu_count() or 1
        self._pool: ProcessPoolExecutor | None = None
        self.lockstep = on_batch_path(pusher)
        self._scenes: dict[tuple[float, ...], LockstepScenes] = {}

    def simulate(
        self, lengths: tuple[float, ...], starts: np.ndarray, actions: np.ndarray,
        masses: np.ndarray, friction: np.ndarray,
    ) -> tuple[np.ndarray, list[str | None]]:  # fmt: skip
        """Rest configurations (m, d) and failures after pushing each chain (masses,
        friction) from its start pose (m, d) with its action (m, 2)."""
        if self.lockstep:
            scenes = self._scenes.get(tuple(lengths))
            if scenes is None:
                self._scenes.clear()  # one chain (its lengths) per filter episode
                scenes = LockstepScenes(self.physics, self.pusher, tuple(lengths), self.workers)
                self._scenes[tuple(lengths)] = scenes
            return scenes.simulate(starts, actions, np.asarray(masses), np.asarray(friction))
        m = len(masses)
        inputs = (starts, actions, masses, friction)
        parts = np.array_split(np.arange(m), min(self.workers, m))
        jobs = [
            _Job(self.physics, self.pusher, tuple(lengths), *(a[p] for a in inputs)) for p in parts
        ]
        if len(jobs) == 1:
            results = [_run(jobs[0])]
        else:
            if self._pool is None:
                self._pool = ProcessPoolExecutor(max_workers=self.workers)
            results = list(self._pool.map(_run, jobs))
        return np.concatenate([r[0] for r in results]), [f for r in results for f in r[1]]

    def close(self) -> None:
        """Stop the worker processes (a later `simulate` starts them again)."""
        pool, self._pool = getattr(self, "_pool", None), None
        if pool is not None:
            pool.shutdown()

    def __del__(self) -> None:
        self.close()
