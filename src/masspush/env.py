"""The Gymnasium environment: push a chain K times, observe it only at rest."""

from __future__ import annotations

from dataclasses import asdict, replace
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from masspush.config import EnvConfig, PhysicsConfig
from masspush.sim.actions import check_action
from masspush.sim.chain import ChainParams, sample_chain, wrap_angle
from masspush.sim.pushers import make_pusher
from masspush.sim.simulate import ChainSim, PushOutcome

ENV_ID = "masspush/Chain-v0"


def noisy_observation(config: np.ndarray, rng: np.random.Generator, sigma: float) -> np.ndarray:
    """A configuration as sensed: Gaussian noise on every component, yaw wrapped again.

    The one place sensing noise is drawn: the batch engine (`masspush.data.rollout`) calls it too,
    so both draw the same numbers from the same generator."""
    noisy = config + rng.normal(0.0, sigma, size=config.shape)
    noisy[2] = wrap_angle(noisy[2])
    return noisy


def executed_action(action: np.ndarray, rng: np.random.Generator, sigma: float) -> np.ndarray:
    """An action as executed: Gaussian actuation noise, clipped back into the action box."""
    return np.clip(action + rng.normal(0.0, sigma, size=2), -1.0, 1.0)


class ChainEnv(gym.Env):
    """Estimate how an articulated chain's mass is distributed by pushing it.

    ## Description
    An n-link chain of boxes joined by hinges (about the vertical) lies on a table with
    unknown friction. Each step the robot delivers one push, the chain slides to rest,
    and the robot observes its rest configuration. After K pushes the episode ends; the
    true mass distribution is in `info` for training an estimator. The world follows the
    CoRL 2020 paper by Kumar et al.; every constant is in `masspush.config`.

    ## Action space
    `Box(-1, 1, (2,), float32)`, a = (a1, a2):

    | | meaning |
    |---|---|
    | a1 | push speed = 5 |a1| m/s; sign: which side of the chain is pushed |
    | a2 | which link, and where along it (within +-45 % of its length from its centre) |

    Gaussian noise (std `action_noise`) is added before execution, then clipped to the box.
    An action outside the box or containing NaN raises ValueError.

    ## Observation space
    `Box(-inf, inf, (2n + 2,), float32)`:

    | index | observation | unit |
    |---|---|---|
    | 0, 1 | root link centre x, y on the table | m |
    | 2 | root link yaw, wrapped to [-pi, pi) | rad |
    | 3 .. n + 1 | joint angles (link i relative to link i - 1) | rad |
    | n + 2 .. 2n + 1 | link lengths (exact: geometry is known) | m |

    Gaussian noise (std `obs_noise`) is added to the configuration (indices 0 .. n + 1).
    The table is unbounded, so positions are too.

    ## Rewards
    0.0 on every step. The paper's reward comes from a trained predictor:
    `masspush.learn.policy.PushPolicyEnv` wraps this environment with it. Everything a reward
    needs is in `info`.

    ## Starting state
    Per episode: masses ~ U(mass_range) per link; friction ~ U(0.5, 1); lengths ~
    U(0.1, 0.15) m; joint angles ~ U(-0.75, 0.75) rad; root centre ~ U(-0.1, 0.1)^2 m,
    yaw ~ U(-pi, pi). `reset(options=...)` pins any of `masses`, `friction`, `lengths`,
    `joint_angles`, `root_pose` (x, y, yaw); other keys raise ValueError, and so do pinned
    masses, friction or lengths outside the setting's ranges (unless `allow_out_of_range`)
    and values no table holds (`masspush.config.PLAUSIBLE`). The chain is let settle on the
    table before q_0 is observed.

    ## Episode end
    Terminated after `pushes` pushes (default 2 for 2 links, 3 for 3 links), or at once
    when a push fails: `info["failure"]` is then "nan" (the simulation diverged; the state
    is restored to before the push), "unstable" (thrown off the table, absurd speed, or
    at rest on its side), "timeout" (still moving after 10 s), or one of the arms' own
    (`pusher` below). Never truncated.

    ## Info
    `mass_distribution` (masses / total, n floats), `masses`, `friction`, `lengths`,
    `config` (the noiseless configuration), `failure` (None or a reason), `pushes_done`;
    after a step also `push` (link, offset, side, speed, the executed action, the speed
    the pusher reached: `executed_speed`, below `speed` where an arm could not reach it) and
    `settle_time` (simulated seconds until rest).

    ## Arguments
    `gymnasium.make("masspush/Chain-v0", n_links=2, mass_range=(0.1, 1.0), pushes=None,
    obs_noise=0.01, action_noise=0.01, pusher="stiff", physics=None,
    allow_out_of_range=False)`; `physics` is a full `PhysicsConfig` whose n_links and
    mass_range the two arguments override; n_links up to `masspush.config.MAX_LINKS` (64).
    `pusher`: "stiff" (idealised, velocity-controlled), "kuka" or "ur10" (robot arms under
    the paper's operational-space control whose base follows the chain; they add the
    failures "arm_contact" and "unreachable", see docs/arms.md), or "ur10-stationary" (the
    UR10 on a fixed base beside the table, as in the paper's real setup, with its joint
    speed limits; it adds "left_workspace" when the chain comes to rest out of its reach,
    at reset too; docs/real-robot.md).

    ## Version history
    v0: first version.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}

    def __init__(
        self,
        n_links: int = 2,
        mass_range: tuple[float, float] = (0.1, 1.0),
        pushes: int | None = None,
        obs_noise: float = 0.01,
        action_noise: float = 0.01,
        pusher: str = "stiff",
        physics: PhysicsConfig | None = None,
        allow_out_of_range: bool = False,
    ):
        physics = replace(physics or PhysicsConfig(), n_links=n_links, mass_range=mass_range)
        self.config = EnvConfig(
            physics=physics,
            pushes=pushes,
            obs_noise=obs_noise,
            action_noise=action_noise,
            pusher=pusher,
        )
        self.pusher = make_pusher(pusher)
        self.allow_out_of_range = allow_out_of_range
        n = physics.n_links
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(
            -np.inf, np.inf, shape=(physics.obs_dim + n,), dtype=np.float32
        )
        self.chain: ChainParams | None = None
        self.sim: ChainSim | None = None
        self._pushes_done = 0
        self._done = True

    @classmethod
    def from_config(cls, config: EnvConfig, allow_out_of_range: bool = False) -> ChainEnv:
        """The environment an `EnvConfig` describes."""
        physics = config.physics
        return cls(
            n_links=physics.n_links,
            mass_range=physics.mass_range,
            pushes=config.pushes,
            obs_noise=config.obs_noise,
            action_noise=config.action_noise,
            pusher=config.pusher,
            physics=physics,
            allow_out_of_range=allow_out_of_range,
        )

    @property
    def physics(self) -> PhysicsConfig:
        return self.config.physics

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self.chain = sample_chain(self.physics, self.np_random, options, self.allow_out_of_range)
        self.sim = ChainSim(self.chain, self.physics, self.pusher)
        self._pushes_done = 0
        failure = self.sim.initial_failure
        self._done = failure is not None
        return self._observe(), self._info(failure)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self.sim is None or self._done:
            raise RuntimeError("the episode is over (or never began): call reset() first")
        action = check_action(action)
        executed = executed_action(action, self.np_random, self.config.action_noise)
        outcome = self.sim.push(executed)
        self._pushes_done += 1
        self._done = outcome.failure is not None or self._pushes_done >= self.config.pushes
        info = self._info(outcome.failure)
        info.update(push=_push_info(outcome, executed), settle_time=outcome.settle_time)
        return self._observe(), 0.0, self._done, False, info

    def _observe(self) -> np.ndarray:
        assert self.sim is not None and self.chain is not None
        config = self.sim.config()
        noisy = noisy_observation(config, self.np_random, self.config.obs_noise)
        return np.concatenate([noisy, self.chain.lengths]).astype(np.float32)

    def _info(self, failure: str | None) -> dict[str, Any]:
        assert self.sim is not None and self.chain is not None
        return {
            "mass_distribution": self.chain.mass_distribution,
            "masses": np.array(self.chain.masses),
            "friction": self.chain.friction,
            "lengths": np.array(self.chain.lengths),
            "config": self.sim.config(),
            "failure": failure,
            "pushes_done": self._pushes_done,
        }


def _push_info(outcome: PushOutcome, executed: np.ndarray) -> dict[str, Any]:
    return {
        **asdict(outcome.push),
        "action": executed.copy(),
        "steps": outcome.steps,
        "executed_speed": outcome.executed_speed,
    }
