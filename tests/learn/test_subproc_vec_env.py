import signal

import gymnasium as gym
import numpy as np
import pytest

from masspush.learn.subproc_vec_env import WatchedSubprocVecEnv, WorkerDiedError


class Breaks(gym.Env):
    """Steps fine, except that environment `broken` raises on its second step."""

    observation_space = gym.spaces.Box(-1.0, 1.0, (1,))
    action_space = gym.spaces.Box(-1.0, 1.0, (1,))

    def __init__(self, index: int, broken: int):
        self.index, self.broken, self.steps = index, broken, 0

    def reset(self, *, seed=None, options=None):
        return np.zeros(1, np.float32), {}

    def step(self, action):
        self.steps += 1
        if self.index == self.broken and self.steps == 2:
            raise RuntimeError("the simulation broke")
        return np.zeros(1, np.float32), 0.0, False, False, {}


def make(broken: int) -> WatchedSubprocVecEnv:
    fns = [lambda i=i: Breaks(i, broken) for i in range(3)]
    return WatchedSubprocVecEnv(fns, start_method="fork")


@pytest.fixture
def deadline():
    """Fail a test that hangs (the bug this module mends) instead of hanging the suite."""

    def hung(signum, frame):
        raise TimeoutError("the vectorised environment hung")

    previous = signal.signal(signal.SIGALRM, hung)
    signal.alarm(60)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


@pytest.mark.parametrize("broken", [0, 2])  # the last worker's pipe is held by its siblings
def test_a_dead_worker_fails_the_step_instead_of_hanging(broken, deadline):
    vec = make(broken)
    vec.reset()
    actions = np.zeros((3, 1), np.float32)
    vec.step(actions)
    with pytest.raises(WorkerDiedError, match=f"worker {broken} died .*resume"):
        vec.step(actions)
    vec.close()  # stops the living workers without waiting on the dead one
    assert not any(p.is_alive() for p in vec.processes)


def test_healthy_workers_step_and_close():
    vec = make(broken=-1)
    vec.reset()
    for _ in range(3):
        obs, _, dones, _ = vec.step(np.zeros((3, 1), np.float32))
    assert obs.shape == (3, 1) and not dones.any()
    vec.close()
    assert not any(p.is_alive() for p in vec.processes)


def test_the_error_is_one_the_command_line_reports_in_a_line():
    assert issubclass(WorkerDiedError, OSError)  # masspush's CLI prints OSErrors as one line
