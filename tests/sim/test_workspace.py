import dataclasses
import math

import numpy as np
import pytest

from masspush.config import PhysicsConfig
from masspush.sim.chain import link_poses
from masspush.sim.workspace import (
    ROBOT_FRAME_DIM,
    ReachGovernor,
    Workspace,
    fit_slides,
    push_slides,
)

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


# --- the speed governor -----------------------------------------------------------------
GOVERNOR = ReachGovernor(WS, PhysicsConfig())
CHAIN_LENGTHS = (0.125, 0.125)


def chain_at(y: float) -> np.ndarray:
    """A straight chain along +x, its first link centred at (0, y): 0.7 + y m from the base."""
    return np.array([0.0, y, 0.0, 0.0])


def test_a_push_in_the_middle_of_the_workspace_is_left_as_it_is():
    action = np.array([1.0, -0.3], np.float32)  # full speed, away from the base
    np.testing.assert_array_equal(GOVERNOR(action, chain_at(0.0), CHAIN_LENGTHS), action)


def test_a_push_out_of_reach_is_slowed_to_the_fastest_safe_one():
    config = chain_at(0.15)  # 0.15 m from the far edge, pushed towards it
    governed = GOVERNOR(np.array([1.0, -0.3], np.float32), config, CHAIN_LENGTHS)
    assert 0.0 < governed[0] < 0.5 and governed[1] == np.float32(-0.3)  # same link and point
    assert GOVERNOR.safe(governed, config, CHAIN_LENGTHS)
    assert not GOVERNOR.safe(governed + np.array([0.01, 0.0]), config, CHAIN_LENGTHS)
    np.testing.assert_array_equal(GOVERNOR(governed, config, CHAIN_LENGTHS), governed)
    # From the other side the same push points back into the workspace: left alone.
    back = np.array([-1.0, -0.3], np.float32)
    np.testing.assert_array_equal(GOVERNOR(back, config, CHAIN_LENGTHS), back)


def test_the_side_of_the_push_is_kept_when_it_is_slowed_to_nearly_nothing():
    # 2 cm from the near edge, pushed towards the base: about 0.18 m/s is left.
    governed = GOVERNOR(np.array([-0.8, 0.5]), chain_at(-0.28), CHAIN_LENGTHS)
    assert -0.05 < governed[0] <= 0.0 and math.copysign(1.0, governed[0]) == -1.0


def test_the_slide_grows_with_speed_up_to_the_arms_top_slide():
    config = chain_at(0.1)  # 0.19 m of room for the second link's centre, pushed outwards
    assert GOVERNOR.safe(np.array([0.2, 0.0]), config, CHAIN_LENGTHS)
    assert not GOVERNOR.safe(np.array([0.5, 0.0]), config, CHAIN_LENGTHS)
    roomy = ReachGovernor(Workspace(WS.base, 0.4, 1.0, 1.2, slide_max=0.1), PhysicsConfig())
    assert roomy.safe(np.array([1.0, 0.0]), config, CHAIN_LENGTHS)  # no push slides further


def test_slide_bounds_are_validated():
    with pytest.raises(ValueError, match="slide"):
        Workspace(base=(0.0, 0.0, 0.0), r_min=0.4, r_max=1.0, max_bearing=1.0, slide_max=-0.1)


def test_push_slides_measures_along_and_across_the_push():
    physics = PhysicsConfig()
    before = chain_at(0.0)
    after = before + np.array([0.02, 0.10, 0.0, 0.0])  # 10 cm along +y, 2 cm across
    # a1 > 0 on a chain along +x pushes towards +y (`push_geometry`): 0.4 x 5 m/s.
    speed, along, across = push_slides(
        before[None], after[None], np.array([[0.4, 0.0]]), np.array([CHAIN_LENGTHS]), physics
    )
    np.testing.assert_allclose([speed[0], along[0], across[0]], [2.0, 0.10, 0.02], atol=1e-9)


def test_fit_slides_reads_the_quantiles_of_the_pushes():
    rng = np.random.default_rng(0)
    speed = rng.uniform(0.0, 5.0, 4000)
    along = np.minimum(0.1 * speed, 0.25) * rng.uniform(0.0, 1.0, 4000)
    bounds = fit_slides(speed, along, 0.5 * along)
    assert 0.2 <= bounds["slide_base"] + 2.0 * bounds["slide_per_speed"] <= 0.23  # 2 m/s
    assert bounds["slide_max"] == pytest.approx(0.25, abs=0.01)
    assert bounds["slide_sideways"] == pytest.approx(0.5, abs=0.01)
    with pytest.raises(ValueError, match="too few pushes"):
        fit_slides(speed[:10], along[:10], along[:10])
    with pytest.raises(ValueError, match="quantile"):
        fit_slides(speed, along, along, quantile=1.0)


def test_fitted_bounds_hold_slow_pushes_which_slide_even_at_low_speed():
    # As in lab 5 of the target world: a slow push still carries the chain a few cm (the
    # tool's travel past the face), which a bound through zero denies it, so the governor
    # let chains near the edge go with slow pushes (docs/notebook 2026-12-02-reach-governor).
    rng = np.random.default_rng(1)
    speed = rng.uniform(0.0, 5.0, 4000)
    along = np.minimum(0.03 + 0.1 * speed, 0.25) * rng.uniform(0.0, 1.0, 4000)
    b = fit_slides(speed, along, along)
    bound = np.minimum(b["slide_max"], b["slide_base"] + b["slide_per_speed"] * speed)
    slow = speed <= 0.5
    assert (along[slow] > bound[slow]).mean() <= 0.02
    assert (along > bound).mean() <= 0.02
    assert 0.03 <= b["slide_base"] <= 0.03 + 0.1 * 0.5 + 0.005  # not looser than the slow bin
    through_zero = np.minimum(b["slide_max"], 0.1 * speed)  # the true slope, no base
    assert (along[slow] > through_zero[slow]).mean() > 0.1


def test_a_governor_with_a_base_slide_keeps_a_slow_push_off_the_edge():
    config = chain_at(0.1)  # 0.19 m of room for the second link's centre, pushed outwards
    slow = np.array([0.02, 0.0])  # 0.1 m/s
    assert GOVERNOR.safe(slow, config, CHAIN_LENGTHS)
    based = ReachGovernor(dataclasses.replace(WS, slide_base=0.25), PhysicsConfig())
    assert not based.safe(slow, config, CHAIN_LENGTHS)


def test_headroom_is_the_nearest_centre_s_distance_to_the_boundary():
    # A straight chain along +x at the table origin: its second centre (0.125, 0) lies
    # 0.711 m out; the nearer side of the reach is the outer arc, 0.289 m away.
    room = WS.headroom(np.zeros(4), LENGTHS, GAP)
    centres, _ = link_poses(np.zeros(4), LENGTHS, GAP)
    r, _ = WS.polar(centres)
    assert room == pytest.approx(1.0 - r.max())
    # Nearer the outer arc, less room; beyond it, negative; in a batch, each its own.
    configs = np.array([[0.0, y, 0.0, 0.0] for y in (0.0, 0.2, 0.35, -0.35)])
    rooms = WS.headroom(configs, LENGTHS, GAP)
    assert rooms.shape == (4,) and rooms[1] < rooms[0] and rooms[2] < 0 and rooms[3] < 0
    for config, value in zip(configs, rooms, strict=True):
        assert bool(value >= 0) is WS.holds(config, LENGTHS, GAP)
    # Beside the base, past the side line: negative too.
    assert WS.headroom(np.array([-0.8, -0.6, 0.0, 0.0]), LENGTHS, GAP) < 0
