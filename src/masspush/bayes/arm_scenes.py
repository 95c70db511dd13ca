"""Arm pushes for many candidate chains: the particle filter's simulator where an arm pushes.

MuJoCo's batch path runs open-loop pushers only; an arm needs its operational-space
control law every step, in Python. Compiling a scene per candidate costs more than the push
(~25 ms) and the arm's inverse kinematics from its home pose ~150 ms, so `ArmScene` compiles
one scene per chain geometry and reuses it: each candidate's masses, inertias and table
friction are written into the model (`mj_setConst` recomputes what depends on them), the
chain is placed at the start pose and settled, and the arm starts every push from the same
ready pose (its joints after one push: the base is placed behind each push facing along
it, so the inverse kinematics of any push starts close to its solution). Every candidate's
outcome is thus a function of its own inputs alone, whatever else the scene simulated
before, and `ArmSimulator` spreads the candidates over worker processes.

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
import numpy as np

from masspush.config import PhysicsConfig
from masspush.sim.chain import ChainParams, box_inertia
from masspush.sim.pushers import make_pusher
from masspush.sim.simulate import ChainSim

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
        self.nq, self.nv = self.sim.layout.nq, self.sim.layout.nv
        self.ready = None
        self.ready = self.push(self.sim.config(), READY_ACTION, chain.masses, chain.friction)[2]

    def push(
        self, start: np.ndarray, action: np.ndarray, masses, friction: float
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
        self._hand_over(settler.data, sim.data)
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
        self._hand_over(sim.data, settler.data)
        mujoco.mj_forward(settler.model, settler.data)
        failure, _ = settler.settle()
        return settler.config(), failure, arm_q

    def _hand_over(self, source: mujoco.MjData, target: mujoco.MjData) -> None:
        """The chain's state (poses, velocities, the solver's warm start) from one scene to
        the other; both put the chain's joints first."""
        target.qpos[: self.nq] = source.qpos[: self.nq]
        target.qvel[: self.nv] = source.qvel[: self.nv]
        target.qacc_warmstart[: self.nv] = source.qacc_warmstart[: self.nv]


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
    """Arm pushes of many candidate chains, spread over `workers` processes (1: here)."""

    def __init__(self, physics: PhysicsConfig, pusher: str, workers: int = 0):
        self.physics = physics
        self.pusher = pusher
        self.workers = workers or os.cpu_count() or 1
        self._pool: ProcessPoolExecutor | None = None

    def simulate(
        self, lengths: tuple[float, ...], starts: np.ndarray, actions: np.ndarray,
        masses: np.ndarray, friction: np.ndarray,
    ) -> tuple[np.ndarray, list[str | None]]:  # fmt: skip
        """Rest configurations (m, d) and failures after pushing each chain (masses,
        friction) from its start pose (m, d) with its action (m, 2)."""
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
