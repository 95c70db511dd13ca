import numpy as np
import pytest

from masspush.data.recording import Recording, write_recording
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


def test_a_seed_too_large_for_its_chains_is_refused_first():
    # its chains' seeds (a million a session) would overflow the policies' 64-bit seeds
    with pytest.raises(ValueError, match="seed must be an integer <= 4294967295"):
        SessionConfig(robot="stiff", setting=SETTING, model="rp", seed=2**32)
