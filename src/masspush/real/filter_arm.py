"""The particle filter as an arm of the real-robot protocol (`masspush sim2real
--learned-model bayes`).

The protocol gives a model two roles: its policy chooses the pushes and its predictor's
estimates feed the classifier. `FilterArm` plays both with one particle filter
(`masspush.bayes`): the information-seeking pushes (random ones for bayes-random) and the
filter's estimate after each good push, which the recording keeps (`estimates`). The filter
keeps every push of an episode, all its runs: a predictor reads each run on its own because it
was trained on runs of the setting's length; the filter's posterior after 16 pushes is what all
16 say.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from masspush.bayes.estimator import BayesEstimator
from masspush.bayes.filter import (
    BayesConfig,
    InfoSeekingPolicy,
    UnexplainedObservationWarning,
    filter_for,
)
from masspush.config import MAX_PUSHES
from masspush.data.rollout import Episodes, RandomPolicy
from masspush.sim.workspace import ReachGovernor

if TYPE_CHECKING:
    from masspush.settings import Setting

Reachable = Callable[[np.ndarray, np.ndarray, Sequence[float]], bool]
"""`reachable(action, config, lengths)`: whether the robot can make a push
(`masspush.sim.arm_reach.ReachCheck`)."""


def check_bayes_options(bayes: dict | None, filtered: bool) -> None:
    """A one-line ValueError, before any episode, for `BayesConfig` overrides (`--bayes`)
    that no filter arm (`filtered` False) would use or that `BayesConfig` refuses."""
    if not bayes:
        return
    if not filtered:
        raise ValueError("bayes options are the particle filter's; no arm's model is bayes")
    if "density" in bayes:
        raise ValueError("bayes: give the push density as density (--density FILE)")
    try:
        BayesConfig(**bayes)
    except (TypeError, ValueError) as err:
        raise ValueError(f"bayes: {err}") from None


class FilterArm:
    """The filter of `estimator` (`masspush.models.load_estimator("bayes", ...)`) as a
    `masspush.data.rollout.Policy` for one episode at a time and as the predictor that
    `masspush.real.robot.run_estimation` asks after each good push."""

    runs = MAX_PUSHES
    """Never start afresh between runs of one episode (`run_segments`)."""

    @classmethod
    def load(
        cls, model: str, setting: Setting, seed: int = 0, density: str | None = None,
        overrides: dict | None = None,
    ) -> FilterArm:  # fmt: skip
        """The filter `model` (bayes, bayes-random) for chains of `setting` (a `Setting`),
        weighing pushes with the push density file `density` (default: the setting's
        shipped one, `masspush.models.load_estimator`), its `BayesConfig` changed by
        `overrides`."""
        from masspush.models import load_estimator

        bayes = {} if density is None else {"likelihood": "learned", "density": density}
        bayes |= overrides or {}
        return cls(load_estimator(model, setting, bayes=bayes or None, progress=False), seed)

    def __init__(
        self, estimator: BayesEstimator, seed: int = 0, governor: ReachGovernor | None = None
    ) -> None:
        self.name = estimator.name
        self.filter = filter_for(
            estimator.setting, estimator.pusher, estimator.config, seed, estimator.density
        )
        self.seeking = InfoSeekingPolicy(self.filter, seed, governor) if estimator.seeking else None
        self._random = RandomPolicy()
        self._episode: int | None = None

    @property
    def governor(self) -> ReachGovernor | None:
        """The stationary robot's speed governor the candidates are compared through (the
        robot's own, which may be fitted to its lab: `masspush.real.governor`)."""
        return None if self.seeking is None else self.seeking.governor

    @governor.setter
    def governor(self, governor: ReachGovernor | None) -> None:
        if self.seeking is not None:
            self.seeking.governor = governor

    @property
    def reach_check(self) -> Reachable | None:
        """Whether the robot can make a push (`masspush.sim.arm_reach.ReachCheck`), asked
        of the candidates best first; None: the best is pushed unasked."""
        return None if self.seeking is None else self.seeking.reachable

    @reach_check.setter
    def reach_check(self, check: Reachable | None) -> None:
        if self.seeking is not None:
            self.seeking.reachable = check

    def reset(self, seeds: np.ndarray) -> None:
        if len(seeds) != 1:
            raise ValueError(f"the filter runs one episode at a time, got {len(seeds)} seeds")
        self._episode = int(seeds[0])
        self._random.reset(seeds)

    def act(
        self, observations: np.ndarray, actions: np.ndarray, step: int, lengths: np.ndarray
    ) -> np.ndarray:
        if self._episode is not None:  # the first push of an episode: a fresh prior
            self.filter.reset(np.asarray(lengths[0], float), episode=self._episode)
            if self.seeking is not None:
                self.seeking.reset(self._episode)
            self._episode = None
        if self.seeking is None:
            return self._random.act(observations, actions, step, lengths)
        start = np.asarray(observations[0, step], float)
        return self.seeking.act(start)[None].astype(np.float32)

    def predict(self, history: Episodes) -> np.ndarray:
        """The filter's estimate (1, 1, n) after the newest push of `history`, which it
        weighs now: call it once after each good push, in order, as `run_estimation` does."""
        k = history.actions.shape[1]
        if k < 1:
            raise ValueError("the filter estimates after a push; the history has none")
        obs = np.asarray(history.observations[0], float)
        with warnings.catch_warnings():  # a lab's outlier is weighed all the same
            warnings.simplefilter("ignore", UnexplainedObservationWarning)
            posterior = self.filter.update(obs[k - 1], np.asarray(history.actions[0, k - 1]),
                                           obs[k])  # fmt: skip
        return np.asarray(posterior.estimate, np.float32)[None, None]

    def close(self) -> None:
        self.filter.close()
