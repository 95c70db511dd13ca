import numpy as np
import pytest

from masspush.bayes.hypotheses import friction_grid, hypothesis_filter
from masspush.settings import get_setting

SETTING = get_setting("2link-1-10")  # stiff pusher: quick to simulate
HYPOTHESES = [np.array([2.0, 8.0]), np.array([8.0, 2.0]), np.array([5.0, 5.0])]


def test_the_friction_grid_lies_evenly_inside_the_range():
    low, high = SETTING.physics().friction_range
    grid = friction_grid(SETTING, 4)
    assert len(grid) == 4 and low < grid[0] and grid[-1] < high
    np.testing.assert_allclose(np.diff(grid), (high - low) / 5)
    with pytest.raises(ValueError, match="at least 1"):
        friction_grid(SETTING, 0)


def test_each_episode_starts_from_the_hypotheses_themselves():
    hyp = hypothesis_filter(SETTING, HYPOTHESES, friction_grid(SETTING, 3), lookahead=4)
    try:
        assert hyp.filter.config.particles == 9 and hyp.filter.config.lookahead_particles == 4
        hyp.reset(np.array([0.12, 0.13]), episode=0)
        np.testing.assert_array_equal(hyp.filter.masses, np.repeat(HYPOTHESES, 3, axis=0))
        hyp.filter.masses[:] = 1.0  # what a resampling would do
        hyp.reset(np.array([0.12, 0.13]), episode=1)
        np.testing.assert_array_equal(hyp.filter.masses[3:6], np.tile(HYPOTHESES[1], (3, 1)))
        np.testing.assert_array_equal(hyp.filter.friction, np.tile(friction_grid(SETTING, 3), 3))
        assert hyp.weights() == pytest.approx(np.full(3, 1 / 3))
        assert hyp.onehot.shape == (9, 3) and np.all(hyp.onehot[3:6, 1] == 1)
    finally:
        hyp.close()


def test_a_push_made_by_one_hypothesis_weighs_it_highest():
    frictions = friction_grid(SETTING, 3)
    hyp = hypothesis_filter(SETTING, HYPOTHESES, frictions)
    try:
        hyp.reset(np.array([0.12, 0.12]), episode=0)
        start, action = np.array([0.0, 0.0, 0.0, 0.3]), np.array([0.6, 0.5])
        # The first link light, the second heavy: pushed on its second link, it turns less.
        observed, failed = hyp.filter.simulate(start, action[None], HYPOTHESES[:1], frictions[1:2])
        assert not failed[0]
        hyp.filter.update(start, action, observed[0])
        weights = hyp.weights()
        assert np.argmax(weights) == 0 and weights.sum() == pytest.approx(1.0)
        assert weights[0] > 0.5
    finally:
        hyp.close()


def test_hypotheses_of_another_chain_are_refused():
    with pytest.raises(ValueError, match=r"\(H, 2\) link masses"):
        hypothesis_filter(SETTING, [np.array([1.0, 2.0, 3.0])], friction_grid(SETTING, 2))
    with pytest.raises(ValueError, match="frictions at least"):
        hypothesis_filter(SETTING, HYPOTHESES, np.array([]))
    with pytest.raises(ValueError, match="lookahead_particles >= 4"):  # 0 is not the default
        hypothesis_filter(SETTING, HYPOTHESES, friction_grid(SETTING, 3), lookahead=0)


class ShareLikelihood:
    """A known push density: the chain moves along its first link by the first link's share
    of the mass, seen with noise 0.01, whatever the friction."""

    def digest(self):
        return "share"

    def _mean(self, start, masses):
        out = np.array(np.broadcast_to(start, (len(masses), len(start))), float)
        out[:, 0] += masses[:, 0] / masses.sum(axis=1)
        return out

    def log_prob(self, start, action, observed, masses, friction, lengths):
        return -0.5 * np.sum(((observed - self._mean(start, masses)) / 0.01) ** 2, axis=1)


def test_with_a_density_the_hypotheses_are_weighed_by_it_not_simulated():
    hyp = hypothesis_filter(
        SETTING, HYPOTHESES, friction_grid(SETTING, 3), density=ShareLikelihood()
    )
    try:
        assert hyp.filter.density is not None and hyp.filter.config.likelihood == "learned"
        assert hyp.filter.config.particles == 9  # the hypotheses, not the learned filter's 4096
        hyp.reset(np.array([0.12, 0.12]), episode=0)
        start = np.zeros(4)
        observed = start + np.array([0.8, 0, 0, 0])  # the second hypothesis's share, 8 / 10
        hyp.filter.update(start, np.array([0.5, 0.5]), observed)
        weights = hyp.weights()
        assert np.argmax(weights) == 1 and weights[1] > 0.99
    finally:
        hyp.close()
