import re
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from masspush.data.recording import Recording, read_recording, write_recording
from masspush.data.rollout import RandomPolicy
from masspush.learn.predictor import load_model
from masspush.models import resolve_model
from masspush.real.backends import SimRobot
from masspush.real.robot import run_estimation
from masspush.real.session import SessionConfig, run_session

SETTING = "2link-1-10"


@pytest.fixture(scope="module")
def recording_of_long_episodes(tmp_path_factory):
    """Two episodes of 4 and 3 pushes, twice and one and a half times the setting's 2."""
    predictor = load_model(resolve_model("rp+", SETTING), SETTING)[0]
    episodes = []
    for pushes in (4, 3):
        for seed in range(20):  # the first chain that no push throws off the table
            robot = SimRobot(SETTING, seed=100 * seed, pushes=pushes)
            run = run_estimation(robot, predictor, RandomPolicy(), pushes, seed=seed)
            if run.failure is None:
                break
        episodes.append(run.recorded(id=f"e{pushes}"))
    path = tmp_path_factory.mktemp("rec") / "long.jsonl"
    return write_recording(path, Recording(2, setting=SETTING, episodes=episodes))


def test_replay_plays_every_recorded_push(recording_of_long_episodes):
    said = []
    config = SessionConfig("replay", SETTING, "rp+", str(recording_of_long_episodes))
    replayed = run_session(config, say=said.append)
    assert [len(e["actions"]) for e in replayed] == [4, 3]
    first = SessionConfig("replay", SETTING, "rp+", str(recording_of_long_episodes), pushes=2)
    assert [len(e["actions"]) for e in run_session(first, say=said.append)] == [2, 2]
    assert any("the first 2 of each" in line for line in said)


def test_a_replay_reads_the_recorded_speeds_unless_told_not_to(recording_of_long_episodes):
    import numpy as np

    from masspush.data.recording import read_recording

    path = str(recording_of_long_episodes)
    recorded = read_recording(path).episodes
    read = run_session(SessionConfig("replay", SETTING, "rp+", path), say=lambda _: None)
    commanded = run_session(
        SessionConfig("replay", SETTING, "rp+", path, read_speeds=False), say=lambda _: None
    )
    for r, c, original in zip(read, commanded, recorded, strict=True):
        np.testing.assert_array_equal(r["actions"], c["actions"])
        # Read as commanded, the estimates are the ones made live; at the speeds, others.
        np.testing.assert_allclose(c["estimates"], original["estimates"], rtol=1e-5)
        assert not np.allclose(r["estimates"], original["estimates"], rtol=1e-5, atol=0)


def test_replay_refuses_more_pushes_than_were_recorded(recording_of_long_episodes):
    config = SessionConfig("replay", SETTING, "rp+", str(recording_of_long_episodes), pushes=4)
    with pytest.raises(ValueError, match=r"episode 'e3' .* recorded 3 push"):
        run_session(config, say=lambda _: None)


def test_pinned_masses_outside_the_setting_need_to_be_allowed():
    config = SessionConfig("stiff", SETTING, "rp+", masses=(20.0, 20.0))
    with pytest.raises(ValueError, match=r"outside setting '2link-1-10'.*--allow-out-of-range"):
        run_session(config, say=lambda _: None)
    allowed = SessionConfig("stiff", SETTING, "rp+", masses=(20.0, 20.0), allow_out_of_range=True)
    (episode,) = run_session(allowed, say=lambda _: None)
    assert list(episode["masses"]) == [20.0, 20.0]


def test_a_replay_of_another_chain_geometry_warns(recording_of_long_episodes, tmp_path):
    from dataclasses import replace

    from masspush.data.recording import read_recording
    from masspush.real.robot import GeometryWarning

    recording = read_recording(recording_of_long_episodes)
    lab = replace(_stiff_geometry(), joint_gap=0.02)
    recording.geometry = lab
    path = write_recording(tmp_path / "lab.jsonl", recording)
    with pytest.warns(GeometryWarning, match="joint_gap"):
        run_session(SessionConfig("replay", SETTING, "rp+", str(path)), say=lambda _: None)


def _stiff_geometry():
    from masspush.config import PhysicsConfig

    return PhysicsConfig().geometry


def test_runs_of_the_policy_push_on_past_the_settings_pushes():
    # The simulated robot's episode is long enough for every run (it ended after 2 before).
    episodes = run_session(
        SessionConfig(robot="stiff", setting=SETTING, model="rp", segments=3), say=lambda _: None
    )
    assert len(episodes[0]["actions"]) == 6 or "failure" in episodes[0]


@pytest.mark.slow
def test_the_particle_filter_runs_a_session_and_records_its_estimates(tmp_path):
    said = []
    config = SessionConfig(robot="stiff", setting=SETTING, model="bayes", segments=2,
                           record=str(tmp_path / "r.jsonl"))  # fmt: skip
    (episode,) = run_session(config, say=said.append)
    assert "particle filter (information-seeking)" in said[0]
    assert not any("averaged over" in line for line in said)  # its estimate keeps every push
    assert len(episode["estimates"]) == len(episode["actions"])
    with pytest.raises(ValueError, match="chooses its own pushes"):
        SessionConfig(robot="replay", setting=SETTING, model="bayes",
                      episodes_file=str(tmp_path / "r.jsonl"))  # fmt: skip


def test_bayes_options_reach_the_filter_and_bad_ones_are_refused_first(monkeypatch):
    from masspush.real import session

    seen = {}

    def load(model, setting, seed=0, density=None, overrides=None):
        seen.update(model=model, overrides=overrides)
        raise RuntimeError("loaded")  # nothing more to run

    monkeypatch.setattr(session.FilterArm, "load", load)
    options = {"reach_weight": 1.0, "reach_from": 2}
    with pytest.raises(RuntimeError, match="loaded"):
        run_session(SessionConfig(robot="stiff", setting=SETTING, model="bayes", bayes=options))
    assert seen == {"model": "bayes", "overrides": options}
    with pytest.raises(ValueError, match="no arm's model is bayes"):
        SessionConfig(robot="stiff", setting=SETTING, model="rp", bayes=options)
    with pytest.raises(ValueError, match="bayes: reach_from must be >= 0"):
        SessionConfig(robot="stiff", setting=SETTING, model="bayes", bayes={"reach_from": -1})
    with pytest.raises(ValueError, match="as density"):
        SessionConfig(robot="stiff", setting=SETTING, model="bayes", bayes={"density": "x.pt"})


def test_sessions_with_other_seeds_never_share_a_chain():
    # Seed S + 1's chains were once seed S's shifted by one: a labelled calibration session
    # and a "held-out" one then pushed the same chains.
    starts = [
        tuple(np.round(episode["observations"][0], 6))
        for seed in (0, 1, 2)
        for episode in run_session(
            SessionConfig(robot="stiff", setting=SETTING, model="rp", count=3, seed=seed),
            say=lambda _: None,
        )
    ]
    assert len(set(starts)) == len(starts) == 9


def test_a_session_on_another_day_in_a_lab_records_which_lab_and_day(tmp_path):
    path = tmp_path / "day.jsonl"
    config = SessionConfig(robot="target", setting=SETTING, model="rp", lab=3, day=2,
                           record=str(path))  # fmt: skip
    run_session(config, say=lambda _: None)
    assert read_recording(path).robot == "masspush simulation (target), lab 3, day 2"
    with pytest.raises(ValueError, match="day is a day in one lab"):
        SessionConfig(robot="target", setting=SETTING, model="rp", day=2)


def test_a_seed_too_large_for_its_chains_is_refused_first():
    # its chains' seeds (a million a session) would overflow the policies' 64-bit seeds
    with pytest.raises(ValueError, match="seed must be an integer <= 4294967295"):
        SessionConfig(robot="stiff", setting=SETTING, model="rp", seed=2**32)


LAB_ROBOT = '''
from masspush.real import SimRobot

made = []


class LabRobot:
    """A lab's robot as masspush sees it: the simulation stands in, without its truth."""

    def __init__(self, setting):
        self._sim = SimRobot(setting, seed=5, pushes=1000)
        self.n_links = self._sim.n_links
        made.append(self)

    def start(self):
        return self._sim.start()

    def push(self, action):
        self.pushed = True
        return self._sim.push(action)

    def close(self):
        self.closed = True


def not_a_robot(setting):
    made.append(object())
    return made[-1]


def measured(setting):
    from masspush.config import ChainGeometry

    robot = LabRobot(setting)
    robot.geometry = ChainGeometry(0.05, 0.03, 0.02, 0.006)  # not the models' chain
    return robot


class Tiring(LabRobot):
    """Stopped (Ctrl-C) as its third episode starts."""

    starts = 0

    def start(self):
        Tiring.starts += 1
        if Tiring.starts == 3:
            raise KeyboardInterrupt
        return super().start()


def unplugged(setting):
    raise ConnectionError("no arm at 10.0.0.2")


def mismeasured(setting):
    robot = LabRobot(setting)
    robot.geometry = (0.05, 0.03, 0.02, 0.006)
    return robot
'''


@pytest.fixture
def lab_module(tmp_path, monkeypatch):
    """`masspush run` started in a folder that holds the lab's module (found there as
    `python -m` would); the module, Python's path and its module cache restored after."""
    (tmp_path / "my_lab_robot.py").write_text(LAB_ROBOT)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "path", [p for p in sys.path if p not in ("", str(tmp_path))])
    monkeypatch.delitem(sys.modules, "my_lab_robot", raising=False)
    yield tmp_path
    sys.modules.pop("my_lab_robot", None)


def test_your_own_robot_runs_a_session_with_the_settings_governor_and_its_stated_masses(
    lab_module, capsys
):
    from masspush.cli import main

    assert main(["run", "--robot", "my_lab_robot:LabRobot", "--setting", "real-ur10",
                 "--model", "rp", "--pushes", "3", "--count", "2", "--masses", "0.064,0.192",
                 "--label", "light-heavy", "--record", "lab.jsonl"]) == 0  # fmt: skip
    out = capsys.readouterr().out
    assert "Your robot has no governor: it gets real-ur10's" in out
    (robot,) = sys.modules["my_lab_robot"].made
    assert robot.closed and robot.governor is not None  # the stationary UR10's
    recording = read_recording(lab_module / "lab.jsonl")
    assert recording.robot == "my_lab_robot:LabRobot"
    assert len(recording.episodes) == 2
    for episode in recording.episodes:
        assert np.allclose(episode["masses"], [0.064, 0.192])
    assert {e["label"] for e in recording.episodes} == {"light-heavy"}


def test_a_session_stopped_part_way_keeps_the_episodes_it_finished_and_goes_on(lab_module):
    said = []
    config = SessionConfig(robot="my_lab_robot:Tiring", setting="real-ur10", model="rp",
                           count=5, label="a", record="lab.jsonl")  # fmt: skip
    with pytest.raises(KeyboardInterrupt):
        run_session(config, say=said.append)
    assert said[-1] == "recorded 2 episode(s) to lab.jsonl (2 in all)"
    assert [e["id"] for e in read_recording(lab_module / "lab.jsonl").episodes] == [
        "a-0001",
        "a-0002",
    ]
    assert [p.name for p in lab_module.iterdir() if "partial" in p.name] == []
    run_session(replace(config, count=3), say=said.append)  # the rest, appended
    ids = [e["id"] for e in read_recording(lab_module / "lab.jsonl").episodes]
    assert ids == [f"a-{i:04d}" for i in range(1, 6)]


def test_an_episode_the_recording_could_not_take_is_not_counted_as_recorded(
    lab_module, monkeypatch
):
    from masspush.real import session

    def full_disk(path, recording):
        raise OSError(f"{path}: cannot write the recording: No space left on device")

    monkeypatch.setattr(session, "write_recording", full_disk)
    said = []
    config = SessionConfig(robot="my_lab_robot:LabRobot", setting="real-ur10", model="rp",
                           count=2, record="lab.jsonl")  # fmt: skip
    with pytest.raises(OSError, match="No space left"):
        run_session(config, say=said.append)
    assert said[-1] == "recorded 0 episode(s) to lab.jsonl (0 in all)"


def test_your_own_robots_chain_geometry_is_checked_against_the_models_and_recorded(lab_module):
    from masspush.real.robot import GeometryWarning

    config = SessionConfig(robot="my_lab_robot:measured", setting="real-ur10", model="rp",
                           record="lab.jsonl")  # fmt: skip
    with pytest.warns(GeometryWarning, match="joint_gap 0.04 m vs 0.02 m"):
        run_session(config, say=lambda _: None)
    (robot,) = sys.modules["my_lab_robot"].made
    assert read_recording(lab_module / "lab.jsonl").geometry == robot.geometry


def test_your_own_robot_gets_the_governor_fitted_to_your_tables_random_pushes(
    lab_module, slippery_recording
):
    from masspush.real.governor import fit_governor
    from masspush.settings import get_setting
    from masspush.sim import reach_governor

    path = slippery_recording(lab_module / "random.jsonl", slide_per_speed=0.2)
    config = SessionConfig(robot="my_lab_robot:LabRobot", setting="real-ur10", model="rp",
                           pushes=2, governor_fit=str(path), record="lab.jsonl")  # fmt: skip
    said = []
    run_session(config, say=said.append)
    (robot,) = sys.modules["my_lab_robot"].made
    shipped = reach_governor("ur10-stationary", get_setting("real-ur10").physics())
    bounds = ("slide_base", "slide_per_speed", "slide_max")
    got, fit = robot.governor.workspace, fit_governor(shipped, path).workspace
    assert [getattr(got, b) for b in bounds] == [getattr(fit, b) for b in bounds]
    assert got.slide_per_speed != shipped.workspace.slide_per_speed
    assert f"Speed governor fitted to the pushes in {path}." in said
    assert "fitted to" in read_recording(lab_module / "lab.jsonl").robot


@pytest.mark.parametrize(
    ("robot", "governor_fit", "error"),
    [
        ("my_lab_robot:", None, "is named package.module:factory"),
        ("my lab:LabRobot", None, "is named package.module:factory"),
        (
            "no_such_lab_module:LabRobot",
            None,
            "importing no_such_lab_module failed: ModuleNotFoundError",
        ),
        ("my_lab_robot:Robot", None, "my_lab_robot has no callable 'Robot'"),
        ("my_lab_robot:not_a_robot", None, "made a object without start, push, close"),
        ("my_lab_robot:mismeasured", None, "its geometry is a tuple, not a"),
        ("my_lab_robot:unplugged", None, "making it failed: ConnectionError: no arm at"),
        ("my_lab_robot:LabRobot", "short.jsonl", "short.jsonl: too few pushes"),
    ],
)
def test_a_bad_robot_of_your_own_is_refused_before_any_push(
    lab_module, slippery_recording, robot, governor_fit, error
):
    if governor_fit:
        slippery_recording(lab_module / governor_fit, 0.2, pushes=10)
    with pytest.raises(ValueError, match=error):
        config = SessionConfig(robot=robot, setting="real-ur10", model="rp",
                               governor_fit=governor_fit, record="lab.jsonl")  # fmt: skip
        run_session(config, say=lambda _: None)
    module = sys.modules.get("my_lab_robot")
    assert not any(getattr(r, "pushed", False) for r in getattr(module, "made", []))
    assert not (lab_module / "lab.jsonl").exists()


def lab_workflow_commands() -> list[str]:
    """The shell commands of docs/real-robot.md's "Your lab, step by step", continuation
    lines joined, in order."""
    text = (Path(__file__).parents[2] / "docs" / "real-robot.md").read_text()
    section = text.split("## Your lab, step by step", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"^ *```bash\n(.*?)^ *```", section, re.S | re.M)
    joined = "\n".join(blocks).replace("\\\n", " ")
    return [" ".join(line.split()) for line in joined.splitlines() if line.strip()]


@pytest.mark.slow
def test_the_documented_lab_workflow_runs_on_your_own_robot(lab_module, capsys):
    """Steps 3-5 of "Your lab, step by step" as written, on the simulation standing in for
    a lab's robot, with fewer episodes, runs and classes: random pushes, the governor fitted
    to them, a labelled calibration run of the filter, the density tuned to it, and a test
    session sorted by it."""
    from masspush.cli import main

    lines = lab_workflow_commands()
    assert lines[0].startswith("R=") and lines[0].endswith(":make_robot")
    random, loop, calibrate, done, tune, classify = lines[1:]
    assert (loop.startswith("for m in ") and loop.endswith("; do")) and done == "done"
    classes = loop.removeprefix("for m in ").removesuffix("; do").split()
    assert len(classes) == 5

    def run(command: str, **fewer: str) -> None:
        for old, new in fewer.items():  # the docs' counts, cut down: each must be there
            assert f" {old} " in f" {command} ", f"{old!r} is no longer in: {command}"
            command = f" {command} ".replace(f" {old} ", f" {new} ").strip()
        command = command.replace("$R", "my_lab_robot:LabRobot")
        assert command.startswith("masspush ")
        assert main(command.split()[1:]) == 0, command

    run(random, **{"--count 150": "--count 20"})
    for m in classes[:2]:
        label = m.replace(",", "-")
        step = calibrate.replace("$m", m).replace("${m/,/-}", label)
        run(step, **{"--count 30": "--count 5", "--segments 16": "--segments 1"})
        test = step.replace("calibration.jsonl", "test.jsonl")
        run(test, **{"--count 30": "--count 2", "--segments 16": "--segments 1"})
    capsys.readouterr()
    run(tune)
    assert "tuned (5-fold cross-validated)" in capsys.readouterr().out
    run(classify)
    assert "accuracy on the 4 labelled episode(s)" in capsys.readouterr().out
    calibration = read_recording(lab_module / "calibration.jsonl")
    assert {e["label"] for e in calibration.episodes} == {"0.064-0.192", "0.064-0.256"}
    assert "speed governor fitted to random.jsonl" in calibration.robot
