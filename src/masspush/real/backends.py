"""Robot backends: the simulation, the sim-to-real target world and recorded sessions
behind the `masspush.real.robot.Robot` interface, and `make_robot` to pick one by name."""

from __future__ import annotations

import importlib
import os
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from masspush.real.robot import PushReport, RestPose, Robot
from masspush.real.target_world import TargetWorldRobot
from masspush.sim.pushers import PUSHERS, reach_governor

if TYPE_CHECKING:
    from masspush.config import ChainGeometry
    from masspush.settings import Setting


class SimRobot:
    """The simulation as a robot: each `start` places a new random chain of the setting."""

    def __init__(
        self,
        setting: str | Setting,
        pusher: str | None = None,
        seed: int = 0,
        masses: tuple[float, ...] | None = None,
        pushes: int | None = None,
        allow_out_of_range: bool = False,
    ):
        from dataclasses import replace

        from masspush.env import ChainEnv
        from masspush.settings import get_setting

        self.setting = get_setting(setting) if isinstance(setting, str) else setting
        self.pusher = pusher or self.setting.pusher
        config = self.setting.env_config(self.pusher)
        # The environment ends an episode after the setting's pushes unless told otherwise
        # (runs of the policy, `run_segments`, push on).
        if pushes is not None:
            config = replace(config, pushes=pushes)
        self.env = ChainEnv.from_config(config, allow_out_of_range)
        self.governor = reach_governor(self.pusher, config.physics)
        """The stationary robot's speed governor (`run_estimation` applies it), or None."""
        self.n_links = self.setting.n_links
        self.seed = seed
        self.options = None if masses is None else {"masses": list(masses)}
        """Pinned link masses (kg) for every chain, e.g. to record a labelled class."""
        self.truth: dict[str, Any] = {}
        """The current chain's hidden parameters (masses, friction), for scoring only."""

    def start(self) -> RestPose:
        while True:
            obs, info = self.env.reset(seed=self.seed, options=self.options)
            self.seed += 1
            if info["failure"] is None:
                break
        self.truth = {k: info[k] for k in ("masses", "mass_distribution", "friction")}
        self.truth["config"] = info["config"]
        return RestPose(obs[: self.env.physics.obs_dim].copy(), info["lengths"].copy())

    def push(self, action: np.ndarray) -> PushReport:
        obs, _, _, _, info = self.env.step(np.asarray(action, np.float32))
        details = {**info["push"], "settle_time": info["settle_time"], "config": info["config"]}
        speed = float(info["push"]["executed_speed"])
        if info["failure"] is not None:
            return PushReport(None, info["failure"], details, speed)
        return PushReport(obs[: self.env.physics.obs_dim].copy(), None, details, speed)

    def close(self) -> None:
        self.env.close()


class ReplayMismatchError(RuntimeError):
    """A replayed session was asked for a push other than the one recorded."""


class ReplayRobot:
    """Plays back a recorded session: `start` gives the next episode's first rest pose,
    `push` the recorded rest pose after the recorded push. Asking for another push than the
    recorded one is refused: what would have happened is not in the file."""

    def __init__(self, recording: str | os.PathLike, tolerance: float = 1e-4):
        from masspush.data.recording import read_recording

        self.recording = read_recording(recording)
        self.n_links = self.recording.n_links
        self.tolerance = tolerance
        self._next = 0
        self.episode: dict[str, Any] | None = None
        self._k = 0

    @property
    def recorded_actions(self) -> np.ndarray:
        """The current episode's recorded actions (what a `RecordedPolicy` replays)."""
        assert self.episode is not None, "start() first"
        return np.asarray(self.episode["actions"], np.float32)

    @property
    def geometry(self) -> ChainGeometry | None:
        """The chain's geometry, where the recording's header gives it."""
        return self.recording.geometry

    def start(self) -> RestPose:
        if self._next >= len(self.recording.episodes):
            raise StopIteration("every recorded episode has been replayed")
        self.episode = self.recording.episodes[self._next]
        self._next += 1
        self._k = 0
        observations = np.asarray(self.episode["observations"], np.float32)
        return RestPose(observations[0], np.asarray(self.episode["lengths"], np.float32))

    def push(self, action: np.ndarray) -> PushReport:
        assert self.episode is not None, "start() first"
        actions = self.recorded_actions
        if self._k >= len(actions):
            raise ReplayMismatchError(
                f"episode {self.episode['id']!r} has only {len(actions)} recorded pushes"
            )
        if np.max(np.abs(np.asarray(action) - actions[self._k])) > self.tolerance:
            raise ReplayMismatchError(
                f"episode {self.episode['id']!r}, push {self._k + 1}: asked for "
                f"{np.round(action, 4).tolist()}, recorded {actions[self._k].tolist()}; "
                "replay with the recorded pushes (policy 'recorded')"
            )
        self._k += 1
        config = np.asarray(self.episode["observations"][self._k], np.float32)
        speeds = self.episode.get("speeds")
        speed = None if speeds is None else float(speeds[self._k - 1])
        return PushReport(config, None, {"id": self.episode["id"]}, speed)

    def close(self) -> None:
        pass


class RecordedPolicy:
    """The pushes a `ReplayRobot`'s current episode recorded, as a rollout Policy."""

    name = "recorded"

    def __init__(self, robot: ReplayRobot):
        self.robot = robot

    def reset(self, seeds: np.ndarray) -> None:
        pass

    def act(
        self, observations: np.ndarray, actions: np.ndarray, step: int, lengths: np.ndarray
    ) -> np.ndarray:
        return self.robot.recorded_actions[step][None]


BACKENDS = ("target", "replay")
"""Robot backends besides the simulated pushers."""


def is_lab_robot(backend: str) -> bool:
    """Whether `backend` names a lab's own robot, `package.module:factory`, not a shipped one."""
    return ":" in backend


def check_lab_robot_name(backend: str) -> None:
    """ValueError naming `backend` unless it reads `package.module:factory` (checked before
    anything is imported or run)."""
    module, _, factory = backend.partition(":")
    if not all(part.isidentifier() for part in module.split(".")) or not factory.isidentifier():
        raise ValueError(
            f"robot {backend!r}: a robot of your own is named package.module:factory, e.g. "
            "mylab.robot:make_robot"
        )


def load_lab_robot(backend: str) -> Callable[[Setting], Robot]:
    """The factory `backend` (`package.module:factory`) names: called with the `Setting`, it
    returns the lab's `Robot`. The module is looked for on the Python path and in the current
    directory (as `python -m` would find it)."""
    check_lab_robot_name(backend)
    module_name, _, name = backend.partition(":")
    if os.getcwd() not in sys.path and "" not in sys.path:
        sys.path.append(os.getcwd())
    try:
        module = importlib.import_module(module_name)
    except Exception as err:  # the lab's module: any error in it is its own
        raise ValueError(
            f"robot {backend!r}: importing {module_name} failed: {type(err).__name__}: {err}"
        ) from None
    factory = getattr(module, name, None)
    if not callable(factory):
        raise ValueError(f"robot {backend!r}: {module_name} has no callable {name!r}")
    return factory


def check_robot(robot: object, backend: str) -> None:
    """ValueError naming `backend` where what its factory made is not a `Robot`."""
    missing = [m for m in ("start", "push", "close") if not callable(getattr(robot, m, None))]
    if not isinstance(getattr(robot, "n_links", None), int):
        missing.append("an int n_links")
    if missing:
        raise ValueError(
            f"robot {backend!r} made a {type(robot).__name__} without {', '.join(missing)}: a "
            "robot has n_links, start(), push(action) and close() (docs/real-robot.md)"
        )


def make_robot(
    backend: str,
    setting: str | Setting,
    recording: str | None = None,
    seed: int = 0,
    masses: tuple[float, ...] | None = None,
    lab: int | None = None,
    allow_out_of_range: bool = False,
    pushes: int | None = None,
    day: int = 0,
) -> Robot:
    """A robot by backend name: stiff, kuka, ur10 (simulated), target (the sim-to-real
    target world, `masspush.real.target_world`; `lab` keeps one lab's constants, on its day
    `day`), replay (a recording), or a lab's own, `package.module:factory`
    (`load_lab_robot`; `masses` are then only the chain's known masses, for the recording).
    `pushes`: the most pushes an episode may get (a simulated robot's episode otherwise ends
    after the setting's)."""
    if lab is not None and backend != "target":
        raise ValueError(f"a lab is one draw of the target world; backend {backend!r} has none")
    if is_lab_robot(backend):
        from masspush.settings import get_setting

        factory = load_lab_robot(backend)
        try:
            robot = factory(get_setting(setting) if isinstance(setting, str) else setting)
        except Exception as err:  # the lab's code: its error, in one line (its hardware's too)
            raise ValueError(
                f"robot {backend!r}: making it failed: {type(err).__name__}: {err}"
            ) from None
        check_robot(robot, backend)
        return robot
    if backend in PUSHERS:
        return SimRobot(setting, backend, seed, masses, pushes, allow_out_of_range)
    if backend == "target":
        return TargetWorldRobot(setting, seed=seed, masses=masses, lab=lab, day=day)
    if backend == "replay":
        if recording is None:
            raise ValueError("the replay backend needs --episodes FILE (a recording)")
        return ReplayRobot(recording)
    raise ValueError(
        f"unknown robot backend {backend!r}; known: {[*PUSHERS, *BACKENDS]}, or your own as "
        "package.module:factory"
    )
