import numpy as np
import pytest

from masspush.config import EnvConfig
from masspush.env import ChainEnv
from masspush.learn.predictor import ModelMismatchError
from masspush.models import resolve_model
from masspush.reports.demonstration import DEMO_SETTING, draw_demo, run_demo


def test_the_shipped_tp_plus_policy_pushes_and_the_estimate_follows_each_push(tmp_path):
    lines: list[str] = []
    episode = run_demo(DEMO_SETTING, "tp+", seed=2, report=lines.append)
    assert episode.policy.startswith("learned")
    k = episode.setting.n_links  # one push per link in the paper's settings
    assert len(episode.actions) == len(episode.estimates) == k and episode.failure is None
    for estimate in episode.estimates:
        assert estimate.shape == episode.truth.shape and estimate.sum() == pytest.approx(1, 1e-5)
    assert sum(line.startswith("  estimate") for line in lines) == k
    picture = draw_demo(episode, tmp_path / "demo.png")
    assert picture.stat().st_size > 10_000


def test_replaying_the_seed_and_the_actions_is_the_same_episode():
    """The demo's video replays the episode from its seed and actions: that must be it."""
    episode = run_demo(DEMO_SETTING, "rp+", seed=7, report=lambda _: None)
    env = ChainEnv.from_config(EnvConfig(physics=episode.setting.physics(), pusher="stiff"))
    _, info = env.reset(seed=7)
    configs = [info["config"]]
    for action in episode.actions:
        configs.append(env.step(action)[4]["config"])
    np.testing.assert_allclose(np.array(configs), np.array(episode.configs))


def test_a_model_for_another_setting_is_refused():
    other = resolve_model("rp+", "3link-1-10")
    with pytest.raises(ModelMismatchError, match="trained for setting '3link-1-10'"):
        run_demo(DEMO_SETTING, other, report=lambda _: None)
