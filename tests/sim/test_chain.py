import math

import mujoco
import numpy as np
import pytest

from masspush.config import PhysicsConfig
from masspush.sim.chain import ChainParams, compile_scene, link_poses, quat_yaw, sample_chain
from masspush.sim.simulate import ChainSim


@pytest.mark.parametrize("n_links", [2, 3, 5])
def test_planar_kinematics_matches_mujoco(n_links, rng):
    physics = PhysicsConfig(n_links=n_links)
    chain = sample_chain(physics, rng)
    sim = ChainSim(chain, physics)
    centres, headings = link_poses(sim.config(), chain.lengths, physics.joint_gap)
    for i in range(n_links):
        geom = sim.data.geom(f"box{i}")
        np.testing.assert_allclose(centres[i], geom.xpos[:2], atol=1e-6)
        heading = math.atan2(geom.xmat[3], geom.xmat[0])
        assert abs((heading - headings[i] + math.pi) % (2 * math.pi) - math.pi) < 1e-6


def test_initial_pose_is_the_sampled_one_and_at_rest(physics3, rng):
    chain = sample_chain(physics3, rng)
    sim = ChainSim(chain, physics3)
    assert sim.initial_failure is None
    # Settling under gravity moves the chain by well under a millimetre / milliradian.
    np.testing.assert_allclose(sim.config(), chain.initial_config, atol=1e-3)
    assert np.abs(sim.data.qvel[: sim.layout.nv]).max() < physics3.rest_velocity


def test_sampling_is_within_ranges_and_deterministic(physics3):
    a = [sample_chain(physics3, np.random.default_rng(7)) for _ in range(2)]
    assert a[0] == a[1]
    chains = [sample_chain(physics3, np.random.default_rng(s)) for s in range(50)]
    masses = np.array([c.masses for c in chains])
    assert masses.min() >= 0.1 and masses.max() <= 1.0
    assert all(0.5 <= c.friction <= 1.0 for c in chains)
    assert all(0.1 <= min(c.lengths) and max(c.lengths) <= 0.15 for c in chains)
    assert all(max(abs(np.array(c.joint_angles))) <= 0.75 for c in chains)


def test_a_narrowed_heading_range_turns_the_chain_and_nothing_else(physics2):
    from dataclasses import replace

    laid = replace(physics2, root_yaw_range=(1.0, 1.2))
    for seed in range(20):
        free = sample_chain(physics2, np.random.default_rng(seed))
        turned = sample_chain(laid, np.random.default_rng(seed))
        assert 1.0 <= turned.root_pose[2] <= 1.2
        # the same draws otherwise, so runs with and without it pair chain by chain
        assert turned.masses == free.masses and turned.lengths == free.lengths
        assert turned.joint_angles == free.joint_angles
        assert tuple(turned.root_pose[:2]) == tuple(free.root_pose[:2])
    # about +-pi the heading is drawn wrapped, as the chain's pose is observed
    across = replace(physics2, root_yaw_range=(3.0, 3.3))
    yaws = [sample_chain(across, np.random.default_rng(s)).root_pose[2] for s in range(40)]
    assert all(-math.pi <= y < math.pi for y in yaws)
    assert min(np.cos(np.array(yaws) - 3.15)) >= math.cos(0.15) - 1e-12  # in the range, mod 2pi
    assert min(yaws) < 0 < max(yaws)  # both sides of the cut
    with pytest.raises(ValueError, match="root_yaw_range is empty"):
        PhysicsConfig(root_yaw_range=(1.0, 0.0))


def test_pinning_one_parameter_leaves_the_other_draws_unchanged(physics2):
    free = sample_chain(physics2, np.random.default_rng(3))
    pinned = sample_chain(physics2, np.random.default_rng(3), {"masses": [0.2, 0.8]})
    assert pinned.masses == (0.2, 0.8)
    assert (pinned.friction, pinned.lengths, pinned.joint_angles) == (
        free.friction,
        free.lengths,
        free.joint_angles,
    )


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"mass": [1, 1]}, "unknown option"),
        ({"masses": [1.0, -1.0]}, "masses must be positive"),
        ({"masses": [1.0]}, "masses must have 2 values"),
        ({"friction": 0.0}, "friction"),
        ({"friction": -0.5}, "friction"),
        ({"lengths": [0.1, 0.0]}, "lengths must be positive"),
        ({"joint_angles": [2.0]}, "joint limit"),
        ({"joint_angles": [float("nan")]}, "finite"),
    ],
)
def test_bad_pins_raise_clear_errors(physics2, options, message):
    with pytest.raises(ValueError, match=message):
        sample_chain(physics2, np.random.default_rng(0), options)


def test_chain_params_validate():
    with pytest.raises(ValueError, match="at least 2 links"):
        ChainParams((1.0,), 0.5, (0.1,), (), (0, 0, 0))
    chain = ChainParams((1.0, 3.0), 0.5, (0.1, 0.1), (0.0,), (0, 0, 0))
    np.testing.assert_allclose(chain.mass_distribution, [0.25, 0.75])


def test_quat_yaw():
    for yaw in (-3.0, -0.5, 0.0, 1.2, 3.1):
        q = np.array([math.cos(yaw / 2), 0, 0, math.sin(yaw / 2)])
        assert quat_yaw(q) == pytest.approx(yaw)


def test_self_collision_stops_neighbouring_links_passing_through():
    """With the joint limit out of the way, only the boxes themselves can stop a fold."""
    physics = PhysicsConfig(n_links=2, joint_limit=3.1)
    chain = sample_chain(
        physics,
        np.random.default_rng(0),
        {"joint_angles": [1.2], "lengths": [0.12, 0.12], "root_pose": [0, 0, 0]},
    )
    sim = ChainSim(chain, physics)
    ids = {sim.model.geom("box0").id, sim.model.geom("box1").id}
    sim.data.qvel[sim.layout.nv - 1] = 30.0  # fold link 1 onto link 0 at 30 rad/s
    max_angle, deepest, touched = 0.0, 0.0, False
    for _ in range(400):
        mujoco.mj_step(sim.model, sim.data)
        max_angle = max(max_angle, abs(sim.config()[3]))
        for c in sim.data.contact[: sim.data.ncon]:
            if {c.geom1, c.geom2} == ids:
                touched = True
                deepest = min(deepest, c.dist)
    assert touched, "the links never touched"
    # Boxes of width w with a gap w between them meet at pi/2; they must not pass it.
    assert max_angle < math.pi / 2 + 0.15
    assert deepest > -0.005


def _model_differences(a: mujoco.MjModel, b: mujoco.MjModel) -> list[str]:
    """The names of the model fields (arrays, options, statistics) whose bits differ."""
    differ = []
    for name in dir(a):
        value = getattr(a, name) if not name.startswith("_") else None
        if isinstance(value, np.ndarray):
            other = getattr(b, name)
            if value.shape != other.shape or not np.array_equal(value, other, equal_nan=True):
                differ.append(name)
    for group in ("opt", "stat", "vis"):
        x, y = getattr(a, group), getattr(b, group)
        for name in dir(x):
            if name.startswith("_") or callable(getattr(x, name)):
                continue
            try:
                same = np.array_equal(np.asarray(getattr(x, name)), np.asarray(getattr(y, name)))
            except TypeError:  # a nested struct: its fields do not change with the chain
                continue
            if not same:
                differ.append(f"{group}.{name}")
    return differ


@pytest.mark.parametrize("n_links", [2, 3])
@pytest.mark.parametrize("scene", ["stiff", "kuka", "ur10-stationary", "settling"])
def test_a_reused_scene_is_the_compiled_scene_to_the_last_bit(n_links, scene):
    from masspush.sim.pushers import make_pusher
    from masspush.sim.simulate import add_settling_anchor

    physics = PhysicsConfig(n_links=n_links, mass_range=(0.1, 10.0))
    add = add_settling_anchor if scene == "settling" else make_pusher(scene).add_to
    rng = np.random.default_rng(n_links)
    chains = [sample_chain(physics, rng) for _ in range(12)]
    # Extremes: the joints at their limits, a chain turned half round, the lightest links.
    limit = physics.joint_limit
    angles = (limit,) + (-limit,) * (n_links - 2)
    chains.append(
        ChainParams((0.1,) * n_links, 0.2, (0.08,) * n_links, angles, (-0.4, 0.3, math.pi))
    )
    for chain in chains:
        compiled = compile_scene(chain, physics, add)
        reused = compile_scene(chain, physics, add, reuse=f"test-{scene}")
        assert _model_differences(reused, compiled) == []
    # A field that differs is found: the check can fail.
    other = compile_scene(chains[0], physics, add, reuse=f"test-{scene}")
    assert "stat.meaninertia" in _model_differences(other, compiled)


def test_link_poses_of_a_batch_are_each_configuration_s(rng):
    lengths, gap = (0.1, 0.15, 0.12), 0.005
    configs = rng.uniform(-1, 1, size=(4, 3, 5))
    centres, headings = link_poses(configs, lengths, gap)
    assert centres.shape == (4, 3, 3, 2) and headings.shape == (4, 3, 3)
    one_centres, one_headings = link_poses(configs[2, 1], lengths, gap)
    np.testing.assert_allclose(centres[2, 1], one_centres)
    np.testing.assert_allclose(headings[2, 1], one_headings)
