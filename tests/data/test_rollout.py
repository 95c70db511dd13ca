import numpy as np
import pytest

from masspush.config import EnvConfig, PhysicsConfig
from masspush.data.rollout import (
    EVAL,
    NOT_RUN,
    TRAIN,
    Episodes,
    RandomPolicy,
    episode_seed,
    run_batch,
    run_env,
)
from masspush.sim.pushers import on_batch_path


def _same_episodes(config: EnvConfig, n: int) -> Episodes:
    idx = np.arange(n)
    a = run_batch(config, RandomPolicy(), idx, TRAIN, 5)
    b = run_env(config, RandomPolicy(), idx, TRAIN, 5)
    for name in ("observations", "configs", "actions", "executed", "failure", "masses", "seed"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    return a


@pytest.mark.parametrize("n_links", [2, 3])
def test_batch_and_environment_engines_record_identical_episodes(n_links):
    a = _same_episodes(EnvConfig(physics=PhysicsConfig(n_links=n_links)), 12)
    assert a.observations.shape == (12, n_links + 1, n_links + 2)
    assert a.actions.shape == (12, n_links, 2)


@pytest.mark.slow
@pytest.mark.skipif(not on_batch_path("kuka"), reason="arms in lockstep need the compiled law")
def test_an_arm_in_lockstep_records_the_episodes_of_one_at_a_time():
    a = _same_episodes(EnvConfig(physics=PhysicsConfig(n_links=2), pusher="kuka"), 6)
    assert a.ok.sum() >= 4


def test_training_and_evaluation_seeds_never_meet():
    train = {episode_seed(TRAIN, b, i) for b in range(3) for i in range(2000)}
    evaluation = {episode_seed(EVAL, b, i) for b in range(3) for i in range(2000)}
    assert len(train) == 6000 and not train & evaluation


def test_failed_pushes_end_the_episode_in_the_record():
    config = EnvConfig(physics=PhysicsConfig(n_links=2, settle_time_cap=0.05))
    eps = run_batch(config, RandomPolicy(), np.arange(20), TRAIN, 0)
    failed = ~eps.ok
    assert failed.any()
    for e in np.flatnonzero(failed):
        codes = eps.failure[e]
        if codes[0] == NOT_RUN:  # failed already while settling before the first push
            assert (codes == NOT_RUN).all() and np.isnan(eps.observations[e]).all()
            continue
        first = np.flatnonzero(codes != 0)[0]
        assert codes[first] > 0
        assert (codes[first + 1 :] == NOT_RUN).all()
        assert np.isnan(eps.observations[e, first + 1 :]).all()


def test_episodes_select_and_concatenate():
    eps = run_batch(EnvConfig(), RandomPolicy(), np.arange(6), TRAIN, 1)
    both = Episodes.concatenate([eps.select(eps.index < 3), eps.select(eps.index >= 3)])
    np.testing.assert_array_equal(both.observations, eps.observations)
    np.testing.assert_allclose(eps.mass_distribution.sum(1), 1.0, rtol=1e-6)


@pytest.mark.parametrize("pusher", ["stiff", "kuka"])
def test_episodes_on_a_pool_are_the_episodes_run_here(serial_pool, pusher):
    from masspush.data.rollout import run_episodes

    config = EnvConfig(physics=PhysicsConfig(n_links=2), pusher=pusher)
    idx = np.arange(3, 9 if pusher == "kuka" else 20)
    here = run_episodes(config, RandomPolicy(), idx, EVAL, 2, workers=1)
    pooled = run_episodes(config, RandomPolicy(), idx, EVAL, 2, workers=serial_pool(size=2))
    for name in ("index", "observations", "configs", "actions", "executed", "failure"):
        np.testing.assert_array_equal(getattr(pooled, name), getattr(here, name))


class _FullSpeed(RandomPolicy):
    def act(self, observations, actions, step, lengths):
        return np.tile(np.array([1.0, -0.5], np.float32), (len(observations), 1))


@pytest.mark.slow
def test_a_stationary_robots_episodes_record_the_governed_push():
    from masspush.settings import get_setting
    from masspush.sim.pushers import reach_governor

    setting = get_setting("real-ur10")
    config = setting.env_config()
    governor = reach_governor(config.pusher, config.physics)
    out = run_env(config, _FullSpeed(), np.arange(8), TRAIN, 3)
    done = ~np.isnan(out.actions[..., 0])
    assert done.any()
    for e, t in zip(*np.nonzero(done), strict=True):
        expected = governor([1.0, -0.5], out.observations[e, t], out.lengths[e])
        np.testing.assert_array_equal(out.actions[e, t], expected)
    assert (out.actions[done][:, 0] < 1.0).any()  # some pushes were slowed


def test_an_episodes_chain_is_its_chain_at_its_true_start_pose():
    eps = run_batch(EnvConfig(), RandomPolicy(), np.arange(3), TRAIN, 3)
    for e in range(3):
        chain = eps.chain(e)
        np.testing.assert_allclose(chain.masses, eps.masses[e])
        np.testing.assert_allclose(chain.lengths, eps.lengths[e])
        assert chain.friction == pytest.approx(eps.friction[e])
        assert chain.root_pose + chain.joint_angles == tuple(eps.configs[e, 0].astype(float))
    heavier = eps.chain(1, masses=2 * eps.masses[1])
    np.testing.assert_allclose(heavier.mass_distribution, eps.mass_distribution[1], rtol=1e-6)
