import math

import numpy as np
import pytest

from masspush.sim.chain import link_poses
from masspush.sim.workspace import ROBOT_FRAME_DIM, Workspace

# A base at (0, -0.7) facing +y, as the stationary UR10's.
WS = Workspace(base=(0.0, -0.7, math.pi / 2), r_min=0.4, r_max=1.0, max_bearing=1.2)
LENGTHS, GAP = (0.12, 0.12), 0.005


def test_polar_measures_from_the_base_axis_and_its_facing():
    r, bearing = WS.polar(np.array([[0.0, 0.0], [0.7, -0.7], [-0.5, -0.7]]))
    np.testing.assert_allclose(r, [0.7, 0.7, 0.5])
    np.testing.assert_allclose(bearing, [0.0, -math.pi / 2, math.pi / 2], atol=1e-12)


@pytest.mark.parametrize(
    ("config", "inside"),
    [
        ([0.0, 0.0, 0.0, 0.0], True),  # the start region, in front of the base
        ([0.0, 0.35, 0.0, 0.0], False),  # too far: r = 1.05 m
        ([0.0, -0.35, 0.0, 0.0], False),  # too near: r = 0.35 m
        ([0.0, 0.2, 0.0, 0.0], True),  # the second link's centre at r = 0.91 m
        ([0.0, 0.25, math.pi / 2, 0.0], False),  # the same, pointing away: r = 1.08
        ([-0.8, -0.6, 0.0, 0.0], False),  # beside the base: bearing 1.45 rad
    ],
)
def test_holds_asks_every_link_centre(config, inside):
    assert WS.holds(np.array(config), LENGTHS, GAP) is inside
    centres, _ = link_poses(np.array(config), LENGTHS, GAP)
    r, bearing = WS.polar(centres)
    expected = bool(np.all((r >= 0.4) & (r <= 1.0) & (np.abs(bearing) <= 1.2)))
    assert expected is inside


def test_robot_frame_is_the_root_pose_seen_from_the_base():
    frame = WS.robot_frame(np.array([0.1, 0.0, math.pi / 2, 0.3]))
    assert frame.shape == (ROBOT_FRAME_DIM,)
    # 0.7 m ahead of the base, 0.1 m to its right (the base faces +y: right is +x).
    np.testing.assert_allclose(frame, [0.7, -0.1, 1.0, 0.0], atol=1e-6)
    batch = WS.robot_frame(np.zeros((3, 2, 4)))
    assert batch.shape == (3, 2, ROBOT_FRAME_DIM)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"r_min": 0.5, "r_max": 0.5},
        {"r_min": -0.1},
        {"max_bearing": 0.0},
        {"max_bearing": 4.0},
    ],
)
def test_bad_bounds_are_refused(kwargs):
    args = {"base": (0.0, 0.0, 0.0), "r_min": 0.4, "r_max": 1.0, "max_bearing": 1.0, **kwargs}
    with pytest.raises(ValueError):
        Workspace(**args)
