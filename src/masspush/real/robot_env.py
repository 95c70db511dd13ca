"""A Gymnasium view of a robot (`masspush.real.robot.Robot`) that can be reseeded: what PPO needs
to train a pushing policy in a world other than the training simulation, such as worlds
drawn at random per episode (`masspush.real.target_world.WorldRanges`, `masspush randomise`).

It speaks `masspush.env.ChainEnv`'s language (observations: the observed configuration then
the link lengths the robot knows; `info`: mass_distribution, lengths, failure), so
`masspush.learn.policy.PushPolicyEnv` drives it as it drives the simulation.
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from masspush.real.robot import Robot
from masspush.sim.actions import check_action


class RobotEnv(gym.Env):
    """`pushes` pushes per episode on a robot with a `seed` attribute and a `truth` dict
    (`SimRobot`, `TargetWorldRobot`): each reset starts the robot at a seed drawn from the
    environment's generator, so the episodes follow `reset(seed=...)`."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}

    def __init__(self, robot: Robot, pushes: int) -> None:
        if pushes < 1:
            raise ValueError(f"pushes must be >= 1, got {pushes}")
        self.robot, self.pushes = robot, pushes
        n = robot.n_links
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (3 + n - 1 + n,), np.float32)
        self._done = True

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        if options:
            raise ValueError(f"RobotEnv takes no reset options, got {sorted(options)}")
        super().reset(seed=seed)
        self.robot.seed = int(self.np_random.integers(2**62))
        rest = self.robot.start()
        self._lengths = np.asarray(rest.lengths, np.float32)
        self._k, self._done = 0, False
        return self._obs(rest.config), self._info(None)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self._done:
            raise RuntimeError("the episode is over (or never began): call reset() first")
        report = self.robot.push(check_action(action))
        self._k += 1
        self._done = report.failure is not None or self._k >= self.pushes
        config = report.config if report.config is not None else np.full(
            len(self._lengths) + 2, np.nan, np.float32
        )  # fmt: skip
        return self._obs(config), 0.0, self._done, False, self._info(report.failure)

    def close(self) -> None:
        self.robot.close()

    def _obs(self, config: np.ndarray) -> np.ndarray:
        return np.concatenate([np.asarray(config, np.float32), self._lengths])

    def _info(self, failure: str | None) -> dict[str, Any]:
        truth = self.robot.truth
        return {
            "mass_distribution": np.array(truth["mass_distribution"]),
            "masses": np.array(truth["masses"]),
            "lengths": self._lengths.copy(),
            "failure": failure,
            "pushes_done": self._k,
        }
