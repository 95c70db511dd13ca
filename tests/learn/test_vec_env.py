import numpy as np
import pytest

from masspush.config import EnvConfig
from masspush.learn.features import history_dim, paper_reward
from masspush.learn.vec_env import BatchPushVecEnv
from masspush.settings import get_setting
from masspush.sim.pushers import on_batch_path

CONFIG = EnvConfig(physics=get_setting("2link-0.1-1").physics(), pusher="stiff")


def play(vec, rng):
    obs = [vec.reset()]
    rewards, dones, infos = [], [], []
    for _ in range(CONFIG.pushes):
        o, r, d, i = vec.step(rng.uniform(-1, 1, (vec.num_envs, 2)).astype(np.float32))
        obs.append(o), rewards.append(r), dones.append(d), infos.append(i)
    return obs, rewards, dones, infos


@pytest.mark.slow
def test_lockstep_episodes_reward_the_predictors_estimates(predictor_file):
    vec = BatchPushVecEnv(CONFIG, str(predictor_file), n_envs=8, seed=0)
    obs, rewards, dones, infos = play(vec, np.random.default_rng(0))
    assert obs[0].shape == (8, history_dim(2, 2))
    assert not dones[0].any() and dones[1].all()  # K = 2 pushes, together
    assert "terminal_observation" in infos[1][0]
    for t in range(2):
        for e in range(8):
            info = infos[t][e]
            if info["failure"] is None and "estimate" in info:
                assert rewards[t][e] == pytest.approx(
                    paper_reward(info["estimate"], info["mass_distribution"]), rel=1e-5
                )
    # A fresh episode starts after the last push: the push counter is back at 0.
    np.testing.assert_array_equal(obs[2][:, -2:], np.tile([1.0, 0.0], (8, 1)))


@pytest.mark.slow
def test_the_same_seed_gives_the_same_episodes(predictor_file):
    runs = []
    for _ in range(2):
        vec = BatchPushVecEnv(CONFIG, str(predictor_file), n_envs=4, seed=0)
        vec.seed(7)
        runs.append(play(vec, np.random.default_rng(1)))
    for a, b in zip(runs[0][1], runs[1][1], strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.slow
@pytest.mark.skipif(not on_batch_path("kuka"), reason="arms in lockstep need the compiled law")
def test_an_arm_pushes_in_lockstep(predictor_file):
    config = EnvConfig(physics=CONFIG.physics, pusher="kuka")
    vec = BatchPushVecEnv(config, str(predictor_file), n_envs=3, seed=0)
    _, rewards, dones, infos = play(vec, np.random.default_rng(0))
    assert dones[1].all() and np.isfinite(rewards[0]).all()
    assert sum(i["failure"] is None for i in infos[0]) >= 2


@pytest.mark.slow
def test_a_stationary_robot_is_refused(predictor_file):
    # Its pushes go through the reach governor, which the lockstep environments lack.
    config = EnvConfig(physics=CONFIG.physics, pusher="ur10-stationary")
    with pytest.raises(ValueError, match="batch path"):
        BatchPushVecEnv(config, str(predictor_file), 2)
