import math
from dataclasses import replace

import mujoco
import numpy as np
import pytest

from masspush.config import PhysicsConfig
from masspush.sim.chain import link_poses, sample_chain
from masspush.sim.pushers import compiled, make_pusher
from masspush.sim.pushers.arm import ARM_PARK, ARMS, ASSETS, ArmPusher, _cross, tool_rotation
from masspush.sim.pushers.osc import desired_acceleration, osc_torque, rotation_error
from masspush.sim.simulate import ChainSim

STRAIGHT = {"joint_angles": [0.0], "lengths": [0.12, 0.12], "root_pose": [0.0, 0.0, 0.0]}
ARM_NAMES = sorted(ARMS)


def sim_with(pusher, masses=(0.3, 0.3), **pins):
    physics = PhysicsConfig(n_links=2)
    options = {**STRAIGHT, "masses": list(masses), "friction": 0.7, **pins}
    chain = sample_chain(physics, np.random.default_rng(0), options, allow_out_of_range=True)
    return ChainSim(chain, physics, make_pusher(pusher) if isinstance(pusher, str) else pusher)


@pytest.mark.parametrize("arm", ARM_NAMES)
def test_controller_reaches_a_target_pose(arm):
    pusher = ArmPusher(arm)
    sim = sim_with(pusher)
    direction = np.array([1.0, 0.0, 0.0])
    target_r = tool_rotation(direction, pusher.arm.tool_pitch)
    base = np.array([2.0, 2.0])  # away from the chain
    pusher.place_base(sim.model, sim.data, base, 0.0)
    start = np.array([base[0] + pusher.arm.base_distance - 0.05, base[1], 0.05])
    touch = start + 0.03 * direction  # the IK starts from the pose 3 cm before the face
    q, error = pusher._ik(sim.model, sim.data, pusher._h(sim.model), start, target_r, touch,
                          direction)  # fmt: skip
    assert error < 1e-3
    sim.data.qpos[pusher._h(sim.model).qadr] = q
    # Move 4 cm sideways and 3 cm up, with a 10 degree turn, from rest.
    target = start + np.array([0.0, 0.04, 0.03])
    turned = tool_rotation(np.array([math.cos(0.17), math.sin(0.17), 0.0]), pusher.arm.tool_pitch)
    pos_err, rot_err = pusher.move_to(sim.model, sim.data, target, turned, duration=0.5)
    assert pos_err < 0.003  # a few millimetres
    assert math.degrees(rot_err) < 2.0  # a few degrees
    assert pusher.trace.max_torque_ratio <= 1.0 + 1e-9


def test_a_longer_run_up_lets_the_same_arm_push_faster():
    # Torque-limited, the KR 5 reaches the speed its run-up allows (v^2 = 2 a d): placed
    # farther back with a longer run-up, the same fast push hits harder and slides further.
    ends, speeds = {}, {}
    for arm in ("kuka", "kuka-far"):
        sim = sim_with(arm)
        start = sim.config()
        outcome = sim.push(np.array([1.0, 0.5]))
        assert outcome.failure is None
        speeds[arm] = sim.pusher.executed_speed
        ends[arm] = np.linalg.norm(sim.config()[:2] - start[:2])
    assert ARMS["kuka-far"].xml == ARMS["kuka"].xml  # the same robot, placed otherwise
    assert speeds["kuka"] < 2.8 and speeds["kuka-far"] > 1.15 * speeds["kuka"]
    assert ends["kuka-far"] > ends["kuka"]


@pytest.mark.parametrize("arm", ARM_NAMES)
@pytest.mark.parametrize("a1", [0.1, 0.2])
def test_tip_reaches_the_commanded_speed_on_a_light_chain(arm, a1):
    sim = sim_with(arm, masses=(0.1, 0.1))
    outcome = sim.push(np.array([a1, -0.5]))
    trace = sim.pusher.trace
    assert outcome.failure is None and trace.contact_step is not None
    commanded = outcome.push.speed
    at_contact = trace.tip_speed[trace.contact_step]
    assert at_contact == pytest.approx(commanded, rel=0.10)  # stated tolerance: 10 %
    assert max(trace.tip_speed) <= 1.10 * commanded


def _motion(pusher, action):
    sim = sim_with(pusher, masses=(0.3, 0.3), joint_angles=[0.4])
    physics = sim.physics
    before = link_poses(sim.config(), sim.chain.lengths, physics.joint_gap)
    outcome = sim.push(np.array(action))
    assert outcome.failure is None, outcome.failure
    after = link_poses(sim.config(), sim.chain.lengths, physics.joint_gap)
    link = outcome.push.link
    h = before[1][link]
    normal = np.array([-math.sin(h), math.cos(h)]) * outcome.push.side
    shift = (after[0][link] - before[0][link]) @ normal
    turn = (after[1][link] - before[1][link] + math.pi) % (2 * math.pi) - math.pi
    return shift, turn


@pytest.mark.parametrize("arm", ARM_NAMES)
@pytest.mark.parametrize("action", [[0.2, -0.8], [-0.2, -0.2], [0.25, 0.3], [-0.3, 0.85]])
def test_arm_and_stiff_pushes_move_the_chain_the_same_way(arm, action):
    stiff_shift, stiff_turn = _motion("stiff", action)
    arm_shift, arm_turn = _motion(arm, action)
    assert stiff_shift > 0 and arm_shift > 0  # both pushed the link away from the pusher
    if abs(stiff_turn) > 0.05 and abs(arm_turn) > 0.05:
        assert np.sign(stiff_turn) == np.sign(arm_turn)


@pytest.mark.parametrize("arm", ARM_NAMES)
def test_with_an_arm_the_mass_scale_matters(arm):
    """A torque-limited arm is slowed by a heavy chain: x10 masses move it less."""
    light, heavy = sim_with(arm, masses=(0.2, 0.4)), sim_with(arm, masses=(2.0, 4.0))
    x0 = light.config()
    for sim in (light, heavy):
        assert sim.push(np.array([0.3, -0.5])).failure is None
    light_travel = np.linalg.norm(light.config()[:2] - x0[:2])
    heavy_travel = np.linalg.norm(heavy.config()[:2] - x0[:2])
    assert heavy_travel < 0.8 * light_travel, (light_travel, heavy_travel)


@pytest.mark.parametrize("arm", ARM_NAMES)
def test_torque_limits_hold_in_hard_pushes(arm):
    sim = sim_with(arm, masses=(5.0, 5.0))
    h = sim.pusher._h(sim.model)
    peak = np.zeros(6)

    def watch():
        peak[:] = np.maximum(peak, np.abs(sim.data.qfrc_actuator[h.dadr]))

    sim.on_step = watch
    sim.push(np.array([1.0, -0.5]))
    assert sim.pusher.trace.max_torque_ratio == pytest.approx(1.0, abs=1e-6)  # limits reached
    assert np.all(peak <= h.torque_limit * (1 + 1e-9))


def test_an_arm_link_touching_the_chain_is_detected():
    pusher = ArmPusher("kuka")
    sim = sim_with(pusher)
    h = pusher._h(sim.model)
    # Stand the base right on the chain: the base and lower links overlap link 0.
    pusher.place_base(sim.model, sim.data, sim.config()[:2], 0.0)
    mujoco.mj_forward(sim.model, sim.data)
    assert pusher._contacts(sim.data, h) == (False, True)


@pytest.mark.parametrize("arm", ARM_NAMES)
def test_very_slow_pushes_still_arrive(arm):
    sim = sim_with(arm)
    outcome = sim.push(np.array([0.002, -0.5]))  # 1 cm/s
    assert outcome.failure is None and sim.pusher.trace.contact_step is not None


def test_zero_speed_push_touches_nothing():
    sim = sim_with("kuka")
    before = sim.config()
    assert sim.push(np.array([0.0, 0.0])).failure is None
    np.testing.assert_allclose(sim.config(), before, atol=1e-4)


def test_unknown_arm_is_refused():
    with pytest.raises(ValueError, match="unknown arm"):
        ArmPusher("puma")
    with pytest.raises(ValueError, match="unknown pusher"):
        make_pusher("puma")


@pytest.mark.parametrize("arm", ARM_NAMES)
def test_control_law_matches_the_reference_law(arm):
    """The per-step law (M^-1 J^T from MuJoCo's factorisation, one solve) is osc.py's law
    with the full mass matrix, in states along a real push."""
    pusher = ArmPusher(arm)
    sim = sim_with(pusher)
    model, data, h = sim.model, sim.data, pusher._h(sim.model)
    rng = np.random.default_rng(3)
    direction = np.array([0.6, 0.8, 0.0])
    target_r = tool_rotation(direction, pusher.arm.tool_pitch)
    for _ in range(5):
        data.qpos[h.qadr] = rng.uniform(h.low / 3, h.high / 3)
        data.qvel[h.dadr] = rng.normal(0.0, 0.5, 6)
        mujoco.mj_step1(model, data)
        x_des, v_des = rng.normal(0.0, 0.5, 3), rng.normal(0.0, 0.3, 6)
        tau, tip_velocity = pusher._torque(model, data, h, x_des, target_r, v_des, direction)
        jac = ArmPusher._jacobian(model, data, h)
        full_m = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, full_m)
        pos_err = x_des - data.site_xpos[h.site]
        pos_err -= (pos_err @ direction) * direction
        rot_err = rotation_error(target_r, data.site_xmat[h.site].reshape(3, 3))
        xdd = desired_acceleration(pos_err, rot_err, jac @ data.qvel[h.dadr], v_des)
        expected = osc_torque(jac, full_m[np.ix_(h.dadr, h.dadr)], xdd)
        np.testing.assert_allclose(tip_velocity, jac @ data.qvel[h.dadr], rtol=1e-12)
        np.testing.assert_allclose(tau, expected, rtol=1e-7, atol=1e-7 * np.abs(expected).max())


@pytest.mark.parametrize("arm", ["kuka", "ur10"])
def test_scenes_from_the_parsed_arm_are_those_from_its_file(arm):
    """The arm's file is parsed once per pusher: each later scene compiles to the same
    bytes as one from a fresh parse."""
    import mujoco

    from masspush.sim.chain import compile_scene

    physics = PhysicsConfig()
    chain = sample_chain(physics, np.random.default_rng(0))
    pusher = make_pusher(arm)

    def saved(model):
        out = np.zeros(mujoco.mj_sizeModel(model), np.uint8)
        mujoco.mj_saveModel(model, None, out)
        return out

    def from_file(spec, physics):  # what add_to did before it kept the parsed file
        parsed = mujoco.MjSpec.from_file(str(ASSETS / ARMS[arm].xml))
        frame = spec.worldbody.add_frame(pos=ARM_PARK.tolist())
        frame.attach_body(parsed.body("base"), f"{arm}/", "")
        spec.nuserdata = compiled.Userdata.SIZE  # room for the batch path's lockstep

    first, again = (saved(compile_scene(chain, physics, pusher.add_to)) for _ in range(2))
    fresh = saved(compile_scene(chain, physics, from_file))
    assert np.array_equal(first, again) and np.array_equal(again, fresh)


# --- the stationary UR10 -----------------------------------------------------------------


def stationary_sim(root, masses=(0.05, 0.05), pusher=None):
    physics = PhysicsConfig(n_links=2, mass_range=(0.01, 0.3))
    options = {**STRAIGHT, "masses": list(masses), "friction": 0.5, "root_pose": list(root)}
    chain = sample_chain(physics, np.random.default_rng(0), options)
    return ChainSim(chain, physics, pusher or make_pusher("ur10-stationary"))


def test_the_stationary_base_stands_where_its_workspace_says_during_a_push():
    sim = stationary_sim((0.1, 0.0, 0.4))
    base = sim.pusher.workspace.base
    seen = []
    sim.on_step = lambda: seen.append(sim.data.mocap_pos[sim.pusher._h(sim.model).mocap].copy())
    outcome = sim.push(np.array([0.3, -0.4]))
    assert outcome.failure is None
    pushing = np.array(seen[: outcome.steps - round(outcome.settle_time / sim.physics.timestep)])
    assert len(pushing) > 10
    np.testing.assert_allclose(pushing[:, :2], np.tile(base[:2], (len(pushing), 1)))


def test_a_chain_thrown_out_of_reach_ends_the_episode():
    sim = stationary_sim((0.0, 0.2, 0.0), masses=(0.02, 0.02))
    assert sim.initial_failure is None
    # Full speed on a light chain near the edge, away from the robot.
    assert sim.push(np.array([1.0, -0.5])).failure == "left_workspace"
    assert not sim.pusher.workspace.holds(sim.config(), sim.chain.lengths, sim.physics.joint_gap)


def test_a_chain_out_of_reach_from_the_start_is_a_failed_episode():
    assert stationary_sim((0.0, 0.4, 0.0)).initial_failure == "left_workspace"
    assert stationary_sim((0.0, 0.0, 0.0)).initial_failure is None


def test_a_push_beyond_the_arm_is_unreachable():
    pusher = make_pusher("ur10-stationary")
    pusher.workspace = replace(pusher.workspace, r_max=2.5)  # let the chain lie out of reach
    sim = stationary_sim((0.0, 1.0, 0.0), pusher=pusher)
    assert sim.initial_failure is None
    assert sim.push(np.array([0.5, 0.0])).failure == "unreachable"


def test_a_stationary_push_does_not_depend_on_the_pushes_before():
    # The inverse kinematics starts from its cell's solution, whatever was solved before.
    fresh = stationary_sim((0.05, 0.05, 1.0))
    fresh.push(np.array([-0.3, 0.6]))
    used = make_pusher("ur10-stationary")
    for root, action in (((0.0, -0.1, 2.0), [0.4, 0.2]), ((-0.1, 0.1, -1.0), [-0.6, -0.8])):
        stationary_sim(root, pusher=used).push(np.array(action))
    again = stationary_sim((0.05, 0.05, 1.0), pusher=used)
    again.push(np.array([-0.3, 0.6]))
    np.testing.assert_array_equal(again.config(), fresh.config())


def test_joint_speed_limits_scale_a_push_down_as_a_controller_would():
    sim = stationary_sim((0.0, 0.0, 0.3))
    pusher = sim.pusher
    joints = []
    sim.on_step = lambda: joints.append(sim.data.qvel[pusher._h(sim.model).dadr].copy())
    outcome = sim.push(np.array([1.0, 0.3]))
    assert outcome.failure is None
    assert 0.3 < pusher.trace.commanded_speed < outcome.push.speed == 5.0
    # The tip follows the scaled speed, and no joint turns much faster than its limit.
    contact = pusher.trace.tip_speed[pusher.trace.contact_step]
    assert contact == pytest.approx(pusher.trace.commanded_speed, rel=0.1)
    limit = np.array(pusher.arm.joint_speed_limit)
    assert np.max(np.abs(np.array(joints)) / limit) < 1.05


@pytest.mark.parametrize("arm", ["kuka", "ur10"])
def test_arms_that_follow_the_chain_have_no_joint_speed_limit(arm):
    sim = sim_with(arm)
    outcome = sim.push(np.array([0.4, -0.5]))
    assert sim.pusher.trace.commanded_speed == outcome.push.speed


def test_the_shipped_ik_cells_are_the_arms_own_solutions():
    from masspush.sim.pushers.arm import ik_cell_file

    sim = stationary_sim((0.0, 0.0, 0.0))
    pusher, height = sim.pusher, sim.physics.link_height / 2
    pusher.place_base(sim.model, sim.data, pusher.workspace.base[:2], pusher.workspace.base[2])
    with np.load(ik_cell_file("ur10-stationary")) as table:
        assert float(table["height"]) == height
        cells, solutions = table["cells"], table["q"]
    # Every cell a push inside the workspace falls in (the workspace's distances +- margin,
    # every direction), each the careful solution in a scene with a chain in it.
    assert {int(i) for i in cells[:, 0]} >= set(range(6, 23))
    assert len({int(j) for j in cells[:, 1]}) == 25
    for k in (0, len(cells) // 2, len(cells) - 1):
        cell = (int(cells[k, 0]), int(cells[k, 1]))
        fresh = pusher._cell_solution(sim.model, sim.data, pusher._h(sim.model), cell, height)
        # Within 1e-12 rad, not to the bit: the cells were solved on another CPU, whose
        # vector units round the IK's sums in another order.
        np.testing.assert_allclose(fresh, solutions[k], rtol=0, atol=1e-12)
    before = len(pusher._cells(height))
    sim.push(np.array([0.4, 0.3]))
    assert len(pusher._cells(height)) == before  # a push inside used a shipped cell


def test_a_push_near_a_singular_pose_is_unreachable_not_endless(monkeypatch):
    # Joint speed limits that leave a push a thousandth of its speed: the arm cannot make it
    # (before this rule, its run-up would have taken hours of simulated time).
    pusher = make_pusher("ur10-stationary")
    monkeypatch.setattr(pusher, "_speed_within_joint_limits", lambda *a: a[-1] * 1e-3)
    sim = stationary_sim((0.0, 0.0, 0.3), pusher=pusher)
    outcome = sim.push(np.array([0.8, 0.3]))
    assert outcome.failure == "unreachable" and outcome.steps == 0


def test_a_push_from_an_exactly_singular_pose_is_unreachable_not_a_crash(monkeypatch):
    # A Jacobian with no inverse (met once in a training run: LinAlgError killed a worker).
    # A speed of 0 then makes the push unreachable (the test above).
    sim = stationary_sim((0.0, 0.0, 0.3))
    pusher, model, data = sim.pusher, sim.model, sim.data
    h = pusher._h(model)
    q = data.qpos[h.qadr].copy()
    direction = np.array([0.0, 1.0, 0.0])
    assert pusher._speed_within_joint_limits(model, data, h, q, direction, 2.0) > 0
    monkeypatch.setattr(pusher, "_jacobian", lambda *a: np.zeros((6, 6)))
    assert pusher._speed_within_joint_limits(model, data, h, q, direction, 2.0) == 0.0
    np.testing.assert_array_equal(data.qpos[h.qadr], q)  # the arm's pose as it was


def test_a_slowed_push_runs_up_for_the_speed_it_will_have():
    sim = stationary_sim((0.0, 0.0, 0.3))
    sim.push(np.array([1.0, 0.3]))
    trace = sim.pusher.trace
    assert trace.commanded_speed < 5.0
    # STANDOFF_TIME (30 ms) of travel at the slowed speed, plus the ~30 ms the arm takes to
    # reach it from rest; a run-up for the commanded 5 m/s (15 cm) would take over 90 steps.
    assert 30 <= trace.contact_step <= 60


@pytest.mark.slow
def test_an_arm_episode_does_not_depend_on_the_episodes_before_it():
    # The following arm's inverse kinematics starts from one solution of the geometry alone:
    # episodes split over workers in any way give the same rest poses, to the bit.
    from masspush.data.rollout import TRAIN, RandomPolicy, run_env
    from masspush.settings import get_setting

    config = get_setting("3link-0.1-1").env_config("kuka")
    after = run_env(config, RandomPolicy(), np.array([150, 151, 152, 176]), TRAIN, 0)
    alone = run_env(config, RandomPolicy(), np.array([176]), TRAIN, 0)
    np.testing.assert_array_equal(after.configs[-1], alone.configs[0])


def test_tool_rotation_is_a_rotation_with_numpys_own_bits():
    # The planner's cross product is NumPy's, bit for bit (rest poses must not move).
    rng = np.random.default_rng(4)
    for a, b in rng.normal(size=(200, 2, 3)):
        np.testing.assert_array_equal(_cross(a, b), np.cross(a, b))
    r = tool_rotation(np.array([0.6, 0.8, 0.0]), 0.3)
    np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)


@pytest.mark.parametrize("pusher", ["stiff", *ARM_NAMES])
def test_the_tool_has_the_configs_friction(pusher):
    for friction in (PhysicsConfig.tool_friction, 0.3):
        physics = PhysicsConfig(n_links=2, tool_friction=friction)
        chain = sample_chain(physics, np.random.default_rng(0), STRAIGHT, allow_out_of_range=True)
        tool = make_pusher(pusher)
        model = ChainSim(chain, physics, tool).model
        assert model.geom_friction[model.geom(tool.tool).id, 0] == friction


def test_on_a_sticky_table_the_tools_friction_holds_the_chain_back():
    # In contact the link's face slides along the tool, whose friction then presses the link
    # onto the table: on a sticky table the stationary UR10's push all but jams the chain
    # (docs/notebook/2026-12-07-sticky-tables.md). On a slippery table it hardly matters.
    def moved(tool_friction, table_friction):
        physics = PhysicsConfig(n_links=2, tool_friction=tool_friction,
                                link_friction=min(0.5, tool_friction))  # fmt: skip
        options = {**STRAIGHT, "masses": [0.064, 0.192], "friction": table_friction}
        chain = sample_chain(physics, np.random.default_rng(0), options, allow_out_of_range=True)
        sim = ChainSim(chain, physics, make_pusher("ur10-stationary"))
        start = sim.config()[:2].copy()
        assert sim.push(np.array([0.2, 0.0])).failure is None
        return float(np.linalg.norm(sim.config()[:2] - start))

    assert moved(0.1, 1.0) > 1.5 * moved(1.0, 1.0)
    assert moved(0.1, 0.5) == pytest.approx(moved(1.0, 0.5), rel=0.15)
