import math

import mujoco
import numpy as np
import pytest

from masspush.real.backends import make_robot
from masspush.real.target_world import (
    FrictionField,
    TargetWorld,
    TargetWorldRobot,
    WorldRanges,
    scaled_world,
)
from masspush.sim.chain import wrap_angle

SETTING = "2link-1-10"  # the stiff pusher keeps these tests fast


def robot(world: TargetWorld | None = None, seed: int = 3) -> TargetWorldRobot:
    return TargetWorldRobot(SETTING, world, seed=seed, masses=(2.0, 6.0))


def test_the_model_differs_from_training_as_configured():
    r = robot()
    r.start()
    m = r.sim.model
    assert m.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    assert m.opt.solver == mujoco.mjtSolver.mjSOL_CG
    assert m.opt.timestep == 0.0005
    assert list(m.geom_condim[r._boxes]) == [4, 4]
    np.testing.assert_allclose(m.geom_solref[r._boxes], [[0.01, 0.8]] * 2)
    # Geometry: the boxes are the world's size, not the training world's 4 x 3 cm.
    np.testing.assert_allclose(m.geom_size[r._boxes][:, 1:], [[0.0225, 0.0175]] * 2)
    # The solver and cones are knobs too (the ablation script puts them back to training's).
    r = robot(TargetWorld(solver="Newton", cone="elliptic"))
    r.start()
    assert r.sim.model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert r.sim.model.opt.solver == mujoco.mjtSolver.mjSOL_NEWTON


def test_each_link_feels_the_friction_of_the_table_where_it_lies():
    r = robot()
    r.start()
    r.push(np.array([0.6, 0.3]))
    xy = r.sim.data.geom_xpos[r._boxes, :2]
    felt = r.sim.model.geom_friction[r._boxes, 0]
    np.testing.assert_allclose(felt, r.field(xy), rtol=1e-3)  # last step's positions
    assert felt[0] != felt[1]


def test_the_friction_field_varies_around_its_mean_by_the_configured_amount():
    world = TargetWorld(friction_variation=0.15)
    field = FrictionField(0.8, world, np.random.default_rng(0))
    xy = np.random.default_rng(1).uniform(-3, 3, size=(20_000, 2))
    mu = field(xy)
    assert abs(mu.mean() - 0.8) < 0.02
    assert 0.08 < mu.std() / 0.8 < 0.22
    assert mu.min() >= 0.4 and mu.max() <= 1.2


def test_tracking_bias_is_held_for_an_episode_and_drawn_anew_for_the_next():
    r = robot(TargetWorld(obs_noise=0.0))
    seen = r.start()
    errors = [seen.config - r.sim.config()]
    report = r.push(np.array([0.5, 0.2]))
    errors.append(report.config - r.sim.config())
    errors = [np.concatenate([e[:2], [wrap_angle(e[2])], e[3:]]) for e in errors]
    np.testing.assert_allclose(errors[0], errors[1], atol=1e-5)
    assert np.abs(errors[0]).max() > 1e-3
    next_start = r.start()
    assert not np.allclose(next_start.config - r.sim.config(), errors[0], atol=1e-5)


def test_observing_again_sees_the_chain_where_the_last_push_left_it():
    r = robot(TargetWorld(obs_noise=0.0))
    seen = r.start()
    np.testing.assert_array_equal(r.observe(), seen.config)
    report = r.push(np.array([0.5, 0.2]))
    np.testing.assert_array_equal(r.observe(), report.config)
    assert not np.allclose(report.config, seen.config, atol=1e-3)


def test_actuation_has_a_per_episode_gain_and_contact_bias():
    r = robot(TargetWorld(action_noise=0.0))
    r.start()
    a = np.array([0.4, 0.1])
    executed = [r.push(a).details["executed"] for _ in range(2)]
    np.testing.assert_allclose(executed[0], executed[1])
    assert executed[0][0] == pytest.approx(0.4 * r.gain)
    assert executed[0][1] == pytest.approx(0.1 + r.contact)
    assert not np.allclose(executed[0], a)


def test_the_robot_is_told_measured_lengths_not_the_true_ones():
    r = robot()
    rest = r.start()
    error = rest.lengths - r.truth["lengths"]
    assert 0 < np.abs(error).max() < 0.015


def test_the_same_seed_gives_the_same_episode():
    runs = []
    for _ in range(2):
        r = robot(seed=5)
        rest = r.start()
        report = r.push(np.array([0.7, -0.2]))
        runs.append(np.concatenate([rest.config, report.config, rest.lengths]))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_pinned_masses_are_the_chain_masses():
    r = robot()
    r.start()
    np.testing.assert_allclose(r.truth["masses"], [2.0, 6.0])


def lab_constants(r: TargetWorldRobot) -> np.ndarray:
    """What a lab keeps from one episode to the next, as one vector."""
    offsets = r.sim.model.body_ipos[r.sim.model.geom_bodyid[r._boxes], 0]
    told = r.lab.told_lengths if r.lab else None
    return np.concatenate(
        [r.bias, [r.gain, r.contact, r.truth["friction"]], r.truth["lengths"], offsets,
         r.field(np.array([[0.1, -0.2]])), [] if told is None else told]
    )  # fmt: skip


def test_a_lab_keeps_its_table_calibration_robot_and_objects_for_every_episode():
    r = TargetWorldRobot(SETTING, seed=3, masses=(2.0, 6.0), lab=4)
    first = r.start()
    kept = lab_constants(r)
    pose = r.sim.config()
    second = r.start()
    np.testing.assert_array_equal(lab_constants(r), kept)
    np.testing.assert_array_equal(first.lengths, second.lengths)  # told the same lengths
    assert not np.allclose(r.sim.config(), pose)  # placed anew on the table
    # Without a lab the same two episodes differ in all of it.
    r = robot()
    r.start()
    drawn = lab_constants(r)
    r.start()
    assert not np.isin(lab_constants(r), drawn).any()


def test_a_lab_places_the_chain_as_the_same_seed_does_without_it():
    with_lab = TargetWorldRobot(SETTING, seed=3, masses=(2.0, 6.0), lab=4)
    with_lab.start()
    r = robot()
    r.start()
    # The pose is drawn as without a lab; the lengths are the lab's, so the joint is elsewhere.
    np.testing.assert_allclose(with_lab.sim.config()[2:], r.sim.config()[2:], atol=0.02)


def test_each_object_of_a_lab_has_its_own_centre_of_mass_offsets():
    def offsets(masses, lab=4, seed=3):
        r = TargetWorldRobot(SETTING, seed=seed, masses=masses, lab=lab)
        r.start()
        return r.sim.model.body_ipos[r.sim.model.geom_bodyid[r._boxes], 0].copy()

    same = offsets((2.0, 6.0))
    np.testing.assert_array_equal(offsets((2.0, 6.0), seed=9), same)
    assert not np.allclose(offsets((6.0, 2.0)), same)
    assert not np.allclose(offsets((2.0, 6.0), lab=5), same)
    centred = TargetWorldRobot(SETTING, TargetWorld(com_offset=0.0), seed=3, masses=(2.0, 6.0),
                               lab=4)  # fmt: skip
    centred.start()
    shift = same - centred.sim.model.body_ipos[centred.sim.model.geom_bodyid[centred._boxes], 0]
    assert 0 < np.abs(shift).max() <= TargetWorld().com_offset


def test_another_day_in_a_lab_drifts_its_table_robot_and_tracker_but_keeps_its_objects():
    def started(day, world=None):
        r = TargetWorldRobot(SETTING, world, seed=3, masses=(2.0, 6.0), lab=4, day=day)
        r.start()
        return r

    first, later, again = started(0), started(2), started(2)
    np.testing.assert_array_equal(lab_constants(again), lab_constants(later))  # one draw a day
    lab = later.lab
    assert lab.friction_factor != 1 and lab.speed_factor != 1
    assert later.truth["friction"] == pytest.approx(first.truth["friction"] * lab.friction_factor)
    assert later.gain == pytest.approx(first.gain * lab.speed_factor)
    # The table's pattern stays, scaled with its mean.
    xy = np.array([[0.1, -0.2], [-0.3, 0.05]])
    np.testing.assert_allclose(later.field(xy), first.field(xy) * lab.friction_factor)
    assert not np.isin(later.bias, first.bias).any()  # the tracker recalibrated
    # The same objects, lengths, tool and chain placement on every day.
    for name in ("lengths", "told_lengths"):
        np.testing.assert_array_equal(getattr(lab, name), getattr(first.lab, name))
    assert later.contact == first.contact
    offsets = [r.sim.model.body_ipos[r.sim.model.geom_bodyid[r._boxes], 0] for r in (first, later)]
    np.testing.assert_array_equal(*offsets)
    np.testing.assert_allclose(later.sim.config(), first.sim.config(), atol=1e-9)
    assert started(1).lab.friction_factor != lab.friction_factor  # each day its own
    # Without drift a later day differs only in its tracker's calibration.
    still = started(2, TargetWorld(day_friction_drift=0.0, day_speed_drift=0.0))
    assert (still.truth["friction"], still.gain) == (first.truth["friction"], first.gain)


def test_a_day_is_a_day_in_a_lab():
    with pytest.raises(ValueError, match="lab"):
        TargetWorldRobot(SETTING, day=1)
    assert make_robot("target", SETTING, lab=2, day=3).lab.day == 3


def test_a_lab_cannot_be_drawn_from_world_ranges():
    with pytest.raises(ValueError, match="lab"):
        TargetWorldRobot(SETTING, WorldRanges(), lab=0)


def test_make_robot_knows_the_target_backend():
    r = make_robot("target", SETTING, seed=1)
    assert isinstance(r, TargetWorldRobot) and r.n_links == 2
    assert make_robot("target", SETTING, lab=2).lab.seed == 2
    with pytest.raises(ValueError, match="lab"):
        make_robot("stiff", SETTING, lab=2)


@pytest.mark.parametrize(
    "field, value",
    [("timestep", 0.0), ("obs_noise", -1.0), ("friction_range", (0.0, 1.0)),
     ("solver", "Jacobi"), ("cone", "round"), ("day_friction_drift", -0.1)],
)  # fmt: skip
def test_invalid_world_parameters_are_refused(field, value):
    with pytest.raises(ValueError, match=field):
        TargetWorld(**{field: value})


def test_the_world_keeps_the_links_meeting_at_a_right_angle():
    # The hinge gap grows with the width, so self-collision still backs the joint limit.
    physics = TargetWorld().physics(robot().setting.physics())
    assert physics.joint_gap == pytest.approx(physics.link_width)
    assert physics.joint_limit < math.pi / 2


def test_at_severity_0_the_knobs_are_the_training_worlds():
    from masspush.real.backends import SimRobot
    from masspush.settings import get_setting

    train = SimRobot(SETTING, seed=3)
    train.start()
    target = robot(scaled_world(0))
    target.start()
    a, b = train.env.sim.model, target.sim.model
    for name in ("timestep", "cone", "solver", "iterations"):
        assert getattr(a.opt, name) == getattr(b.opt, name), name
    boxes = [a.geom(f"box{i}").id for i in range(2)]
    # Width and height; the lengths are each chain's own.
    np.testing.assert_allclose(a.geom_size[boxes, 1:], b.geom_size[target._boxes, 1:])
    np.testing.assert_allclose(a.geom_solref[boxes], b.geom_solref[target._boxes])
    np.testing.assert_allclose(a.geom_solimp[boxes], b.geom_solimp[target._boxes])
    env = get_setting(SETTING).env_config()
    world = scaled_world(0)
    assert (world.obs_noise, world.action_noise) == (env.obs_noise, env.action_noise)
    assert world.friction_range == env.physics.friction_range
    # Nothing is drawn per episode: no bias, gain, contact offset or friction field.
    assert not target.bias.any() and target.gain == 1.0 and target.contact == 0.0
    assert target.field.amplitude == 0.0


def test_severity_moves_each_difference_from_training_to_the_target_world():
    half, world = scaled_world(0.5), TargetWorld()
    assert scaled_world(1) == world
    assert half.obs_noise == pytest.approx((0.01 + world.obs_noise) / 2)
    assert half.contact_solref == pytest.approx((0.015, 0.9))
    assert half.solver_iterations == 60 and isinstance(half.solver_iterations, int)
    # What cannot be scaled is the target world's as soon as anything differs.
    assert (half.solver, half.cone) == (world.solver, world.cone)
    assert scaled_world(0.5, TargetWorld(com_offset=0.002)).com_offset == pytest.approx(0.001)
    with pytest.raises(ValueError, match="severity"):
        scaled_world(1.5)
