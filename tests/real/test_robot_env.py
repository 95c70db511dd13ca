import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from masspush.real.robot_env import RobotEnv
from masspush.real.target_world import TargetWorldRobot, WorldRanges

SETTING = "2link-1-10"  # the stiff pusher keeps these tests fast


def make_env(pushes: int = 2) -> RobotEnv:
    return RobotEnv(TargetWorldRobot(SETTING, world=WorldRanges()), pushes)


def test_the_robot_passes_gymnasiums_checks():
    check_env(make_env(), skip_render_check=True)


def test_episodes_follow_the_reset_seed_and_end_after_the_pushes():
    env, other = make_env(), make_env()
    obs, info = env.reset(seed=5)
    again, _ = other.reset(seed=5)
    np.testing.assert_array_equal(obs, again)
    assert not np.array_equal(obs, other.reset(seed=6)[0])
    # The observation is the configuration as tracked, then the lengths the robot was told.
    assert obs.shape == (2 + 2 + 2,)
    np.testing.assert_array_equal(obs[4:], info["lengths"])
    np.testing.assert_allclose(info["mass_distribution"].sum(), 1.0)
    done, pushes = False, 0
    while not done:
        _, reward, done, truncated, step_info = env.step(np.array([0.5, 0.5], np.float32))
        pushes += 1
        assert reward == 0.0 and not truncated
    assert pushes == 2 or step_info["failure"] is not None
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.array([0.5, 0.5], np.float32))


def test_bad_uses_are_refused():
    with pytest.raises(ValueError, match="pushes"):
        RobotEnv(TargetWorldRobot(SETTING), 0)
    env = make_env()
    with pytest.raises(ValueError, match="options"):
        env.reset(seed=0, options={"masses": [0.5, 0.5]})
    env.reset(seed=0)
    with pytest.raises(ValueError, match="outside the action box"):
        env.step(np.array([2.0, 0.0]))
