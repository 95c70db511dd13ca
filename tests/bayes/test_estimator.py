import pytest

from masspush.bayes.estimator import BayesEstimator
from masspush.bayes.filter import BayesConfig
from masspush.evaluate import evaluate
from masspush.settings import get_setting

SETTING = get_setting("2link-1-10")  # stiff pusher: the filter's own
SMALL = BayesConfig(particles=48, lookahead_particles=8, candidates=3)


def evaluate_bayes(setting, model, episodes, config, overrides=None):
    estimator = BayesEstimator(setting, model, config=config, overrides=overrides, progress=False)
    return evaluate(setting, estimator, episodes).to_dict()


@pytest.mark.slow
def test_evaluate_scores_the_filter_with_coverage_and_time(monkeypatch):
    result = evaluate_bayes(SETTING, "bayes-random", episodes=3, config=SMALL)
    assert result["episodes"] + result["failures"] == 3
    assert 0 <= result["coverage"] <= 1 and result["seconds_per_episode"] > 0
    assert result["percentage_error"] < result["constant_floor"] * 2
    tuned = evaluate_bayes(SETTING, "bayes-random", episodes=1, config=SMALL,
                           overrides={"likelihood_power": 0.5})  # fmt: skip
    assert tuned["filter"]["likelihood_power"] == 0.5 and result["filter"]["likelihood_power"] == 1
    assert tuned["filter"]["particles"] == SMALL.particles
    with pytest.raises(ValueError, match="unknown Bayesian model"):
        BayesEstimator(SETTING, "bayes-magic", config=SMALL)


@pytest.mark.slow
def test_information_seeking_beats_random_pushes_and_intervals_cover():
    config = BayesConfig(particles=128, lookahead_particles=16, candidates=6)
    random = evaluate_bayes(SETTING, "bayes-random", episodes=16, config=config)
    seeking = evaluate_bayes(SETTING, "bayes", episodes=16, config=config)
    assert seeking["percentage_error"] < random["percentage_error"], (seeking, random)
    assert 0.7 <= seeking["coverage"] <= 1.0 and 0.7 <= random["coverage"] <= 1.0


def bayes_run(indices, workers=None, model="bayes"):
    import numpy as np

    estimator = BayesEstimator(SETTING, model, config=SMALL, progress=False)
    return estimator.run(SETTING.env_config("stiff"), np.asarray(indices), 4, workers)


@pytest.mark.slow
def test_an_episode_estimate_does_not_depend_on_the_episodes_before_it():
    import numpy as np

    alone = bayes_run([2, 3])
    after_others = bayes_run([0, 1, 2, 3])
    keep = np.isin(after_others.index, [2, 3])
    np.testing.assert_array_equal(after_others.estimates[keep], alone.estimates)


@pytest.mark.slow
def test_the_filter_on_a_pool_gives_the_run_it_gives_here(serial_pool):
    import numpy as np

    here = bayes_run(range(5), model="bayes-random")
    pooled = bayes_run(range(5), workers=serial_pool(size=2), model="bayes-random")
    np.testing.assert_array_equal(pooled.index, here.index)
    np.testing.assert_array_equal(pooled.estimates, here.estimates)
    assert pooled.failures == here.failures
    timing = "seconds_per_episode"
    assert {k: v for k, v in pooled.extra.items() if k != timing} == {
        k: v for k, v in here.extra.items() if k != timing
    }
