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
"""

from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import mujoco
import numpy as np

from masspush.chain import ChainParams, box_inertia
from masspush.config import PhysicsConfig
from masspush.pusher import make_pusher
from masspush.simulate import ChainSim

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
        model = self.sim.model
        self.bodies = [model.body(f"link{i}").id for i in range(n)]
        self.table = model.geom("table").id
        self.nq = self.sim.layout.nq
        self.spec = mujoco.mjtState.mjSTATE_INTEGRATION
        self.home = np.empty(mujoco.mj_stateSize(model, self.spec))
        mujoco.mj_getState(model, self.sim.data, self.home, self.spec)
        self.ready = None
        self.ready = self.push(self.sim.config(), READY_ACTION, chain.masses, chain.friction)[2]

    def push(
        self, start: np.ndarray, action: np.ndarray, masses, friction: float
    ) -> tuple[np.ndarray, str | None, np.ndarray]:
        """The rest configuration after pushing a chain of these masses and table friction
        from `start` with `action`, the failure (None, or one of simulate.FAILURES), and the
        arm's joints after the push."""
        sim, model, ph = self.sim, self.sim.model, self.physics
        for body, mass, length in zip(self.bodies, masses, self.lengths, strict=True):
            model.body_mass[body] = mass
            model.body_inertia[body] = box_inertia(float(mass), (length, ph.link_width,
                                                                  ph.link_height))  # fmt: skip
        model.geom_friction[self.table, 0] = friction
        mujoco.mj_setConst(model, sim.data)
        mujoco.mj_setState(model, sim.data, self.home, self.spec)
        sim.layout.set_config(sim.data.qpos, np.asarray(start, float), ph.link_height / 2)
        sim.data.qvel[:] = 0.0
        if self.ready is not None:
            sim.data.qpos[self.nq :] = self.ready
        mujoco.mj_forward(model, sim.data)
        failure, _ = sim.settle()
        if failure is None:
            failure = sim.push(np.asarray(action, float)).failure
        return sim.config(), failure, sim.data.qpos[self.nq :].copy()


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
