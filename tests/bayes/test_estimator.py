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
