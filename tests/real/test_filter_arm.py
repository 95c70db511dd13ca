import numpy as np
import pytest

from masspush.data.recording import Recording, read_recording, write_recording
from masspush.models import load_estimator
from masspush.real.backends import SimRobot
from masspush.real.filter_arm import FilterArm
from masspush.real.robot import run_segments
from masspush.settings import get_setting

SETTING = get_setting("2link-1-10")  # the stiff pusher: cheap episodes


def arm(density_file, model="bayes") -> FilterArm:
    bayes = {"likelihood": "learned", "density": str(density_file), "particles": 200}
    return FilterArm(load_estimator(model, SETTING, bayes=bayes, progress=False), seed=3)


def test_one_filter_keeps_every_run_of_an_episode_and_its_estimates_are_recorded(
    density_file, tmp_path, monkeypatch
):
    filt = arm(density_file)
    resets = []
    reset = filt.filter.reset
    monkeypatch.setattr(filt.filter, "reset", lambda *a, **k: (resets.append(a), reset(*a, **k)))
    robot = SimRobot(SETTING, seed=5, pushes=4)
    episode = run_segments(robot, filt, filt, pushes=2, segments=2, seed=robot.seed)
    assert len(resets) == 1  # a fresh prior once an episode, not once a run
    assert len(episode.estimates) == len(episode.actions) == 4
    for estimate in episode.estimates:
        assert estimate.shape == (2,) and np.isclose(estimate.sum(), 1, atol=1e-4)
    # The filter weighed all four pushes: its estimate after the last is its posterior's.
    assert len(filt.filter.pushes) == 4
    recorded = episode.recorded(id="e-001", label="even", masses=robot.truth["masses"])
    path = write_recording(tmp_path / "r.jsonl", Recording(n_links=2, episodes=[recorded]))
    back = read_recording(path).episodes[0]
    # written with 6 decimals
    np.testing.assert_allclose(back["estimates"], np.array(episode.estimates), atol=1e-6)
    filt.close()


def test_the_same_episode_seed_gives_the_same_pushes_and_estimates(density_file):
    runs = []
    for _ in range(2):
        filt = arm(density_file)
        robot = SimRobot(SETTING, seed=9, pushes=2)
        episode = run_segments(robot, filt, filt, pushes=2, segments=1, seed=robot.seed)
        runs.append((np.array(episode.actions), np.array(episode.estimates)))
        filt.close()
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])


def test_bayes_random_pushes_at_random_and_the_governor_reaches_the_candidates(density_file):
    filt = arm(density_file, "bayes-random")
    assert filt.seeking is None and filt.governor is None
    filt.governor = abs  # no candidates to govern: ignored
    filt.reset(np.array([1], np.uint64))
    obs = np.zeros((1, 3, 4), np.float32)
    action = filt.act(obs, np.zeros((1, 2, 2), np.float32), 0, np.full((1, 2), 0.1, np.float32))
    assert action.shape == (1, 2) and np.all(np.abs(action) <= 1)
    seeking = arm(density_file)
    seeking.governor = abs
    assert seeking.seeking.governor is abs
    with pytest.raises(ValueError, match="one episode at a time"):
        seeking.reset(np.array([1, 2], np.uint64))


def test_a_filter_arm_loads_with_the_density_it_is_given(density_file):
    loaded = FilterArm.load("bayes", SETTING, seed=2, density=str(density_file))
    assert loaded.filter.density is not None and loaded.seeking is not None
    assert loaded.filter.config.likelihood == "learned"
    with pytest.raises(ValueError, match="n_links 2, not 3"):
        FilterArm.load("bayes", get_setting("3link-1-10"), density=str(density_file))
    loaded.close()
    tuned = FilterArm.load("bayes", SETTING, 2, str(density_file), {"likelihood_power": 0.5})
    assert tuned.filter.likelihood_power == 0.5 and tuned.filter.density is not None
    tuned.close()
