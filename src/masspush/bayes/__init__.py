"""The simulation-based Bayesian estimator: a particle filter whose likelihood is the
simulator (`filter`), the arm scenes it simulates arms in (`arm_scenes`), and the filter as
an estimator of `masspush.evaluate` (`estimator`).

The names of the 0.1 module `masspush.bayes` are importable from here."""

from masspush.bayes.estimator import BAYES_MODELS, BayesEstimator, run_bayes_episode
from masspush.bayes.filter import (
    ARM_CONFIG,
    BayesConfig,
    InfoSeekingPolicy,
    ParticleFilter,
    Posterior,
    UnexplainedObservationWarning,
    default_config,
    filter_for,
)

__all__ = [
    "ARM_CONFIG",
    "BAYES_MODELS",
    "BayesConfig",
    "BayesEstimator",
    "InfoSeekingPolicy",
    "ParticleFilter",
    "Posterior",
    "UnexplainedObservationWarning",
    "default_config",
    "filter_for",
    "run_bayes_episode",
]
