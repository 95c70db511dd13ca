"""Many chains, pushed together on every core through MuJoCo's native batch.

Each chain gets its own compiled model (masses, friction and lengths differ; the models
share one layout, as `mujoco.batch.Batch.set_models` requires). A push runs the pusher's
open-loop velocity commands as one `rollout`, then steps all still-moving chains in
chunks of `rest_check_steps`, dropping each as it comes to rest. The rest and failure
checks are the same code at the same steps as the one-at-a-time `ChainSim`, so the two
paths give the same rest poses.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import mujoco.batch
import numpy as np

from masspush.config import PhysicsConfig
from masspush.sim.actions import PushSpec, action_to_push, push_geometry
from masspush.sim.chain import INITIAL_KEY, ChainLayout, ChainParams, compile_scene
from masspush.sim.pushers import IDEAL_PUSHER, StiffPusher, pusher_kind
from masspush.sim.simulate import OK, PushOutcome, classify, failure_name, settle_cap_steps


class ChainBatch:
    """A batch of chains, each at rest between pushes, pushed by the stiff pusher."""

    def __init__(
        self,
        chains: Sequence[ChainParams],
        physics: PhysicsConfig,
        nthread: int = 0,
        pusher: str = IDEAL_PUSHER,
    ):
        if not pusher_kind(pusher).batch:
            # An arm needs Python control at every step, which MuJoCo's C batch cannot run.
            raise ValueError(
                f"the batch path runs the stiff pusher only, not {pusher!r}; "
                "simulate arm pushes one chain at a time with ChainSim (or the environment)"
            )
        if not chains:
            raise ValueError("ChainBatch needs at least one chain")
        for chain in chains:
            if chain.n_links != physics.n_links:
                raise ValueError(
                    f"every chain must have physics.n_links = {physics.n_links} links, "
                    f"got one with {chain.n_links}"
                )
        self.chains = list(chains)
        self.physics = physics
        self.pusher = StiffPusher()
        self.models = [compile_scene(c, physics, self.pusher.add_to) for c in chains]
        self.batch = mujoco.batch.Batch(self.models[0], len(chains), nthread)
        self.batch.set_models(self.models)
        self.batch.reset(keyframe=INITIAL_KEY)
        self.layout = ChainLayout.of(self.models[0], physics.n_links)
        pusher_joint = self.models[0].joint("pusher_x")
        self._pusher_q = int(pusher_joint.qposadr[0])
        self._pusher_v = int(pusher_joint.dofadr[0])
        self._qpos = self.batch.bind("qpos")
        self._qvel = self.batch.bind("qvel")
        self._ctrl = self.batch.bind("ctrl")
        self.failed = np.zeros(len(chains), dtype=bool)
        """Chains whose simulation has failed; they are not pushed again."""
        initial, _ = self.settle(np.arange(len(chains)))
        self.initial_failures = initial

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
        ids, specs, controls = self.prepare_push(actions)
        if ids.size == 0:
            return [None] * self.nsim
        saved = self.batch.state[ids].copy()
        self.deliver(ids, controls)
        failures, steps = self.settle(ids)
        nan = [i for i in ids if failures[i] == "nan"]
        if nan:
            self.batch.state[nan] = saved[np.isin(ids, nan)]
        outcomes: list[PushOutcome | None] = [None] * self.nsim
        for row, i in enumerate(ids):
            if failures[i] is not None:
                self.failed[i] = True
            outcomes[i] = PushOutcome(
                push=specs[row],
                failure=failures[i],
                settle_time=steps[i] * self.physics.timestep,
                steps=controls.shape[1] + steps[i],
                executed_speed=specs[row].speed,  # the stiff pusher holds its speed
            )
        return outcomes

    def prepare_push(self, actions: np.ndarray) -> tuple[np.ndarray, list[PushSpec], np.ndarray]:
        """Place the pusher for each live chain's push: (chain ids, pushes, (ids, steps, nu)
        velocity commands). The first phase of `push`, public for benchmarks."""
        actions = np.asarray(actions, dtype=float)
        if actions.shape != (self.nsim, 2):
            raise ValueError(f"actions must have shape ({self.nsim}, 2), got {actions.shape}")
        ids = np.flatnonzero(~self.failed)
        configs = self.configs()
        profile = self.pusher.speed_profile(self.physics)
        controls = np.zeros((ids.size, profile.size, self._ctrl.shape[1]))
        specs = []
        for row, i in enumerate(ids):
            chain = self.chains[i]
            spec = action_to_push(actions[i], chain.lengths, self.physics)
            geometry = push_geometry(spec, configs[i], chain.lengths, self.physics)
            specs.append(spec)
            self._qpos[i, self._pusher_q : self._pusher_q + 2] = self.pusher.start_qpos(
                geometry, self.physics
            )
            self._qvel[i, self._pusher_v : self._pusher_v + 2] = 0.0
            controls[row, :, :2] = self.pusher.controls(geometry, self.physics)
        return ids, specs, controls

    def deliver(self, ids: np.ndarray, controls: np.ndarray) -> None:
        """Run the pushes' open-loop commands in one rollout, then retract the pusher."""
        self.batch.rollout(
            controls.shape[1], control=controls, record=(mujoco.mjtState.mjSTATE_TIME,), ids=ids
        )
        self._qpos[ids, self._pusher_q : self._pusher_q + 2] = 0.0
        self._qvel[ids, self._pusher_v : self._pusher_v + 2] = 0.0
        self._ctrl[ids] = 0.0

    def settle(self, ids: np.ndarray) -> tuple[list[str | None], np.ndarray]:
        """Step the chains `ids` until each is at rest or fails; (failure per chain, steps)."""
        k = self.physics.rest_check_steps
        cap = settle_cap_steps(self.physics)
        failures: list[str | None] = [None] * self.nsim
        steps = np.zeros(self.nsim, dtype=int)
        moving = np.asarray(ids, dtype=int)
        taken = 0
        while moving.size and taken < cap:
            try:
                self.batch.step(moving, nstep=k)
            except mujoco.batch.SimulationError as err:
                for i in err.ids:
                    failures[int(i)] = "nan"
                moving = moving[~np.isin(moving, err.ids)]
            taken += k
            steps[moving] = taken
            code, at_rest = classify(
                self._qpos[moving], self._qvel[moving], self.layout, self.physics
            )
            for i, c in zip(moving[code != OK], code[code != OK], strict=True):
                failures[int(i)] = failure_name(c)
            moving = moving[(code == OK) & ~at_rest]
        for i in moving:
            failures[int(i)] = "timeout"
        return failures, steps
