import numpy as np
import pytest

from masspush.config import PhysicsConfig
from masspush.sim.actions import action_to_push, check_action, push_geometry
from masspush.sim.chain import sample_chain
from masspush.sim.simulate import ChainSim

L2 = (0.1, 0.14)
L3 = (0.1, 0.12, 0.14)


@pytest.mark.parametrize(
    ("action", "lengths", "link", "offset_fraction"),
    [
        ((0.5, -1.0), L2, 0, -0.45),  # start of link 0
        ((0.5, -0.5), L2, 0, 0.0),  # centre of link 0
        ((0.5, 0.0), L2, 1, -0.45),  # start of link 1
        ((0.5, 0.75), L2, 1, 0.225),  # the paper's p2 example
        ((0.5, 1.0), L2, 1, 0.45),  # end of the last link (continuous at a2 = 1)
        ((0.5, -1 / 3), L3, 1, -0.45),
        ((0.5, 0.0), L3, 1, 0.0),
        ((0.5, 0.999), L3, 2, 0.44865),
    ],
)
def test_a2_picks_link_and_point_as_the_authors_code(action, lengths, link, offset_fraction):
    physics = PhysicsConfig(n_links=len(lengths))
    push = action_to_push(np.array(action), lengths, physics)
    assert push.link == link
    assert push.offset == pytest.approx(offset_fraction * lengths[link], abs=1e-9)


def test_a1_picks_speed_and_side():
    physics = PhysicsConfig()
    assert action_to_push(np.array([0.4, 0]), L2, physics).speed == pytest.approx(2.0)
    assert action_to_push(np.array([-1.0, 0]), L2, physics).speed == pytest.approx(5.0)
    assert action_to_push(np.array([0.4, 0]), L2, physics).side == 1
    assert action_to_push(np.array([-0.4, 0]), L2, physics).side == -1


@pytest.mark.parametrize(
    ("action", "message"),
    [
        ([1.5, 0.0], "outside the action box"),
        ([0.0, -1.01], "outside the action box"),
        ([float("nan"), 0.0], "NaN"),
        ([0.1, 0.2, 0.3], "shape"),
        ("push", "two numbers"),
    ],
)
def test_bad_actions_are_refused(action, message):
    with pytest.raises(ValueError, match=message):
        check_action(action)


@pytest.mark.parametrize("a1", [0.3, -0.3])
def test_contact_point_lies_on_the_pushed_face_and_points_inward(a1):
    physics = PhysicsConfig(n_links=3)
    chain = sample_chain(physics, np.random.default_rng(5))
    sim = ChainSim(chain, physics)
    push = action_to_push(np.array([a1, 0.2]), chain.lengths, physics)
    geometry = push_geometry(push, sim.config(), chain.lengths, physics)
    geom = sim.data.geom(f"box{push.link}")
    frame = geom.xmat.reshape(3, 3)
    local = frame.T @ (np.r_[geometry.contact, geom.xpos[2]] - geom.xpos)
    assert local[0] == pytest.approx(push.offset, abs=1e-6)
    assert local[1] == pytest.approx(-push.side * physics.link_width / 2, abs=1e-6)
    # The push goes into the box: from the face towards the centre line.
    assert np.dot(frame[:2, 1] * -np.sign(local[1]), geometry.direction) == pytest.approx(1.0)
