"""The particle filter over a fixed set of hypotheses: known mass distributions (a real
object's classes), each at a grid of table frictions, never resampled.

Its weights after an episode's pushes say how well each hypothesis explains them: the
ceiling of any classifier of the same pushes (`experiments/sim2real/class_oracle.py`), and,
through the filter's lookahead with one-hot values, how well a candidate push would tell the
hypotheses apart (`experiments/sim2real/class_seeking.py`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from masspush.bayes.filter import ParticleFilter, PushLikelihood, default_config, filter_for

if TYPE_CHECKING:
    from masspush.settings import Setting


def friction_grid(setting: Setting, count: int) -> np.ndarray:
    """`count` table frictions evenly inside the setting's range (`grid_inside`)."""
    return grid_inside(*setting.physics().friction_range, count)


def grid_inside(low: float, high: float, count: int) -> np.ndarray:
    """`count` frictions evenly inside [low, high], its ends left out: each point stands
    for the stretch around it."""
    if count < 1:
        raise ValueError(f"a friction grid needs at least 1 point, got {count}")
    return np.linspace(low, high, count + 2)[1:-1]


@dataclass
class HypothesisFilter:
    """A `ParticleFilter` whose particles are every hypothesis at every friction
    (hypothesis-major: particle h * F + f), restored by `reset` for each episode."""

    filter: ParticleFilter
    masses: np.ndarray
    """(H * F, n) each particle's link masses."""
    friction: np.ndarray
    """(H * F,) each particle's table friction."""
    hypotheses: int

    @property
    def onehot(self) -> np.ndarray:
        """(H * F, H) each particle's hypothesis, one-hot (`ParticleFilter.expected_variance`
        values whose expected variance is the Gini impurity of the hypotheses)."""
        per = len(self.friction) // self.hypotheses
        return np.repeat(np.eye(self.hypotheses), per, axis=0)

    def reset(self, lengths: np.ndarray, episode: int | None = None) -> None:
        """A new episode (`ParticleFilter.reset`), the particles the hypotheses again."""
        self.filter.reset(np.asarray(lengths, float), episode=episode)
        self.filter.masses, self.filter.friction = self.masses.copy(), self.friction.copy()

    def weights(self) -> np.ndarray:
        """(H,) each hypothesis's posterior probability, its frictions summed."""
        return self.filter.weights.reshape(self.hypotheses, -1).sum(axis=1)

    def close(self) -> None:
        self.filter.close()


def hypothesis_filter(
    setting: Setting,
    hypotheses: list[np.ndarray] | np.ndarray,
    frictions: np.ndarray,
    pusher: str | None = None,
    lookahead: int | None = None,
    seed: int = 0,
    density: PushLikelihood | None = None,
) -> HypothesisFilter:
    """The filter for chains of `setting` pushed by `pusher` (the setting's by default) whose
    particles are each of `hypotheses` (link masses) at each of `frictions`, never
    resampled; `lookahead` particles per candidate push (the setting's default, at most
    all of them). With a `density` (`masspush.learn.push_density`) it weighs pushes with
    that learned likelihood instead of simulating each hypothesis."""
    masses = np.asarray(hypotheses, float)
    frictions = np.asarray(frictions, float)
    if masses.ndim != 2 or masses.shape[1] != setting.n_links or len(frictions) < 1:
        raise ValueError(
            f"hypotheses must be (H, {setting.n_links}) link masses and frictions at least "
            f"one; got {masses.shape} and {frictions.shape}"
        )
    h, f = len(masses), len(frictions)
    config = default_config(setting, pusher, "simulator" if density is None else "learned")
    lookahead = config.lookahead_particles if lookahead is None else lookahead
    config = replace(
        config,
        particles=h * f,
        ess_fraction=1e-9,  # never resampled: the hypotheses are the particles
        lookahead_particles=min(lookahead, h * f),
    )
    filt = filter_for(setting, pusher, config=config, seed=seed, density=density)
    return HypothesisFilter(filt, np.repeat(masses, f, axis=0), np.tile(frictions, h), h)
