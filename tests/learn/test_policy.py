from dataclasses import replace

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from masspush.config import EnvConfig
from masspush.data.rollout import TRAIN, Episodes, run_batch, run_env, run_episodes
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
@pytest.mark.parametrize("loss", [LOSS_REWARD, -30.0])
def test_a_policy_environment_for_a_stationary_robot_pays_for_a_lost_chain(predictor_file, loss):
    config = EnvConfig(physics=get_setting("real-ur10").physics(), pusher="ur10-stationary")
    env = PushPolicyEnv(config, str(predictor_file), loss_reward=loss)
    assert env.observation_space.shape == (history_dim(2, 2, env.workspace),)
    env.governor = None  # the robot without its speed governor
    env.reset(seed=0, options=EDGE_CHAIN)
    # Full speed away from the base on a light chain near the workspace's edge.
    _, reward, done, _, info = env.step(np.array([1.0, -0.5], np.float32))
    assert done and info["failure"] == "left_workspace" and reward == loss


EDGE_CHAIN = {"masses": [0.02, 0.02], "root_pose": [0.0, 0.2, 0.0], "joint_angles": [0.0],
              "lengths": [0.12, 0.12], "friction": 0.5}  # fmt: skip


@pytest.mark.slow
def test_a_stationary_robots_policy_learns_with_its_speed_governor(predictor_file):
    config = EnvConfig(physics=get_setting("real-ur10").physics(), pusher="ur10-stationary")
    env = PushPolicyEnv(config, str(predictor_file))
    env.reset(seed=0, options=EDGE_CHAIN)
    _, _, _, _, info = env.step(np.array([1.0, -0.5], np.float32))
    # The same push as above, slowed: the chain stays, and the history holds the push made.
    assert info["failure"] is None and 0.0 < env._actions[0, 0, 0] < 0.2
    assert env._actions[0, 0, 1] == np.float32(-0.5)


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


@pytest.mark.slow
def test_an_episode_of_runs_restarts_the_history_on_the_same_chain(predictor_file):
    from masspush.learn.predictor import load_model

    # Without observation noise the rest pose seen is the true one.
    env = PushPolicyEnv(replace(CONFIG, obs_noise=0.0), str(predictor_file), runs=3)
    check_env(env, skip_render_check=True)
    predictor = load_model(predictor_file)[0]
    for seed in range(4):
        obs, info = env.reset(seed=seed)
        steps, done = 0, False
        while not done:
            obs, reward, done, _, step = env.step(np.array([0.3, 0.4], np.float32))
            steps += 1
            assert step["mass_distribution"].tolist() == info["mass_distribution"].tolist()
            if steps % 2 == 0 and not done:
                # A run ended: the next begins at its last rest pose with an empty history.
                fresh = np.full((1, 3, env.d), np.nan, np.float32)
                fresh[0, 0] = step["config"]
                expected = history_features(
                    fresh, np.full((1, 2, 2), np.nan, np.float32), env._lengths, 0
                )[0]
                np.testing.assert_allclose(obs, expected, atol=1e-6)
                assert env._t == 0 and env._run == steps // 2
        assert steps == 6 or step["failure"] is not None
    # The estimate paid for is the run's: the frozen predictor on the run's history alone.
    env.reset(seed=1)
    env.step(np.array([0.3, 0.4], np.float32))
    _, _, done, _, step = env.step(np.array([0.3, 0.4], np.float32))
    if not done:
        start = env._obs[0, 0].copy()
        _, reward, _, _, step = env.step(np.array([0.3, 0.4], np.float32))
        if step["failure"] is None:
            obs = np.full((1, 3, env.d), np.nan, np.float32)
            obs[0, 0], obs[0, 1] = start, env._obs[0, 1]
            actions = np.zeros((1, 2, 2), np.float32)
            actions[0, 0] = [0.3, 0.4]
            history = Episodes.history(obs, actions, env._lengths)
            estimate = predictor.predict(history)[0, 0]
            assert reward == pytest.approx(float(paper_reward(estimate, env._truth)))


@pytest.mark.slow
def test_a_policy_trains_on_episodes_of_runs(predictor_file, tmp_path):
    import json

    from masspush.learn.policy import make_vec_env

    vec = make_vec_env(CONFIG, predictor_file, 2, 0, runs=3, reward="gain")
    try:
        # Not the batch path, which has neither.
        assert vec.get_attr("runs") == [3, 3] and vec.get_attr("reward") == ["gain"] * 2
    finally:
        vec.close()
    config = PolicyConfig(n_envs=2, steps=16, n_steps=8, runs=3)
    path = train_policy(CONFIG, predictor_file, tmp_path / "p", config, progress=False)
    assert json.loads((tmp_path / "p" / "policy.json").read_text())["config"]["runs"] == 3
    policy = LearnedPolicy(path, "recurrent", runs=3)
    assert run_episodes(CONFIG, policy, np.arange(3), TRAIN, 0).actions.shape == (3, 2, 2)


def test_a_policy_environment_of_runs_needs_the_training_simulation(predictor_file):
    with pytest.raises(ValueError, match="runs"):
        PushPolicyEnv(CONFIG, str(predictor_file), chain_env=lambda: None, runs=2)
    with pytest.raises(ValueError, match="runs"):
        PushPolicyEnv(CONFIG, str(predictor_file), runs=0)


def test_a_policy_trained_on_runs_says_so_to_its_deployment(tmp_path):
    from masspush.learn.policy import model_policy

    (tmp_path / "policy.zip").write_bytes(b"")
    meta = {"policy": "learned", "policy_file": "policy.zip", "policy_algo": "recurrent"}
    assert model_policy(meta, tmp_path / "m.pt").runs == 1
    assert model_policy({**meta, "policy_runs": 8}, tmp_path / "m.pt").runs == 8


def test_the_gain_reward_pays_what_a_push_taught_over_the_prior():
    truth = np.array([0.2, 0.8])
    assert push_reward(np.array([0.5, 0.5]), truth, None, "gain") == pytest.approx(0.0)
    perfect = push_reward(truth, truth, None, "gain")
    assert perfect == pytest.approx(10.0 - paper_reward(np.array([0.5, 0.5]), truth))
    assert push_reward(truth, truth, None) - perfect == pytest.approx(4.0)  # the prior's 4
    # A loss costs the same under both, and what it is told to.
    assert push_reward(None, truth, "left_workspace", "gain") == LOSS_REWARD
    assert push_reward(None, truth, "unreachable", "gain", loss=-30.0) == -30.0
    assert push_reward(None, truth, "unstable", "gain", loss=-30.0) == 0.0  # not a loss


def test_bad_policy_configs_are_refused():
    with pytest.raises(ValueError, match="reward"):
        PolicyConfig(reward="speed")
    with pytest.raises(ValueError, match="loss_reward"):
        PolicyConfig(loss_reward=5.0)
    with pytest.raises(ValueError, match="runs"):
        PolicyConfig(runs=0)
    with pytest.raises(ValueError, match="recurrent"):
        PolicyConfig(algo="mlp", runs=2)
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

    from masspush.real.randomisation import world_env
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
