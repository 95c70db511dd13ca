"""The simulation-based Bayesian estimator: a particle filter whose likelihood is the
simulator (`filter`), the arm scenes it simulates arms in (`arm_scenes`), the filter over a
fixed set of hypotheses (`hypotheses`), and the filter as an estimator of
`masspush.evaluate` (`estimator`).

The names below are its public API (what experiments/ may import); those of the 0.1 module
`masspush.bayes` are among them."""

from masspush._exports import lazy, names

EXPORTS = {
    "filter": ("ARM_CONFIG", "ARM_MAX_PUSH", "ARM_SURROGATE", "BayesConfig", "InfoSeekingPolicy",
               "ParticleFilter", "Posterior", "UnexplainedObservationWarning", "bayes_overrides",
               "config_difference", "default_config", "failure_floor", "filter_for",
               "friction_prior"),
    "estimator": ("BAYES_MODELS", "BayesEstimator", "run_bayes_episode"),
    "arm_scenes": ("ArmScene", "ArmSimulator"),
    "hypotheses": ("HypothesisFilter", "friction_grid", "hypothesis_filter"),
}  # fmt: skip
__getattr__ = lazy(__name__, EXPORTS)
__all__ = names(EXPORTS)
