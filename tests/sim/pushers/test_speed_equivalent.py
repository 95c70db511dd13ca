import numpy as np
import pytest

from masspush.config import PhysicsConfig
from masspush.sim.chain import sample_chain
from masspush.sim.pushers import SpeedEquivalent, make_pusher, speed_equivalent
from masspush.sim.simulate import ChainSim

PHYSICS = PhysicsConfig(n_links=2, mass_range=(0.01, 0.3))
STRAIGHT = {"joint_angles": [0.0], "lengths": [0.12, 0.12], "masses": [0.05, 0.05],
            "friction": 0.5}  # fmt: skip
CONFIG = np.array([0.0, 0.0, 0.3, 0.0])
LENGTHS = [0.12, 0.12]


@pytest.fixture(scope="module")
def ur10() -> SpeedEquivalent:
    equivalent = speed_equivalent("ur10-stationary", PHYSICS)
    assert equivalent is not None
    return equivalent


def test_only_pushers_whose_plan_sets_the_speed_have_one():
    assert speed_equivalent("ur10", PHYSICS) is None  # torque-limited: its plan cannot tell
    assert speed_equivalent("kuka", PHYSICS) is None
    assert isinstance(speed_equivalent("stiff", PHYSICS), SpeedEquivalent)
    with pytest.raises(ValueError, match="not set by its plan"):
        SpeedEquivalent(make_pusher("ur10"), PHYSICS)


def test_the_stiff_pusher_reads_a_speed_as_the_action_of_that_speed():
    stiff = speed_equivalent("stiff", PHYSICS)
    assert stiff.speed(CONFIG, LENGTHS, np.array([-0.4, 0.3])) == pytest.approx(2.0)
    np.testing.assert_allclose(stiff.action(CONFIG, LENGTHS, np.array([-0.4, 0.3]), 1.0),
                               [-0.2, 0.3], rtol=1e-6)  # fmt: skip
    # A push faster than the slowest full-speed one counts as the fastest the pusher makes.
    np.testing.assert_allclose(stiff.action(CONFIG, LENGTHS, np.array([0.4, 0.3]), 9.0), [1, 0.3])


def test_the_planned_speed_is_the_speed_the_stationary_ur10_reaches():
    rng = np.random.default_rng(3)
    equivalent = speed_equivalent("ur10-stationary", PHYSICS)
    compared = 0
    for root in ((0.0, 0.0, 0.3), (0.1, -0.1, 2.0), (-0.1, 0.1, -1.2)):
        chain = sample_chain(PHYSICS, rng, {**STRAIGHT, "root_pose": list(root)})
        sim = ChainSim(chain, PHYSICS, make_pusher("ur10-stationary"))
        action = np.array([rng.choice([-1, 1]) * rng.uniform(0.1, 1.0), rng.uniform(-1, 1)])
        planned = equivalent.speed(sim.config(), chain.lengths, action)
        outcome = sim.push(action)
        if outcome.failure is None:
            assert outcome.executed_speed == pytest.approx(planned, rel=0.1)
            compared += 1
    assert compared >= 2


def test_a_full_speed_push_is_capped_below_the_commanded_speed(ur10):
    top = ur10.speed(CONFIG, LENGTHS, np.array([1.0, 0.5]))
    assert 0 < top < PHYSICS.push_speed_max  # its joints cannot move the tool at 5 m/s
    slow = ur10.speed(CONFIG, LENGTHS, np.array([0.4 * top / PHYSICS.push_speed_max, 0.5]))
    assert slow == pytest.approx(0.4 * top, rel=1e-6)  # below the cap: the command


def test_a_slower_push_than_commanded_reads_as_the_action_of_its_speed(ur10):
    top = ur10.speed(CONFIG, LENGTHS, np.array([-1.0, -0.5]))
    commanded = np.array([-0.5 * top / PHYSICS.push_speed_max, -0.5], np.float32)
    read = ur10.action(CONFIG, LENGTHS, commanded, 0.8 * 0.5 * top)
    np.testing.assert_allclose(read, [0.8 * commanded[0], -0.5], rtol=1e-5)
    # A push at the speed its plan foresaw reads as commanded.
    np.testing.assert_allclose(ur10.action(CONFIG, LENGTHS, commanded, 0.5 * top), commanded,
                               rtol=1e-5)  # fmt: skip


def test_full_speed_pushes_made_at_the_top_speed_read_as_commanded(ur10):
    top = ur10.speed(CONFIG, LENGTHS, np.array([1.0, 0.5]))
    for a1 in (1.0, 0.9):  # both beyond what the arm reaches from here
        action = np.array([a1, 0.5], np.float32)
        np.testing.assert_array_equal(ur10.action(CONFIG, LENGTHS, action, top), action)
    # A capped push that the robot made slower than the cap: the action of that speed.
    read = ur10.action(CONFIG, LENGTHS, np.array([1.0, 0.5]), 0.5 * top)
    assert read[0] == pytest.approx(0.5 * top / PHYSICS.push_speed_max, rel=1e-5)


def test_no_speed_or_an_unmakeable_push_leaves_the_action(ur10):
    action = np.array([0.3, 0.1], np.float32)
    for speed in (None, float("nan"), -1.0):
        np.testing.assert_array_equal(ur10.action(CONFIG, LENGTHS, action, speed), action)
    far = np.array([0.0, 3.0, 0.0, 0.0])  # beyond the arm's reach
    assert ur10.speed(far, LENGTHS, action) is None
    np.testing.assert_array_equal(ur10.action(far, LENGTHS, action, 0.1), action)
