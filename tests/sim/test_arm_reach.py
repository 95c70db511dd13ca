import numpy as np
import pytest

from masspush.settings import get_setting
from masspush.sim.arm_reach import ReachCheck, reach_check
from masspush.sim.chain import ChainParams
from masspush.sim.pushers import make_pusher
from masspush.sim.simulate import ChainSim

SETTING = get_setting("real-ur10")  # the UR10 standing at (0, -0.7), facing +y
LENGTHS = [0.12, 0.12]
PUSH = np.array([0.3, -0.5])  # link 1's middle, 1.5 m/s


def test_the_check_says_what_the_arm_then_does():
    physics = SETTING.physics()
    check = reach_check(SETTING.pusher, physics)
    near, far = np.array([0.0, 0.0, 0.3, 0.2]), np.array([0.0, 1.2, 0.3, 0.2])
    assert check(PUSH, near, LENGTHS)
    assert not check(PUSH, far, LENGTHS)  # 1.9 m from the base: beyond the UR10's reach
    assert check(np.array([0.0, 0.2]), far, LENGTHS)  # no speed: nothing to reach
    # The arm makes the push the check allows, at the origin of its workspace.
    chain = ChainParams(masses=(0.1, 0.1), friction=0.6, lengths=tuple(LENGTHS),
                        joint_angles=(0.2,), root_pose=(0.0, 0.0, 0.3))  # fmt: skip
    sim = ChainSim(chain, physics, make_pusher(SETTING.pusher))
    assert sim.initial_failure is None
    assert sim.push(PUSH).failure != "unreachable"


def test_only_a_stationary_arm_has_one():
    physics = get_setting("2link-1-10").physics()
    assert reach_check("stiff", physics) is None
    assert reach_check("ur10", physics) is None  # its base follows the chain
    with pytest.raises(ValueError, match="stationary arm"):
        ReachCheck("ur10", physics)
