import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import masspush
from masspush.env import ChainEnv


def rollout(env, seed, actions):
    obs, info = env.reset(seed=seed)
    trajectory = [obs]
    for a in actions:
        obs, _reward, terminated, _truncated, info = env.step(a)
        trajectory.append(obs)
        if terminated:
            break
    return np.array(trajectory), info


def test_make_after_import():
    env = gym.make(masspush.ENV_ID, n_links=2, mass_range=(0.1, 1.0))
    obs, info = env.reset(seed=0)
    assert obs.shape == (6,) and obs.dtype == np.float32
    assert env.action_space.shape == (2,)
    for key in ("mass_distribution", "masses", "friction", "lengths"):
        assert key in info
    assert np.sum(info["mass_distribution"]) == pytest.approx(1.0)
    env.close()


# The table is unbounded, and so are positions: the checker's warning about that is expected.
@pytest.mark.filterwarnings("ignore:.*Box observation space m.*:UserWarning")
@pytest.mark.parametrize("n_links", [2, 3])
def test_passes_gymnasium_env_checker(n_links):
    check_env(ChainEnv(n_links=n_links), skip_render_check=True)


@pytest.mark.parametrize(("n_links", "pushes"), [(2, 2), (3, 3)])
def test_episode_is_k_pushes(n_links, pushes):
    env = ChainEnv(n_links=n_links)
    env.reset(seed=1)
    for k in range(pushes):
        _, reward, terminated, truncated, info = env.step(np.array([0.2, 0.0]))
        assert reward == 0.0 and not truncated
        assert info["pushes_done"] == k + 1
        assert terminated == (k == pushes - 1)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.array([0.2, 0.0]))
    env = ChainEnv(n_links=2, pushes=5)
    env.reset(seed=1)
    assert sum(not env.step(np.array([0.1, 0.0]))[2] for _ in range(5)) == 4


def test_same_seed_same_trajectory_other_seed_other():
    actions = np.array([[0.5, -0.3], [-0.7, 0.6], [0.3, 0.9]], dtype=np.float32)
    a, info_a = rollout(ChainEnv(n_links=3), 42, actions)
    b, info_b = rollout(ChainEnv(n_links=3), 42, actions)
    c, _ = rollout(ChainEnv(n_links=3), 43, actions)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(info_a["mass_distribution"], info_b["mass_distribution"])
    assert not np.array_equal(a, c)


def test_noise_settings():
    env = ChainEnv(n_links=2, obs_noise=0.0, action_noise=0.0)
    obs, info = env.reset(seed=3)
    np.testing.assert_allclose(obs[:4], info["config"], atol=1e-6)
    np.testing.assert_allclose(obs[4:], info["lengths"], atol=1e-6)
    obs, _, _, _, info = env.step(np.array([0.3, -0.2], dtype=np.float32))
    np.testing.assert_allclose(obs[:4], info["config"], atol=1e-6)
    np.testing.assert_array_equal(info["push"]["action"], np.array([0.3, -0.2], dtype=np.float32))

    noisy = ChainEnv(n_links=2, obs_noise=0.05)
    diffs = []
    for seed in range(20):
        obs, info = noisy.reset(seed=seed)
        diffs.append(obs[:4] - info["config"])
    assert np.std(diffs) == pytest.approx(0.05, rel=0.3)
    obs, info = ChainEnv(n_links=2).reset(seed=0)
    assert 0 < np.abs(obs[:4] - info["config"]).max() < 0.05


def test_options_pin_parameters():
    env = ChainEnv(n_links=2)
    options = {
        "masses": [0.2, 0.6],
        "friction": 0.8,
        "lengths": [0.11, 0.13],
        "joint_angles": [0.5],
        "root_pose": [0.0, 0.0, 0.0],
    }
    _obs, info = env.reset(seed=0, options=options)
    np.testing.assert_allclose(info["masses"], [0.2, 0.6])
    np.testing.assert_allclose(info["mass_distribution"], [0.25, 0.75])
    assert info["friction"] == 0.8
    np.testing.assert_allclose(info["config"][3], 0.5, atol=1e-3)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"n_links": 1}, "n_links"),
        ({"mass_range": (1.0, 1.0 - 1e-3)}, "empty"),
        ({"mass_range": (-1.0, 1.0)}, "positive"),
        ({"pusher": "hammer"}, "unknown pusher"),
        ({"pushes": 0}, "pushes"),
    ],
)
def test_bad_constructor_arguments(kwargs, message):
    with pytest.raises(ValueError, match=message):
        ChainEnv(**kwargs)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"colour": "red"}, "unknown option"),
        ({"friction": 0.0}, "friction"),
        ({"lengths": [0.1, -0.1]}, "lengths must be positive"),
        ({"masses": [0.0, 1.0]}, "masses must be positive"),
    ],
)
def test_bad_options(options, message):
    with pytest.raises(ValueError, match=message):
        ChainEnv().reset(seed=0, options=options)


@pytest.mark.parametrize("action", [[2.0, 0.0], [np.nan, 0.0], [0.1]])
def test_bad_actions_name_the_value(action):
    env = ChainEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.step(np.array(action))


def test_failed_push_ends_the_episode_with_a_reason():
    from masspush.config import PhysicsConfig

    env = ChainEnv(n_links=2, physics=PhysicsConfig(settle_time_cap=0.1))
    _, info = env.reset(seed=0)
    assert info["failure"] is None
    obs, _, terminated, _, info = env.step(np.array([1.0, -0.5]))
    assert terminated and info["failure"] == "timeout"
    assert np.all(np.isfinite(obs))


# Generated bad input (issue 26): every constructor argument and reset option given values
# of every wrong kind. Each must end in a ValueError of one line, nothing else.
WRONG = [None, True, "x", "2", np.nan, np.inf, -1, 0, 2.5, 1e6, [], [[1, 2]], {}, (1, 0)]
# The values of WRONG that an argument does accept: no pushes means the default; no noise.
ACCEPTED = {("pushes", None), ("obs_noise", 0), ("action_noise", 0)}
OPTION_KEYS = ("masses", "friction", "lengths", "joint_angles", "root_pose")


def _wrong_constructor_args():
    for key in ("n_links", "mass_range", "pushes", "obs_noise", "action_noise", "pusher"):
        for value in WRONG:
            if type(value) is not int or (key, value) not in ACCEPTED:
                if not (key == "pushes" and value is None):
                    yield key, value
    yield "n_links", 65  # beyond MAX_LINKS
    yield "mass_range", (1.0, 1e6)  # a tonne is the most a link may weigh
    yield "obs_noise", 5.0
    yield "action_noise", 2.0
    yield "pushes", 10**6


@pytest.mark.parametrize(("key", "value"), list(_wrong_constructor_args()), ids=repr)
def test_every_wrong_constructor_argument_is_one_clear_error(key, value):
    with pytest.raises(ValueError) as err:
        ChainEnv(**{key: value})
    assert "\n" not in str(err.value) and str(err.value)


def _wrong_options():
    for key in OPTION_KEYS:
        for value in WRONG:
            yield key, value
        size = {"masses": 2, "lengths": 2, "joint_angles": 1, "root_pose": 3, "friction": 1}[key]
        for item in (True, "0.5", None, np.nan):
            yield key, [item] * size if size > 1 or key != "friction" else item
    yield "masses", [1e6, 1.0]  # beyond any table
    yield "masses", [5.0, 0.5]  # beyond the setting's range
    yield "friction", 10.0
    yield "lengths", [10.0, 0.1]
    yield "root_pose", [1e9, 0.0, 0.0]
    yield "joint_angles", [3.0]


@pytest.mark.parametrize(("key", "value"), list(_wrong_options()), ids=repr)
def test_every_wrong_reset_option_is_one_clear_error(key, value):
    with pytest.raises(ValueError) as err:
        ChainEnv().reset(seed=0, options={key: value})
    assert "\n" not in str(err.value) and str(err.value)


def test_out_of_range_chains_when_allowed_and_long_chains():
    env = ChainEnv(allow_out_of_range=True)
    _, info = env.reset(seed=0, options={"masses": [5.0, 0.5], "friction": 1.5})
    np.testing.assert_allclose(info["masses"], [5.0, 0.5])
    with pytest.raises(ValueError, match="outside what a chain on a table can have"):
        env.reset(seed=0, options={"masses": [1e6, 1.0]})  # absurd is refused always


@pytest.mark.slow
def test_the_longest_supported_chain_resets_and_pushes():
    from masspush.config import MAX_LINKS

    env = ChainEnv(n_links=MAX_LINKS)
    _, info = env.reset(seed=0)
    assert info["failure"] is None  # 1 MB of arena was not enough above ~40 links
    _, _, _, _, info = env.step(np.array([0.3, 0.0], np.float32))
    assert info["failure"] in (None, "timeout")
