import re
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from masspush.data.recording import Recording, write_recording
from masspush.data.rollout import RandomPolicy
from masspush.learn.predictor import load_model
from masspush.models import resolve_model
from masspush.real.backends import (
    RecordedPolicy,
    ReplayMismatchError,
    ReplayRobot,
    SimRobot,
    make_robot,
)
from masspush.real.robot import run_estimation
from masspush.sim.actions import PushGeometry

SETTING = "2link-1-10"


@pytest.fixture(scope="module")
def predictor():
    return load_model(resolve_model("rp+", SETTING), SETTING)[0]


def simulated_session(predictor, episodes: int = 3):
    robot = SimRobot(SETTING, seed=11)
    runs, masses = [], []
    for i in range(episodes):
        runs.append(run_estimation(robot, predictor, RandomPolicy(), 2, seed=i))
        masses.append(robot.truth["masses"])
    return runs, masses


def test_a_replayed_session_gives_the_same_estimates(predictor, tmp_path):
    runs, masses = simulated_session(predictor)
    recording = Recording(
        n_links=2,
        episodes=[
            r.recorded(id=f"e{i}", masses=m)
            for i, (r, m) in enumerate(zip(runs, masses, strict=True))
            if r.failure is None
        ],
    )
    path = write_recording(tmp_path / "session.jsonl", recording)
    robot = ReplayRobot(path)
    for original in (r for r in runs if r.failure is None):
        replay = run_estimation(robot, predictor, RecordedPolicy(robot), 2)
        # The file keeps 6 decimals; the estimates agree to what that allows.
        np.testing.assert_allclose(replay.estimates, original.estimates, atol=1e-4)
    with pytest.raises(StopIteration):
        robot.start()


def test_replay_refuses_a_push_that_was_not_recorded(predictor, tmp_path):
    runs, _ = simulated_session(predictor)
    r = next(r for r in runs if r.failure is None)
    episode = r.recorded(id="only")
    robot = ReplayRobot(write_recording(tmp_path / "s.jsonl", Recording(2, episodes=[episode])))
    robot.start()
    with pytest.raises(ReplayMismatchError, match="push 1: asked for"):
        robot.push(np.array([0.0, 0.0]))


def test_simulated_robot_is_deterministic_and_backends_are_checked(predictor):
    a = run_estimation(SimRobot(SETTING, seed=5), predictor, RandomPolicy(), 2, seed=1)
    b = run_estimation(SimRobot(SETTING, seed=5), predictor, RandomPolicy(), 2, seed=1)
    np.testing.assert_array_equal(np.array(a.estimates), np.array(b.estimates))
    assert len(a.estimates) == 2 and a.failure is None
    with pytest.raises(ValueError, match="unknown robot backend 'ros'"):
        make_robot("ros", SETTING)
    with pytest.raises(ValueError, match="needs --episodes"):
        make_robot("replay", SETTING)


def test_runs_of_the_policy_go_on_from_where_the_last_left_the_chain(predictor):
    from masspush.real.robot import run_segments
    from masspush.real.target_world import TargetWorldRobot

    one = run_segments(TargetWorldRobot(SETTING, seed=5), predictor, RandomPolicy(), 2, 1, seed=1)
    alone = run_estimation(TargetWorldRobot(SETTING, seed=5), predictor, RandomPolicy(), 2, seed=1)
    np.testing.assert_array_equal(np.array(one.estimates), np.array(alone.estimates))
    heard = []
    robot = TargetWorldRobot(SETTING, seed=5)
    runs = run_segments(robot, predictor, RandomPolicy(), 2, 3, lambda k, *_: heard.append(k))
    assert heard == list(range(len(runs.reports)))
    # Each run starts from the rest pose the one before ended in.
    recorded = runs.recorded(id="x")
    assert len(recorded["observations"]) == len(runs.estimates) + 1
    assert len(runs.run_estimates) == -(-len(runs.estimates) // 2)
    with pytest.raises(ValueError, match="segments"):
        run_segments(robot, predictor, RandomPolicy(), 2, 0)


def test_a_chain_of_another_geometry_than_the_models_warns():
    from masspush.config import ChainGeometry, PhysicsConfig
    from masspush.models import model_and_policy
    from masspush.real.robot import GeometryWarning, check_geometry, model_geometry

    _, meta, _ = model_and_policy("tp+", "real-ur10")
    trained = model_geometry(meta)
    physics = PhysicsConfig()
    assert trained == ChainGeometry(
        physics.link_width,
        physics.link_height,
        physics.joint_gap,
        0.006,  # the UR10's dowel
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_geometry(meta, trained)  # the same chain: silent
        check_geometry(meta, replace(trained, joint_gap=trained.joint_gap + 5e-4))  # within 1 mm
    with pytest.warns(GeometryWarning, match=r"joint_gap 0.04 m vs 0.02 m"):
        check_geometry(meta, replace(trained, joint_gap=0.02))


def test_push_geometry_reads_the_labs_own_chain():
    from masspush.config import ChainGeometry, PhysicsConfig
    from masspush.sim.actions import action_to_push, push_geometry

    lab = ChainGeometry(link_width=0.05, link_height=0.03, joint_gap=0.02, tool_radius=0.006)
    physics = PhysicsConfig(n_links=2).with_geometry(lab)
    assert physics.geometry == replace(lab, tool_radius=physics.pusher_radius)
    config, lengths = np.array([0.0, 0.0, 0.0, 0.0]), (0.12, 0.12)
    push = action_to_push(np.array([0.5, 0.5]), lengths, physics)  # link 2, from -y
    g = push_geometry(push, config, lengths, physics)
    # Link 2's centre lies one link length plus the lab's gap from link 1's; the face at
    # half the lab's width.
    assert g.contact[0] == pytest.approx(0.12 + 0.02 + push.offset)
    assert g.contact[1] == pytest.approx(-0.025)
    default = push_geometry(push, config, lengths, PhysicsConfig(n_links=2))
    assert default.contact[0] == pytest.approx(0.12 + 0.04 + push.offset)


@pytest.mark.parametrize(
    "bad", [{"link_width": 0.0}, {"joint_gap": -0.01}, {"tool_radius": 6.0}, {"link_height": None}]
)
def test_a_measured_geometry_is_checked(bad):
    from masspush.config import ChainGeometry

    values = {"link_width": 0.04, "link_height": 0.03, "joint_gap": 0.04, "tool_radius": 0.006}
    with pytest.raises(ValueError):
        ChainGeometry(**{**values, **bad})


class _CountingPolicy(RandomPolicy):
    """A random policy that counts how often its memory is wiped."""

    def __init__(self, runs: int):
        super().__init__()
        self.runs, self.resets = runs, 0

    def reset(self, seeds: np.ndarray) -> None:
        self.resets += 1
        super().reset(seeds)


@pytest.mark.parametrize("runs", [1, 2, 4, 8])
def test_runs_of_a_policy_trained_on_runs_keep_its_memory_as_in_training(predictor, runs):
    from masspush.real.robot import run_segments
    from masspush.real.target_world import TargetWorldRobot

    robot = TargetWorldRobot(SETTING, seed=5)
    policy = _CountingPolicy(runs)
    episode = run_segments(robot, predictor, policy, 2, 4, seed=1)
    started = (len(episode.reports) + 1) // 2
    # Wiped at the start of each block of `runs` runs, as its training episodes began.
    assert policy.resets == len(range(0, started, runs))
    if episode.failure is None:
        assert policy.resets == {1: 4, 2: 2, 4: 1, 8: 1}[runs]


class _SpeedyRobot(SimRobot):
    """A simulated robot that remembers the actions it was told to make."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.told: list[np.ndarray] = []

    def push(self, action):
        self.told.append(np.asarray(action).copy())
        return super().push(action)


class _FullSpeedAway(RandomPolicy):
    """Pushes the first link at full speed away from the stationary robot (its base faces +y;
    a push's direction is the side times the link's +y axis, `push_geometry`)."""

    def act(self, observations, actions, step, lengths):
        side = np.where(np.cos(observations[:, step, 2]) >= 0, 1.0, -1.0)
        return np.stack([side, np.full_like(side, -0.5)], 1).astype(np.float32)


def test_a_stationary_robots_governor_slows_the_push_it_is_told_and_records_it(predictor):
    robot = _SpeedyRobot("real-ur10", seed=44, pushes=6)
    assert robot.governor is not None and SimRobot(SETTING).governor is None
    episode = run_estimation(robot, predictor_for("real-ur10"), _FullSpeedAway(), 6, seed=1)
    assert min(abs(a[0]) for a in robot.told) < 0.5  # the chain neared the edge: slowed
    for k, told in enumerate(robot.told):
        seen = episode.start.config if k == 0 else episode.reports[k - 1].config
        asked = _FullSpeedAway().act(seen[None, None], None, 0, None)[0]
        np.testing.assert_array_equal(told, robot.governor(asked, seen, episode.start.lengths))
        np.testing.assert_array_equal(episode.actions[k], told)  # what the history holds


class _Listening:
    """A predictor that keeps every history it is asked about."""

    def __init__(self, n_links: int = 2):
        self.histories: list = []
        self.n_links = n_links

    def predict(self, history):
        self.histories.append(history)
        return np.full((1, history.actions.shape[1], self.n_links), 1 / self.n_links)


def test_the_predictor_reads_each_push_at_the_speed_the_robot_reports():
    robot = SimRobot("real-ur10", seed=7, pushes=3)
    listening = _Listening()

    def reader(config, lengths, action, speed):  # stands for `speed_reader`: shows its input
        return np.array([speed, action[1]], np.float32)

    episode = run_estimation(robot, listening, RandomPolicy(), 3, seed=2, read_speed=reader)
    speeds = [r.speed for r in episode.reports if r.config is not None]
    assert speeds and all(s > 0 for s in speeds)
    last = listening.histories[-1]
    np.testing.assert_allclose(last.actions[0, :, 0], speeds, rtol=1e-6)
    np.testing.assert_allclose(last.actions[0, :, 1], np.asarray(episode.actions)[: len(speeds), 1])
    # The recording keeps what was commanded, and the speeds beside it.
    recorded = episode.recorded(id="x")
    np.testing.assert_array_equal(recorded["actions"], episode.actions[: len(speeds)])
    assert recorded["speeds"] == speeds


def test_the_shipped_models_read_a_slower_push_as_a_slower_action():
    from masspush.real.robot import speed_reader
    from masspush.settings import get_setting

    setting = get_setting("real-ur10")
    read = speed_reader(setting.pusher, setting.physics())
    assert speed_reader("ur10", setting.physics()) is None  # the following arm: not read
    config, lengths = np.array([0.0, 0.0, 0.2, 0.3]), [0.12, 0.12]
    action = np.array([0.1, 0.2], np.float32)  # 0.5 m/s: below what the arm reaches there
    np.testing.assert_allclose(read(config, lengths, action, 0.4), [0.08, 0.2], rtol=1e-5)
    np.testing.assert_array_equal(read(config, lengths, action, None), action)


@pytest.mark.slow
def test_the_governor_keeps_chains_in_reach_that_full_speed_pushes_lose():
    """Full-speed pushes away from the robot, 6 in a row, on 12 chains: without the governor
    a third of the chains or more leave the workspace (5 of 12); with it none may."""
    lost = {}
    for governed in (True, False):
        robot = SimRobot("real-ur10", seed=40, pushes=6)
        if not governed:
            robot.governor = None
        episodes = [
            run_estimation(robot, predictor_for("real-ur10"), _FullSpeedAway(), 6, seed=i)
            for i in range(12)
        ]
        lost[governed] = sum(e.failure == "left_workspace" for e in episodes)
    assert lost[True] == 0 and lost[False] >= 4, lost


def predictor_for(setting: str):
    return load_model(resolve_model("rp", setting), setting)[0]


def documented_python(marker: str) -> str:
    """The one unindented Python block of docs/real-robot.md that contains `marker`."""
    text = (Path(__file__).parents[2] / "docs" / "real-robot.md").read_text()
    [block] = [b for b in re.findall(r"^```python\n(.*?)^```", text, re.S | re.M) if marker in b]
    return block


class LabDriver:
    """What the documented sketch calls `arm` and `tracker`: here a simulated chain, pushed
    by the contact point, direction and speed the sketch computes."""

    def __init__(self, sim):
        self.sim, self.failure, self.still = sim, None, True  # ChainSim starts at rest

    def push(self, contact, direction, speed):
        geometry = PushGeometry(np.asarray(contact), np.asarray(direction), float(speed))
        self.failure = self.sim.pusher.deliver(
            self.sim.model, self.sim.data, geometry, self.sim.physics
        )
        self.still = False
        return self.failure != "unreachable", self.sim.pusher.executed_speed

    def wait_until_still(self):
        if not self.still and self.failure is None:
            self.failure, _ = self.sim.settle()
        self.still = True

    def chain_config(self):
        return self.sim.config()

    def chain_tipped(self):
        return self.failure is not None

    def reaches_all_of(self, config):
        return self.sim.reach_failure() is None

    def stop(self):
        pass


def test_the_documented_robot_sketch_pushes_the_labs_chain_where_the_simulation_would():
    """docs/real-robot.md's `MyUR10`, run as written on a chain of another geometry than the
    models': the rest poses after each push are those the simulation reaches from the same
    actions, so the sketch places its pushes on the lab's chain as `ChainSim` does."""
    from masspush.config import ChainGeometry
    from masspush.settings import get_setting
    from masspush.sim.chain import sample_chain
    from masspush.sim.simulate import ChainSim

    namespace: dict = {}
    exec(documented_python("class MyUR10"), namespace)
    lab = ChainGeometry(link_width=0.05, link_height=0.03, joint_gap=0.02, tool_radius=0.006)
    physics = get_setting("real-ur10").physics().with_geometry(lab)
    chain = sample_chain(physics, np.random.default_rng(3))
    driver, reference = LabDriver(ChainSim(chain, physics)), ChainSim(chain, physics)
    robot = namespace["MyUR10"](driver, driver, chain.lengths, lab)
    assert np.array_equal(robot.start().config, reference.config())
    moved = 0.0
    for action in [(0.3, 0.8), (-0.25, 0.2), (0.4, 0.6)]:
        report = robot.push(np.array(action))
        outcome = reference.push(np.array(action))
        assert report.failure == outcome.failure is None
        assert np.array_equal(report.config, reference.config())
        assert report.speed == pytest.approx(outcome.executed_speed)
        moved = max(moved, float(np.abs(report.config[:2] - chain.root_pose[:2]).max()))
    assert moved > 0.01  # the pushes moved the chain: the comparison is not of rest with rest
