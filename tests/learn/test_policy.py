from dataclasses import replace

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from masspush.config import EnvConfig
from masspush.data.rollout import TRAIN, run_batch, run_env, run_episodes
from masspush.learn.features import (
    LOSS_REWARD,
    history_dim,
    history_features,
    paper_reward,
    push_reward,
)
from masspush.learn.policy import (
    LearnedPolicy,
    PolicyConfig,
    PushPolicyEnv,
    strip_policy,
    train_policy,
)
from masspush.settings import get_setting
from masspush.sim.pushers import pusher_kind

CONFIG = EnvConfig(physics=get_setting("2link-0.1-1").physics(), pusher="stiff")


def test_reward_is_the_papers_formula_as_coded():
    # 10 (1 - 2 mean_i |m_i - m_hat_i|): mean |.| = (0.2 + 0.2) / 2 = 0.2 -> 10 * 0.6
    assert paper_reward(np.array([0.3, 0.7]), np.array([0.5, 0.5])) == pytest.approx(6.0)
    assert paper_reward(np.array([0.2, 0.3, 0.5]), np.array([0.2, 0.3, 0.5])) == 10.0
    # mean |.| = (0.5 + 0.25 + 0.25) / 3 = 1/3 -> 10 (1 - 2/3)
    got = paper_reward(np.array([[0.0, 0.5, 0.5]]), np.array([[0.5, 0.25, 0.25]]))
    np.testing.assert_allclose(got, [10 / 3])


def test_history_features_hide_the_future():
    rng = np.random.default_rng(0)
    obs = rng.normal(size=(4, 3, 4)).astype(np.float32)
    actions = rng.uniform(-1, 1, (4, 2, 2)).astype(np.float32)
    lengths = np.full((4, 2), 0.12, np.float32)
    before = history_features(obs, actions, lengths, step=0)
    assert before.shape == (4, history_dim(2, 2))
    changed_future = obs.copy()
    changed_future[:, 1:] += 1.0
    np.testing.assert_array_equal(
        before, history_features(changed_future, actions * 0.5, lengths, step=0)
    )
    np.testing.assert_array_equal(before[:, -2:], np.tile([1.0, 0.0], (4, 1)))  # push number
    after = history_features(obs, actions, lengths, step=1)
    assert not np.array_equal(before, after)


def test_a_stationary_robots_policy_sees_where_the_chain_lies_from_it():
    workspace = pusher_kind("ur10-stationary").workspace
    obs = np.zeros((2, 3, 4), np.float32)
    obs[:, :, 1] = [[0.0, 0.1, 0.2], [0.0, -0.1, 0.3]]  # y of the root, push by push
    actions = np.zeros((2, 2, 2), np.float32)
    lengths = np.full((2, 2), 0.12, np.float32)
    plain = history_features(obs, actions, lengths, 1)
    seen = history_features(obs, actions, lengths, 1, workspace)
    assert seen.shape == (2, history_dim(2, 2, workspace)) == (2, plain.shape[1] + 4)
    np.testing.assert_array_equal(seen[:, :-4], plain)  # the relative history is unchanged
    # The latest pose (after push 1), ahead of the base by 0.7 m + y.
    np.testing.assert_allclose(seen[:, -4], [0.8, 0.6], atol=1e-6)
    # Where the chain lies moves only the new inputs: the history is relative to q_0.
    shifted = obs.copy()
    shifted[:, :, 0] += 0.05
    np.testing.assert_array_equal(history_features(shifted, actions, lengths, 1), plain)
    assert not np.array_equal(history_features(shifted, actions, lengths, 1, workspace), seen)


def test_losing_the_chain_costs_more_than_any_estimate_gains():
    truth = np.array([0.5, 0.5])
    assert push_reward(truth, truth, None) == 10.0
    assert push_reward(np.array([1.0, 0.0]), truth, None) == 0.0  # the worst estimate
    for failure in ("unreachable", "left_workspace"):
        assert push_reward(None, truth, failure) == LOSS_REWARD == -10.0
    for failure in ("unstable", "timeout", "arm_contact", "nan"):
        assert push_reward(None, truth, failure) == 0.0


@pytest.mark.slow
def test_a_policy_environment_for_a_stationary_robot_pays_for_a_lost_chain(predictor_file):
    config = EnvConfig(physics=get_setting("real-ur10").physics(), pusher="ur10-stationary")
    env = PushPolicyEnv(config, str(predictor_file))
    assert env.observation_space.shape == (history_dim(2, 2, env.workspace),)
    env.reset(seed=0, options=None)
    # Full speed away from the base on a light chain near the workspace's edge.
    env.chain_env.reset(options={"masses": [0.02, 0.02], "root_pose": [0.0, 0.2, 0.0],
                                 "joint_angles": [0.0], "lengths": [0.12, 0.12],
                                 "friction": 0.5})  # fmt: skip
    _, reward, done, _, info = env.step(np.array([1.0, -0.5], np.float32))
    assert done and info["failure"] == "left_workspace" and reward == LOSS_REWARD


@pytest.mark.slow
def test_environment_rewards_the_frozen_predictors_estimate(predictor_file):
    env = PushPolicyEnv(CONFIG, str(predictor_file))
    check_env(env, skip_render_check=True)
    obs, info = env.reset(seed=3)
    assert obs.shape == env.observation_space.shape
    done, rewards = False, []
    while not done:
        obs, reward, done, _, step_info = env.step(env.action_space.sample())
        if step_info["failure"] is None:
            assert reward == pytest.approx(
                paper_reward(step_info["estimate"], info["mass_distribution"])
            )
        rewards.append(reward)
    assert len(rewards) <= 2


@pytest.mark.slow
def test_a_trained_policy_pushes_the_same_way_for_the_same_seeds(predictor_file, tmp_path):
    config = PolicyConfig(algo="mlp", n_envs=2, steps=64, n_steps=16)
    path = train_policy(
        CONFIG,
        predictor_file,
        tmp_path / "policy",
        config,
        progress=False,
        meta={"setting": {"name": "2link-0.1-1"}},
    )
    assert (tmp_path / "policy" / "progress.csv").read_text().startswith("timesteps,")
    assert not list((tmp_path / "policy").glob("checkpoint_*"))  # cleaned up when done
    for deterministic in (True, False):
        policy = LearnedPolicy(path, "mlp", deterministic)
        a = run_episodes(CONFIG, policy, np.arange(12), TRAIN, 0)
        b = run_episodes(CONFIG, policy, np.arange(12), TRAIN, 0)
        np.testing.assert_array_equal(a.actions, b.actions)
        assert np.all(np.abs(a.actions[a.ok]) <= 1.0)
    # Both engines show the policy the same first rest pose, so it chooses the same first push.
    batch = run_batch(CONFIG, LearnedPolicy(path, "mlp"), np.arange(6), TRAIN, 0)
    single = run_env(CONFIG, LearnedPolicy(path, "mlp"), np.arange(6), TRAIN, 0)
    np.testing.assert_allclose(batch.actions[:, 0], single.actions[:, 0], atol=1e-6)
    # The shipped copy drops the optimizer's moments and acts exactly the same.
    shipped = strip_policy(path, tmp_path / "shipped.zip")
    assert shipped.stat().st_size < 0.6 * path.stat().st_size
    a = run_episodes(CONFIG, LearnedPolicy(path, "mlp"), np.arange(6), TRAIN, 0)
    b = run_episodes(CONFIG, LearnedPolicy(shipped, "mlp"), np.arange(6), TRAIN, 0)
    np.testing.assert_array_equal(a.actions, b.actions)


def test_bad_policy_configs_are_refused():
    with pytest.raises(ValueError, match="algo"):
        PolicyConfig(algo="sac")
    with pytest.raises(ValueError, match="n_steps"):
        PolicyConfig(n_steps=1)
    with pytest.raises(ValueError, match="initial_action"):
        PolicyConfig(initial_action=(1.5, 0.0))
    with pytest.raises(ValueError, match="learning_rate"):
        PolicyConfig(learning_rate=0.0)


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["mlp", "recurrent"])
def test_an_untrained_policy_starts_at_the_initial_action(algo, predictor_file, tmp_path):
    """The zero action is a saddle (docs/training.md): the policy must start elsewhere."""
    config = PolicyConfig(algo=algo, n_envs=2, steps=2, n_steps=2, initial_action=(0.6, -0.4))
    config = replace(config, learning_rate=1e-12)  # one update that changes nothing
    path = train_policy(CONFIG, predictor_file, tmp_path / "p", config, progress=False)
    actions = run_episodes(CONFIG, LearnedPolicy(path, algo), np.arange(4), TRAIN, 0).actions
    np.testing.assert_allclose(actions[:, 0], np.tile([0.6, -0.4], (4, 1)), atol=0.05)


@pytest.mark.slow
def test_the_policy_environment_pushes_in_another_world(predictor_file):
    from functools import partial

    from masspush.real.randomise import world_env
    from masspush.real.target_world import TargetWorld

    setting = get_setting("2link-0.1-1")
    config = replace(CONFIG, pushes=2)
    other = partial(world_env, setting.name, TargetWorld(), config.pusher, config.pushes)
    env = PushPolicyEnv(config, str(predictor_file), chain_env=other)
    check_env(env, skip_render_check=True)
    _, info = env.reset(seed=3)
    _, base_info = PushPolicyEnv(config, str(predictor_file)).reset(seed=3)
    assert info["mass_distribution"].tolist() != base_info["mass_distribution"].tolist()
    _, reward, _, _, step_info = env.step(np.array([0.5, 0.5], np.float32))
    if step_info["failure"] is None:
        assert reward == pytest.approx(
            paper_reward(step_info["estimate"], info["mass_distribution"])
        )
