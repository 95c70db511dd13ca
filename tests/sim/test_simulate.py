import itertools
import math

import mujoco
import numpy as np
import pytest

from masspush.config import PhysicsConfig
from masspush.sim.chain import link_poses, sample_chain
from masspush.sim.pushers import make_pusher
from masspush.sim.simulate import NAN, OK, UNSTABLE, ChainSim, classify

G = 9.81
STRAIGHT = {"joint_angles": [0.0], "lengths": [0.12, 0.12], "root_pose": [0.0, 0.0, 0.0]}


def chain2(masses=(0.4, 0.4), friction=0.7, **pins):
    physics = PhysicsConfig(n_links=2)
    options = {**STRAIGHT, "masses": list(masses), "friction": friction, **pins}
    return sample_chain(
        physics, np.random.default_rng(0), options, allow_out_of_range=True
    ), physics


@pytest.mark.parametrize(("speed", "friction"), [(0.5, 0.7), (1.0, 0.5), (2.0, 1.0)])
def test_sliding_distance_matches_coulomb_friction(speed, friction):
    chain, physics = chain2(friction=friction)
    sim = ChainSim(chain, physics)
    x0 = sim.config()[:2].copy()
    sim.data.qvel[0] = speed  # the whole straight chain slides along its axis
    failure, _ = sim.settle()
    assert failure is None
    distance = np.linalg.norm(sim.config()[:2] - x0)
    assert distance == pytest.approx(speed**2 / (2 * friction * G), rel=0.03)


def test_at_rest_means_at_rest():
    chain, physics = chain2(masses=(0.3, 0.7))
    sim = ChainSim(chain, physics)
    outcome = sim.push(np.array([0.5, 0.3]))
    assert outcome.failure is None
    before = sim.config()
    for _ in range(1000):  # one more simulated second
        mujoco.mj_step(sim.model, sim.data)
    drift = np.abs(sim.config() - before)
    assert drift[:2].max() < 5e-4 and drift[2:].max() < 5e-3


def _pushed_link_travel(masses, action):
    chain, physics = chain2(masses=masses)
    sim = ChainSim(chain, physics)
    q0 = sim.config()
    outcome = sim.push(np.array(action))
    assert outcome.failure is None
    link = outcome.push.link
    before = link_poses(q0, chain.lengths, physics.joint_gap)[0][link]
    after = link_poses(sim.config(), chain.lengths, physics.joint_gap)[0][link]
    return np.linalg.norm(after - before)


def test_heavier_pushed_link_moves_further_with_a_stiff_pusher():
    """The stiff pusher imposes the pushed link's speed whatever its mass; after release,
    a light neighbour holds a heavy link back less. (Under a force-limited pusher, such as
    an arm, the opposite holds: a heavier link moves less. docs/simulation.md.)"""
    travel = [_pushed_link_travel((m, 0.5), [0.2, -0.5]) for m in (0.2, 0.5, 1.0, 2.0)]
    assert all(b > a for a, b in itertools.pairwise(travel)), travel


@pytest.mark.parametrize("action", [[0.2, -0.5], [0.1, 0.5], [-0.3, 0.1]])
def test_common_mass_scale_leaves_rest_pose_unchanged_but_ratio_does_not(action):
    poses = {}
    for name, masses in {
        "base": (0.3, 0.6),
        "x0.1": (0.03, 0.06),
        "x10": (3.0, 6.0),
        "swapped": (0.6, 0.3),
    }.items():
        chain, physics = chain2(masses=masses, joint_angles=[0.3])
        sim = ChainSim(chain, physics)
        assert sim.push(np.array(action)).failure is None
        poses[name] = sim.config()
    for scaled in ("x0.1", "x10"):
        diff = np.abs(poses[scaled] - poses["base"])
        assert diff[:2].max() < 0.005 and diff[2:].max() < 0.03, (scaled, diff)
    ratio_effect = np.abs(poses["swapped"] - poses["base"])
    assert ratio_effect[2:].max() > 0.1, ratio_effect


def test_classify_reports_nan_tipped_and_flying_chains():
    physics = PhysicsConfig(n_links=2)
    chain, _ = chain2()
    layout = ChainSim(chain, physics).layout
    qpos = np.zeros((4, 10))
    qpos[:, 2] = physics.link_height / 2
    qpos[:, 3] = 1.0
    qvel = np.zeros((4, 9))
    qpos[1, 0] = np.nan
    qpos[2, 3:7] = [math.cos(0.5), math.sin(0.5), 0, 0]  # rolled by 1 rad, at rest
    qpos[3, 2] = 1.0  # a metre above the table
    qvel[3, 2] = 1.0
    code, at_rest = classify(qpos, qvel, layout, physics)
    assert code.tolist() == [OK, NAN, UNSTABLE, UNSTABLE]
    assert at_rest.tolist() == [True, False, False, False]


def test_timeout_is_reported_not_hidden():
    physics = PhysicsConfig(n_links=2, settle_time_cap=0.02)
    chain = sample_chain(physics, np.random.default_rng(0), STRAIGHT)
    outcome = ChainSim(chain, physics).push(np.array([1.0, -0.5]))
    assert outcome.failure == "timeout"


def test_diverged_simulation_is_reported_and_state_restored():
    chain, physics = chain2()
    sim = ChainSim(chain, physics)
    before = sim.config()
    sim.model.opt.gravity[2] = np.inf  # makes every later step produce NaN
    outcome = sim.push(np.array([0.5, 0.0]))
    assert outcome.failure == "nan"
    np.testing.assert_array_equal(sim.config(), before)


def test_classify_one_agrees_with_the_batch_classify():
    from masspush.sim.simulate import classify, classify_one

    chain, physics = chain2()
    sim = ChainSim(chain, physics)
    rng = np.random.default_rng(0)
    base_q, base_v = sim.data.qpos.copy(), sim.data.qvel.copy()
    seen = set()
    for _ in range(2000):
        q, v = base_q.copy(), base_v.copy()
        v[: sim.layout.nv] = rng.choice([0.0, 1e-4, 9.9e-4, 1e-3, 0.5, 600.0]) * rng.uniform(
            -1, 1, sim.layout.nv
        )
        r = sim.layout.root_qpos
        q[r + 4 : r + 6] = rng.choice([0.0, 0.03, 0.05, 0.5]) * rng.uniform(-1, 1, 2)
        q[r + 2] += rng.choice([0.0, 0.1, 0.3, -0.3])
        if rng.uniform() < 0.05:
            (q if rng.uniform() < 0.5 else v)[rng.integers(len(v))] = rng.choice([np.nan, np.inf])
        codes, at_rest = classify(q, v, sim.layout, physics)
        one = classify_one(q, v, sim.layout, physics)
        assert one == (int(codes[0]), bool(at_rest[0]))
        seen.add(one)
    assert len(seen) >= 4  # every outcome came up: moving, at rest, unstable, nan


@pytest.mark.slow
@pytest.mark.parametrize("arm", ["kuka", "ur10"])
@pytest.mark.parametrize("n_links", [2, 3])
def test_a_chain_an_arm_pushed_settles_alone_to_the_arm_scenes_rest_pose(arm, n_links):
    physics = PhysicsConfig(n_links=n_links, mass_range=(0.1, 10.0))
    rng = np.random.default_rng(20 + n_links)
    pushes = settled_alone = 0
    for _ in range(6):
        chain = sample_chain(physics, rng)
        reference = ChainSim(chain, physics, make_pusher(arm), settle_alone=False)
        alone = ChainSim(chain, physics, make_pusher(arm))
        watched = ChainSim(chain, physics, make_pusher(arm))
        # A video watches the arm's scene, so the chain settles there (and the Python law
        # pushes: within 1e-9 of the compiled one).
        watched.on_step = lambda: None
        steps_in_alone = []
        alone_step = alone._alone[1]
        for action in rng.uniform(-1, 1, size=(3, 2)):
            time_before, watched_before = alone_step.time, watched._alone[1].time
            outcome = reference.push(action)
            assert alone.push(action) == outcome
            np.testing.assert_array_equal(alone.config(), reference.config())
            assert watched.push(action).failure == outcome.failure
            np.testing.assert_allclose(watched.config(), reference.config(), rtol=0, atol=1e-9)
            assert watched._alone[1].time == watched_before
            pushes += 1
            steps_in_alone.append(alone_step.time > time_before)
            if outcome.failure is not None:
                break
        settled_alone += sum(steps_in_alone)
    assert pushes >= 12 and settled_alone >= pushes // 2
