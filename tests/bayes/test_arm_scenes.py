import numpy as np
import pytest

from masspush.bayes import arm_scenes
from masspush.bayes.arm_scenes import ArmScene, ArmSimulator
from masspush.settings import get_setting
from masspush.sim.chain import ChainParams
from masspush.sim.pushers import make_pusher, on_batch_path
from masspush.sim.simulate import ChainSim

PHYSICS = get_setting("2link-0.1-1").physics()
LENGTHS = (0.12, 0.14)
START = np.array([0.02, -0.01, 0.4, 0.5])


@pytest.fixture(scope="module")
def scene():
    return ArmScene(PHYSICS, "kuka", LENGTHS)


def test_a_candidate_s_outcome_does_not_depend_on_what_was_pushed_before(scene):
    first = scene.push(START, np.array([0.4, 0.3]), (0.2, 0.8), 0.6)[0]
    scene.push(START + 0.05, np.array([-0.9, -0.5]), (0.9, 0.1), 0.95)
    again = scene.push(START, np.array([0.4, 0.3]), (0.2, 0.8), 0.6)[0]
    np.testing.assert_array_equal(first, again)


def test_a_reused_scene_pushes_like_a_freshly_built_chain(scene):
    masses, mu, action = (0.4, 0.7), 0.8, np.array([0.1, 0.5])
    chain = ChainParams(masses, mu, LENGTHS, tuple(START[3:]), tuple(START[:3]))
    fresh = ChainSim(chain, PHYSICS, make_pusher("kuka"))
    fresh.push(action)
    reused, failure, _ = scene.push(fresh_start(chain), action, masses, mu)
    assert failure is None
    # The arm's inverse kinematics starts elsewhere, so its path differs by a hair.
    np.testing.assert_allclose(reused, fresh.config(), atol=0.01)
    assert np.abs(reused - START).max() > 0.02  # the push moved the chain


def fresh_start(chain: ChainParams) -> np.ndarray:
    return ChainSim(chain, PHYSICS).config()


def _candidates(m: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    starts = START[None] + rng.normal(0, 0.02, (m, len(START)))
    actions = rng.uniform(-1, 1, (m, 2))
    actions[0] = (0.0, 0.3)  # a push of zero speed: no arm
    masses, friction = rng.uniform(0.1, 1, (m, 2)), rng.uniform(0.5, 1, m)
    return starts, actions, masses, friction


def test_worker_processes_give_the_same_outcomes_as_one(monkeypatch):
    monkeypatch.setattr(arm_scenes, "on_batch_path", lambda pusher: False)
    starts, actions, masses, friction = _candidates(4)
    one = ArmSimulator(PHYSICS, "kuka", workers=1)
    assert not one.lockstep
    one = one.simulate(LENGTHS, starts, actions, masses, friction)
    two = ArmSimulator(PHYSICS, "kuka", workers=2)
    both = two.simulate(LENGTHS, starts, actions, masses, friction)
    two.close()
    np.testing.assert_array_equal(one[0], both[0])
    assert one[1] == both[1]


@pytest.mark.skipif(not on_batch_path("kuka"), reason="arms in lockstep need the compiled law")
def test_candidates_in_lockstep_end_where_the_reused_scene_puts_them(scene):
    starts, actions, masses, friction = _candidates(10, seed=3)
    simulator = ArmSimulator(PHYSICS, "kuka", workers=2)
    assert simulator.lockstep
    configs, failures = simulator.simulate(LENGTHS, starts, actions, masses, friction)
    for i in range(len(masses)):
        config, failure, _ = scene.push(starts[i], actions[i], masses[i], float(friction[i]))
        assert failure == failures[i]
        np.testing.assert_array_equal(config, configs[i])
    assert failures.count(None) >= 8
