"""A simulation-based Bayesian estimator: a particle filter whose likelihood is the simulator.

Each particle is one guess of the unknowns, the link masses and the table friction. After
a push, every particle's chain is placed at the rest pose observed before the push and
pushed with the action that was commanded, all particles at once on the batch path
(`masspush.sim.batch`); the particle's weight is multiplied by the likelihood of the observed
rest pose given its simulated one. The estimate is the posterior median of the mass
distribution on the simplex (`simplex_median`: the Bayes estimate for the paper's metric,
which scales with the absolute error), with credible intervals per link.

The likelihood is a Student-t (4 degrees of freedom; `tail_dof`, None for a Gaussian) per
configuration component with scale
    sigma_k^2 = obs_noise^2 + spread_k^2 + (motion_slack * |predicted change of k|)^2:
the observation's noise; `spread`, how far the outcome moves when a few particles are
pushed again from a start pose and with an action jittered by the sensing and actuation
noise (large for pushes that make the links collide); and a slack for the rest
(docs/bayes.md; coverage measured in docs/notebook). Where an arm pushes, the filter
simulates the arm itself, one chain at a time on every core (`masspush.bayes.arm_scenes`), or
optionally the stiff pusher fitted to it on the batch path (`ARM_SURROGATE`).

The likelihood is raised to a power beta <= 1 (`likelihood_power`; a power posterior),
below 1 where the simulator is known to be a rougher model (three or more links; an arm's
surrogate), chosen for calibrated intervals on tuning episodes.

Degenerate weights: when the effective sample size drops below `ess_fraction` of the
particles, they are resampled (systematic) and rejuvenated with a Liu-West kernel in
log-parameter space. An observation that no particle explains (best particle beyond the
chi-square `unexplained_quantile`) is tempered until the weights keep `min_ess` particles,
with a warning: the filter never collapses silently and never produces NaN.

With `likelihood="learned"` the simulator's Student-t gives way to a density of the
outcome learned from the pusher's simulated episodes (`PushLikelihood`, made by
`masspush.learn.push_density`): it knows the scatter of outcomes that the observed pose does
not determine, and a particle costs a network evaluation instead of a simulation
(`LEARNED_CONFIG`).

`InfoSeekingPolicy` picks each push among candidate actions by the expected reduction of
the posterior variance of the mass distribution, simulated under the current particles.
`masspush.bayes.estimator` runs it all as an estimator of `masspush.evaluate`.
"""

from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass, replace
from statistics import NormalDist
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

import numpy as np

from masspush.bayes.arm_scenes import ArmSimulator
from masspush.config import EnvConfig, check_range
from masspush.sim.batch import ChainBatch
from masspush.sim.chain import ChainParams, wrap_angle
from masspush.sim.pushers import IDEAL_PUSHER, pusher_kind
from masspush.sim.workspace import ReachGovernor

if TYPE_CHECKING:
    from masspush.settings import Setting

FILTER_REVISION = 2
"""Raised when the filter's algorithm changes in a way its configuration does not show, so
that results measured with an earlier one are not taken for this one's (`bayes_table`).
2: the estimate after a push comes from the weighted particles, before resampling."""


class PushLikelihood(Protocol):
    """A learned likelihood of a push's outcome (`masspush.learn.push_density.PushDensity`),
    for `likelihood="learned"`: per particle (masses (m, n), friction (m,)) and the chain's
    link lengths, the log-density of observed rest poses after `action` from `start`, and
    draws of them."""

    def log_prob(
        self, start: np.ndarray, action: np.ndarray, observed: np.ndarray, masses: np.ndarray,
        friction: np.ndarray, lengths: np.ndarray,
    ) -> np.ndarray: ...  # fmt: skip

    def cross_log_prob(
        self, start: np.ndarray, action: np.ndarray, observed: np.ndarray, masses: np.ndarray,
        friction: np.ndarray, lengths: np.ndarray,
    ) -> np.ndarray: ...  # fmt: skip

    def sample(
        self, start: np.ndarray, action: np.ndarray, masses: np.ndarray, friction: np.ndarray,
        lengths: np.ndarray, rng: np.random.Generator,
    ) -> np.ndarray: ...  # fmt: skip

    def digest(self) -> str: ...


class UnexplainedObservationWarning(UserWarning):
    """No particle explains an observation; the update was tempered."""


@dataclass(frozen=True)
class BayesConfig:
    """The particle filter and the information-seeking policy [ours, each]."""

    particles: int = 256
    motion_slack: float | None = None
    """Extra likelihood scale per unit of predicted change of a component; None: 0.05 for
    two links, 0.1 for longer chains, whose outcomes hang on more contacts between links
    (chosen on the tuning episodes, seed 1, for 90 % intervals; docs/notebook)."""
    ess_fraction: float = 0.5
    """Resample when the effective sample size falls below this fraction of particles."""
    shrink: float = 0.9
    """Liu-West kernel: a particle moves to a*theta + (1-a)*mean + N(0, (1-a^2) cov)."""
    move_sweeps: int = 0
    """Resample-move [Gilks & Berzuini 2001]: after resampling, this many Metropolis-Hastings
    sweeps of a Gaussian random walk in log-parameter space, each proposal accepted by its
    likelihood under every push so far (simulated again, each from its observed start),
    instead of the Liu-West jitter, which moves particles without asking the pushes already
    made. 0: Liu-West."""
    move_scale: float = 0.5
    """The random walk's step: this times the resampled particles' covariance's root."""
    unexplained_quantile: float = 0.999
    """An observation is unexplained when even the best particle's chi-square is beyond this
    quantile; its update is then tempered."""
    min_ess: float = 0.1
    """Fraction of particles a tempered update keeps as effective sample size."""
    credible: float = 0.9
    """Probability mass of the reported intervals."""
    candidates: int | None = None
    """Actions the information-seeking policy compares before each push; None: 8 for two
    links, 6 for longer chains, whose pushes cost more to simulate (it keeps a 3-link
    episode within 10 s on two cores; docs/notebook)."""
    lookahead_particles: int = 32
    """Particles simulated per candidate action."""
    max_push: float = 1.0
    """Largest |a1| (push speed / 5 m/s) among the candidates. The filter simulates the
    stiff pusher; where an arm pushes, its model holds only for pushes the arm tracks
    (`ARM_MAX_PUSH`)."""
    nthread: int = 0
    """Threads of the batch path; 0: every core."""
    likelihood_power: float | None = None
    """Exponent beta of the likelihood (a power posterior: prior x likelihood^beta), which
    widens the posterior where the simulator is a misspecified model of the world
    [Gruenwald 2012; Bissiri, Holmes & Walker 2016] and keeps more particles alive. None:
    1 for two links, 0.6 for longer chains; where an arm pushes `ARM_LIKELIHOOD_POWER`
    (through `default_config`). Each was chosen on the tuning episodes (seed 1) for 90 %
    intervals (docs/notebook)."""
    settle_cap: float = 1.0
    """Simulated seconds a particle's chain may settle after a push before its pose is
    taken as the rest pose. The world waits for rest (up to 10 s), but after 1 s of
    settling the filter's chains are within 0.012 rad and m of their rest poses, about the
    observation noise, while a creeping few keep a batch stepping for seconds more
    (docs/bayes.md)."""
    arm_model: str = "arm"
    """Where an arm pushes, what the filter simulates: "arm", the arm itself under its
    controller (`masspush.bayes.arm_scenes`, one chain at a time on every core); "surrogate", the
    stiff pusher fitted to it (`ARM_SURROGATE`) on the batch path, which holds for slow
    pushes only (the filter's first version; docs/bayes.md)."""
    point: str = "median"
    """The point estimate reported after each push. "median": the point of the simplex with
    the least expected absolute error under the posterior (`simplex_median`), the Bayes
    estimate for the paper's metric, which scales with the mean absolute error; "mean": the
    posterior mean, the Bayes estimate for squared error."""
    likelihood: str = "simulator"
    """How a push's outcome is weighed. "simulator": each particle's chain is simulated (the
    arm itself where an arm pushes) and a Student-t put around its rest pose; "learned": a
    mixture density network of the outcome trained on the pusher's simulated episodes
    (`masspush.learn.push_density`, the file `density`), which learns the outcome's scatter
    that the pose does not determine, at a network evaluation per particle instead of a
    simulation (`LEARNED_CONFIG`; docs/bayes.md)."""
    density: str | None = None
    """With likelihood="learned", the push density's model file (`masspush train-density`);
    None: the setting's shipped one (`masspush evaluate` finds it)."""
    reach_weight: float = 0.0
    """Where a stationary robot's speed governor slows pushes near the edge of its reach,
    how much the information-seeking policy also values leaving the chain where the next
    push can be fast: a candidate's score (expected posterior variance) is lowered by this
    times the variance before the push times the expected headroom of the rest poses its
    lookahead outcomes drew, as a fraction of the governor's longest slide
    (`Workspace.headroom`, -1 outside the reach up to 1 at a full slide's room). 0: the
    push that teaches most now, wherever it leaves the chain; a stationary robot's filter
    gets `STATIONARY_REACH` by default (`default_config`) [ours; docs/notebook/
    2026-12-05-headroom.md]."""
    reach_from: int = 0
    """The pushes of an episode chosen for their information alone before `reach_weight`
    counts: the paper's protocol scores the first two pushes, which room bought for later
    runs would cost (2 points at 2 pushes, docs/notebook/2026-12-05-headroom.md), while
    the losses it avoids come over the later runs [ours; docs/notebook/
    2026-12-06-late-reach-weight.md]."""
    friction_range: tuple[float, float] | None = None
    """The table frictions the particles may guess, (low, high); None: the setting's within
    those a learned likelihood was trained on (`friction_prior`). A lab whose table reads
    outside them (`masspush classify --density` prints the reading) may widen them: a
    learned likelihood then extrapolates beyond its training frictions, as the tuned
    density's sorting does (`TuneConfig.sort_range`) [ours; docs/notebook/
    2026-12-07-lab-1.md]."""
    tail_dof: float | None = 4.0
    """Degrees of freedom of a Student-t likelihood per component; None: Gaussian. Heavy
    tails keep the few outcomes the model reproduces badly (an arm's contact is not the
    simulated pusher's; a collision turns a link unpredictably) from deciding the posterior
    alone. 4 is the usual robust choice [Lange, Little & Taylor, JASA 1989]."""

    def __post_init__(self) -> None:
        if self.particles < 8 or self.lookahead_particles < 4 or (self.candidates or 1) < 1:
            raise ValueError("particles >= 8, lookahead_particles >= 4 and candidates >= 1")
        for name in ("ess_fraction", "shrink", "unexplained_quantile", "min_ess", "credible"):
            if not 0 < getattr(self, name) < 1:
                raise ValueError(f"{name} must be in (0, 1), got {getattr(self, name)!r}")
        if self.move_sweeps < 0 or not self.move_scale > 0:
            raise ValueError("move_sweeps must be >= 0 and move_scale > 0")
        if not 0 < self.max_push <= 1:
            raise ValueError(f"max_push must be in (0, 1], got {self.max_push}")
        if not 0 <= self.reach_weight < float("inf"):
            raise ValueError(f"reach_weight must be >= 0 and finite, got {self.reach_weight}")
        if self.reach_from < 0:
            raise ValueError(f"reach_from must be >= 0 pushes, got {self.reach_from}")
        if self.tail_dof is not None and self.tail_dof <= 0:
            raise ValueError(f"tail_dof must be > 0 or None, got {self.tail_dof}")
        if self.likelihood_power is not None and not 0 < self.likelihood_power <= 1:
            raise ValueError(f"likelihood_power must be in (0, 1], got {self.likelihood_power}")
        if not self.settle_cap > 0:
            raise ValueError(f"settle_cap must be > 0 s, got {self.settle_cap!r}")
        if self.point not in ("median", "mean"):
            raise ValueError(f"point must be 'median' or 'mean', got {self.point!r}")
        if self.arm_model not in ("arm", "surrogate"):
            raise ValueError(f"arm_model must be 'arm' or 'surrogate', got {self.arm_model!r}")
        if self.likelihood not in ("simulator", "learned"):
            raise ValueError(
                f"likelihood must be 'simulator' or 'learned', got {self.likelihood!r}"
            )
        if self.motion_slack is not None and self.motion_slack < 0:
            raise ValueError(f"motion_slack must be >= 0, got {self.motion_slack}")
        if self.friction_range is not None:
            # a finite (low, high) pair as every range, and then a friction's own bounds
            check_range("friction_range", self.friction_range)
            lo, hi = self.friction_range
            if not 0 < lo < hi:
                raise ValueError(
                    f"friction_range must be 0 < low < high, got {self.friction_range}"
                )


@dataclass(frozen=True)
class Posterior:
    """The estimate after a push: per link, the point estimate of its share of the mass
    (`BayesConfig.point`), the posterior mean and median, and the central credible
    interval."""

    estimate: np.ndarray
    mean: np.ndarray
    median: np.ndarray
    low: np.ndarray
    high: np.ndarray
    ess: float
    """Effective sample size of the weights when the estimate was taken."""


class ParticleFilter:
    """Particles over (link masses, table friction) for one chain at a time."""

    def __init__(
        self, env_config: EnvConfig, config: BayesConfig | None = None, seed: int = 0,
        density: PushLikelihood | None = None,
    ):  # fmt: skip
        self.env = env_config
        self.config = config or BayesConfig()
        self.physics = replace(env_config.physics, settle_time_cap=self.config.settle_cap)
        self.seed = seed
        self.rng = np.random.default_rng([seed, 31])
        # A floor keeps the likelihood finite for noise-free worlds (the simulator is
        # deterministic, but its rest test stops chains within ~0.3 mm of rest).
        self.obs_sigma = max(env_config.obs_noise, 1e-3)
        self.warnings = 0
        """Observations no particle explained since `reset`."""
        two = self.physics.n_links == 2
        slack = self.config.motion_slack
        self.motion_slack = (0.05 if two else 0.1) if slack is None else slack
        self.candidates = self.config.candidates or (8 if two else 6)
        power = self.config.likelihood_power
        self.likelihood_power = (1.0 if two else 0.6) if power is None else power
        self.arm = self.density = None
        if self.config.likelihood == "learned":
            if density is None:
                raise ValueError(
                    "likelihood=learned needs a push density: density=FILE "
                    "(`masspush train-density`), loaded by `masspush.models.load_estimator`"
                )
            self.density = density
        elif pusher_kind(env_config.pusher).arm:
            self.arm = ArmSimulator(self.physics, env_config.pusher, self.config.nthread)
        self.friction_range = self.config.friction_range or friction_prior(
            self.density, self.physics.friction_range
        )
        """The prior's frictions: the setting's, within those a learned likelihood knows,
        unless `BayesConfig.friction_range` names them."""

    def settings(self) -> dict:
        """The configuration as run: `BayesConfig` with its defaults resolved for this chain,
        the simulated pusher's speed (the arm's surrogate where an arm pushes) and the
        algorithm's `FILTER_REVISION`."""
        config = asdict(self.config)
        # Options off push as before: caches stay valid.
        for name in ("reach_weight", "reach_from", "friction_range"):
            if not config[name]:
                del config[name]
        return {
            **config,
            "revision": FILTER_REVISION,
            "motion_slack": self.motion_slack,
            "candidates": self.candidates,
            "likelihood_power": self.likelihood_power,
            "push_speed_max": self.physics.push_speed_max,
            "simulated_pusher": self.env.pusher,
            **({"density_digest": self.density.digest()} if self.density is not None else {}),
        }

    def close(self) -> None:
        """Stop the arm simulator's worker processes, if any."""
        if self.arm is not None:
            self.arm.close()

    # --- the particles --------------------------------------------------------------------
    def reset(self, lengths: np.ndarray, episode: int | None = None) -> None:
        """A new chain with these (observed) link lengths: particles from the prior. With
        `episode` (the episode's seed) the filter's randomness restarts from it, so that an
        episode's estimate does not depend on which episodes were estimated before it (and
        episodes can be split over workers)."""
        if episode is not None:
            self.rng = np.random.default_rng([self.seed, 31, episode])
        n, m = self.physics.n_links, self.config.particles
        self.lengths = tuple(float(v) for v in lengths)
        self.masses = self.rng.uniform(*self.physics.mass_range, size=(m, n))
        self.friction = self.rng.uniform(*self.friction_range, size=m)
        self.log_w = np.zeros(m)
        self.warnings = 0
        self.past_log_lik = np.zeros(m)
        """Each particle's log-likelihood under the pushes so far, as weighed."""
        self.pushes: list[tuple] = []
        """(start, action, observed, sigma, power) of each push so far, to weigh a moved
        particle against them."""
        self.accepted: list[float] = []
        """Acceptance rate of each Metropolis-Hastings sweep since `reset`."""

    @property
    def weights(self) -> np.ndarray:
        w = np.exp(self.log_w - self.log_w.max())
        return w / w.sum()

    @property
    def ess(self) -> float:
        return _ess(self.weights)

    def shares(self, masses: np.ndarray | None = None) -> np.ndarray:
        masses = self.masses if masses is None else masses
        return masses / masses.sum(axis=1, keepdims=True)

    def posterior(self, w: np.ndarray | None = None) -> Posterior:
        """The estimate and intervals under normalised weights `w` (the particles' own by
        default; `experiments/bayes/pool_learned.py` passes others)."""
        w = self.weights if w is None else w
        shares = self.shares()
        tail = (1 - self.config.credible) / 2
        low, high = (
            np.array([_weighted_quantile(shares[:, j], w, q) for j in range(shares.shape[1])])
            for q in (tail, 1 - tail)
        )
        mean, median = w @ shares, simplex_median(shares, w)
        estimate = median if self.config.point == "median" else mean
        return Posterior(estimate, mean, median, low, high, _ess(w))

    # --- simulation -----------------------------------------------------------------------
    def simulate(
        self, starts: np.ndarray, actions: np.ndarray, masses: np.ndarray, friction: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Rest configurations (m, d) after pushing chains with these masses and frictions
        from the rest poses `starts` (d,) or (m, d) with `actions` (m, 2), and which pushes
        failed (m,)."""
        m = len(masses)
        starts = np.array(np.broadcast_to(np.asarray(starts, float), (m, self.physics.obs_dim)))
        limit = self.physics.joint_limit - 1e-3
        starts[:, 3:] = np.clip(starts[:, 3:], -limit, limit)
        if self.arm is not None:
            configs, failures = self.arm.simulate(
                self.lengths, starts, np.asarray(actions, float), np.asarray(masses, float),
                np.asarray(friction, float),
            )  # fmt: skip
            return configs, np.array([f not in (None, "timeout") for f in failures])
        chains = [
            ChainParams.at_pose(mass, mu, self.lengths, start)
            for mass, mu, start in zip(masses, friction, starts, strict=True)
        ]
        batch = ChainBatch(chains, self.physics, self.config.nthread)
        outcomes = batch.push(np.asarray(actions, float))
        # A chain still creeping at the settle cap is taken where it is (not a failure).
        failed = np.array([o is None or o.failure not in (None, "timeout") for o in outcomes])
        return batch.configs(), failed

    def noise_spread(
        self, start: np.ndarray, actions: np.ndarray, masses: np.ndarray, friction: np.ndarray,
        nominal: np.ndarray, failed: np.ndarray,
    ) -> np.ndarray:  # fmt: skip
        """RMS change of each outcome component when the start pose is off by the sensing
        noise and the action by the actuation noise: how unpredictable a push is for
        reasons other than the unknowns (large for pushes that make links collide)."""
        diff = self.noise_effect(start, actions, masses, friction, nominal, failed)
        return np.sqrt(np.mean(diff**2, axis=0)) if len(diff) else np.full(len(start), np.inf)

    def noise_effect(
        self, start: np.ndarray, actions: np.ndarray, masses: np.ndarray, friction: np.ndarray,
        nominal: np.ndarray, failed: np.ndarray,
    ) -> np.ndarray:  # fmt: skip
        """(k, d) change of the outcomes `nominal` when these chains are pushed again from
        `start` and with `actions` jittered by the sensing and actuation noise; rows where
        either push failed are left out."""
        m = len(masses)
        starts = start[None] + self.rng.normal(0, self.obs_sigma, (m, len(start)))
        noisy = np.clip(actions + self.rng.normal(0, self.env.action_noise, actions.shape), -1, 1)
        perturbed, bad = self.simulate(starts, noisy, masses, friction)
        ok = ~(bad | failed)
        return config_difference(perturbed[ok], nominal[ok])

    # --- the update -----------------------------------------------------------------------
    def update(self, start: np.ndarray, action: np.ndarray, observed: np.ndarray) -> Posterior:
        """Weigh the particles by how well their simulated rest pose after `action` from
        `start` matches the `observed` one; resample and rejuvenate when degenerate."""
        if self.density is not None:
            log_lik = self._learned_log_lik(start, action, observed, self.masses, self.friction)
            self.pushes.append((np.asarray(start, float), np.asarray(action, float),
                                np.asarray(observed, float), None, 1.0))  # fmt: skip
            return self._weigh(log_lik)
        m, k = self.config.particles, self.config.lookahead_particles
        actions = np.repeat(np.asarray(action, float)[None], m, 0)
        predicted, failed = self.simulate(start, actions, self.masses, self.friction)
        spread = self.noise_spread(
            start, actions[:k], self.masses[:k], self.friction[:k], predicted[:k], failed[:k]
        )
        sigma = self._sigma(start, predicted, failed, spread)
        residual = config_difference(observed[None], predicted) / sigma
        chi = np.where(failed, np.inf, np.sum(residual**2, axis=1))
        log_lik = failure_floor(self._log_lik(residual), ~np.isfinite(chi))
        dof = len(observed)
        if chi.min() > chi2_quantile(self.config.unexplained_quantile, dof):
            self.warnings += 1
            warnings.warn(
                f"no particle explains the observation (best chi-square {chi.min():.1f} on "
                f"{dof} components); the update is tempered",
                UnexplainedObservationWarning,
                stacklevel=2,
            )
            log_lik, power = self._temper(log_lik)
        else:
            power = 1.0
        self.pushes.append((np.asarray(start, float), np.asarray(action, float),
                            np.asarray(observed, float), sigma, power))  # fmt: skip
        return self._weigh(log_lik)

    def replay(self, observations: np.ndarray, actions: np.ndarray) -> Posterior | None:
        """`update` with each push of a recorded episode in turn: `observations` its rest
        poses (the first before any push), `actions` its pushes (those without an observed
        outcome are left out). Observations no particle explains are tempered quietly
        (counted in `warnings`). The posterior after the last push; None without one."""
        obs = np.asarray(observations, float)
        posterior = None
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnexplainedObservationWarning)
            for k, action in enumerate(list(actions)[: len(obs) - 1]):
                posterior = self.update(obs[k], np.asarray(action, float), obs[k + 1])
        return posterior

    def _weigh(self, log_lik: np.ndarray) -> Posterior:
        """Multiply the weights by a push's likelihood; the estimate; resample if degenerate."""
        self.past_log_lik = self.past_log_lik + log_lik
        self.log_w = self.log_w + log_lik
        self.log_w -= self.log_w.max()
        # The estimate comes from the weighted particles, before resampling and jitter add
        # their noise to the cloud (the standard SMC practice [Doucet & Johansen 2011]).
        posterior = self.posterior()
        if self.ess < self.config.ess_fraction * self.config.particles:
            self._resample_and_rejuvenate()
        return posterior

    def _sigma(
        self, start: np.ndarray, predicted: np.ndarray, failed: np.ndarray, spread: np.ndarray
    ) -> np.ndarray:
        """Likelihood std per component: the observation's noise, the push's sensitivity to
        the start pose and the action, and a slack growing with the predicted motion (one
        sigma for all particles, so no particle is favoured for predicting less motion)."""
        ok = ~failed
        change = np.abs(config_difference(predicted[ok], start[None])).mean(axis=0) if ok.any() \
            else np.zeros(len(start))  # fmt: skip
        spread = np.where(np.isfinite(spread), spread, 10 * self.obs_sigma)
        slack = self.motion_slack * change
        return np.sqrt(self.obs_sigma**2 + spread**2 + slack**2)

    def _log_lik(self, residual: np.ndarray) -> np.ndarray:
        """Log-likelihood (up to a constant) of standardised residuals (..., d)."""
        nu, beta = self.config.tail_dof, self.likelihood_power
        if nu is None:
            return -0.5 * beta * np.sum(residual**2, axis=-1)
        return -0.5 * beta * (nu + 1) * np.sum(np.log1p(residual**2 / nu), axis=-1)

    def _learned_log_lik(
        self, start: np.ndarray, action: np.ndarray, observed: np.ndarray, masses: np.ndarray,
        friction: np.ndarray,
    ) -> np.ndarray:  # fmt: skip
        """The push density's log-likelihood of a push's observed outcome, per particle,
        raised to the likelihood power."""
        return self.likelihood_power * self.density.log_prob(
            start, action, observed, masses, friction, self.lengths
        )

    def _temper(self, log_lik: np.ndarray) -> tuple[np.ndarray, float]:
        """Scale the log-likelihood down until the updated weights keep `min_ess`; the
        scaled log-likelihood and the scale."""
        target = self.config.min_ess * len(log_lik)
        lo, hi = 0.0, 1.0
        for _ in range(40):
            beta = (lo + hi) / 2
            w = np.exp(self.log_w + beta * log_lik - np.max(self.log_w + beta * log_lik))
            w /= w.sum()
            if _ess(w) >= target:
                lo = beta
            else:
                hi = beta
        return lo * log_lik, lo

    def _resample_and_rejuvenate(self) -> None:
        m, a = self.config.particles, self.config.shrink
        index = _systematic(self.weights, self.rng)
        theta = np.log(np.column_stack([self.masses[index], self.friction[index]]))
        self.past_log_lik = self.past_log_lik[index]
        self.log_w = np.zeros(m)
        cov = np.cov(theta, rowvar=False) + 1e-10 * np.eye(theta.shape[1])
        if self.config.move_sweeps:
            for _ in range(self.config.move_sweeps):
                theta = self._move(theta, cov)
            return
        mean = theta.mean(axis=0)
        theta = a * theta + (1 - a) * mean
        theta += self.rng.multivariate_normal(np.zeros(len(mean)), (1 - a * a) * cov, size=m)
        theta = _reflect(theta, *self._log_box())
        self._set(theta)

    def _log_box(self) -> tuple[np.ndarray, np.ndarray]:
        """The prior's box in log-parameter space: lows, highs."""
        n, (lo, hi), (flo, fhi) = (self.physics.n_links, self.physics.mass_range,
                                   self.friction_range)  # fmt: skip
        return np.log([lo] * n + [flo]), np.log([hi] * n + [fhi])

    def _set(self, theta: np.ndarray) -> None:
        self.masses, self.friction = np.exp(theta[:, :-1]), np.exp(theta[:, -1])

    def _move(self, theta: np.ndarray, cov: np.ndarray) -> np.ndarray:
        """One Metropolis-Hastings sweep over equally weighted particles `theta` (log
        parameters), targeting prior x the likelihood of every push so far as it was
        weighed (its sigma and power). The walk is symmetric (reflection at the box keeps
        it so); the prior, uniform in masses and friction, has density exp(sum theta) in
        log space."""
        m = len(theta)
        step = self.config.move_scale * np.linalg.cholesky(cov)
        proposal = _reflect(theta + self.rng.normal(size=theta.shape) @ step.T, *self._log_box())
        masses, friction = np.exp(proposal[:, :-1]), np.exp(proposal[:, -1])
        log_lik = np.zeros(m)
        for start, action, observed, sigma, power in self.pushes:
            if self.density is not None:
                log_lik += power * self._learned_log_lik(start, action, observed, masses, friction)
                continue
            predicted, failed = self.simulate(start, np.repeat(action[None], m, 0), masses,
                                              friction)  # fmt: skip
            term = power * self._log_lik(config_difference(observed[None], predicted) / sigma)
            log_lik += np.where(failed, -np.inf, term)
        log_ratio = log_lik + proposal.sum(axis=1) - self.past_log_lik - theta.sum(axis=1)
        accept = np.log(self.rng.uniform(size=m)) < log_ratio
        theta = np.where(accept[:, None], proposal, theta)
        self.past_log_lik = np.where(accept, log_lik, self.past_log_lik)
        self.accepted.append(float(accept.mean()))
        self._set(theta)
        return theta

    # --- looking ahead ----------------------------------------------------------------------
    def expected_variance(
        self, start: np.ndarray, actions: np.ndarray, values: np.ndarray | None = None
    ) -> np.ndarray:
        """For each candidate action, the expected posterior variance of the mass
        distribution (summed over links) after pushing with it. Each lookahead particle in
        turn plays the truth, its outcome simulated with sensing and actuation noise, and
        reweighs the others; a push that fails teaches nothing.

        `values` (particles, q), where given, are scored in place of the mass distribution:
        one-hot class labels, for instance, make the score the expected Gini impurity of
        the class posterior (how likely a class drawn from it is wrong)."""
        return self.lookahead(start, actions, values).variance

    def lookahead(
        self, start: np.ndarray, actions: np.ndarray, values: np.ndarray | None = None
    ) -> Lookahead:
        """`expected_variance`'s scores with the variance before the push and, per
        candidate, the rest poses the lookahead particles' outcomes drew."""
        k, c = self.config.lookahead_particles, len(actions)
        index = _systematic(self.weights, self.rng, k)
        masses, friction = np.tile(self.masses[index], (c, 1)), np.tile(self.friction[index], c)
        if values is None:
            shares = self.shares(self.masses[index])
        else:
            values = np.asarray(values, float)
            if values.ndim != 2 or len(values) != len(self.masses):
                raise ValueError(
                    f"values must be (particles, q) = ({len(self.masses)}, q), got {values.shape}"
                )
            shares = values[index]
        prior_var = float(np.sum(shares.var(axis=0)))
        if self.density is not None:
            out, outcomes = self._learned_expected_variance(start, actions, index, shares)
            return Lookahead(out, prior_var, outcomes)
        rows = np.repeat(np.asarray(actions, float), k, axis=0)
        nominal, failed = self.simulate(start, rows, masses, friction)
        starts = start[None] + self.rng.normal(0, self.obs_sigma, (len(rows), len(start)))
        noisy = np.clip(rows + self.rng.normal(0, self.env.action_noise, rows.shape), -1, 1)
        truth, truth_failed = self.simulate(starts, noisy, masses, friction)
        out = np.full(c, prior_var)
        outcomes = np.where(truth_failed[:, None], np.nan, truth).reshape(c, k, -1)
        for j in range(c):
            part = slice(j * k, (j + 1) * k)
            y, bad = nominal[part], failed[part] | truth_failed[part]
            if bad.all():
                continue
            diff = config_difference(truth[part][~bad], y[~bad])
            spread = np.sqrt(np.mean(diff**2, axis=0))
            sigma = self._sigma(start, y, bad, spread)
            seen = truth[part] + self.rng.normal(0, self.obs_sigma, y.shape)
            d = config_difference(seen[:, None], y[None]) / sigma
            log_w = self._log_lik(d)
            log_w[:, failed[part]] = -np.inf
            log_w[bad] = 0.0  # a failed push leaves the weights as they were
            out[j] = _expected_posterior_variance(log_w, shares)
        return Lookahead(out, prior_var, list(outcomes))

    def _learned_expected_variance(
        self, start: np.ndarray, actions: np.ndarray, index: np.ndarray, shares: np.ndarray
    ) -> tuple[np.ndarray, list[np.ndarray]]:
        """`expected_variance` with the push density: each lookahead particle's outcome is
        drawn from the density (the sensing and actuation noise are in it) and every
        lookahead particle is weighed by the density of that outcome."""
        masses, friction = self.masses[index], self.friction[index]
        out, outcomes = np.empty(len(actions)), []
        for j, action in enumerate(np.asarray(actions, float)):
            seen = self.density.sample(start, action, masses, friction, self.lengths, self.rng)
            log_w = self.likelihood_power * self.density.cross_log_prob(
                start, action, seen, masses, friction, self.lengths
            )
            out[j] = _expected_posterior_variance(log_w, shares)
            outcomes.append(seen)
        return out, outcomes


class Lookahead(NamedTuple):
    """What `ParticleFilter.lookahead` expects of each candidate push."""

    variance: np.ndarray
    """(candidates,) the expected posterior variance after it (`expected_variance`)."""
    prior_variance: float
    """The posterior variance before the push."""
    outcomes: list[np.ndarray]
    """Per candidate, the (lookahead particles, d) rest poses its outcomes drew; NaN rows
    where the simulated push failed."""


class InfoSeekingPolicy:
    """Chooses each push to shrink the posterior of the mass distribution the most (with
    `BayesConfig.reach_weight`, from push `reach_from` on, and where the chain lands)."""

    def __init__(
        self, filt: ParticleFilter, seed: int = 0, governor: ReachGovernor | None = None
    ) -> None:
        self.filter, self.seed = filt, seed
        self.governor = governor
        """A stationary robot's speed governor (`masspush.sim.reach_governor`): each
        candidate is compared as the robot would make it, slowed to keep the chain in reach."""
        self.rng = np.random.default_rng([seed, 37])
        self.reachable = None
        """`reachable(action, start, lengths)`, whether the robot can make a push
        (`masspush.sim.arm_reach`): the best candidate it can make is pushed (the best of
        all where it can make none). None: the best, unasked."""

    def reset(self, episode: int) -> None:
        """Restart the candidates' randomness from the episode's seed (`ParticleFilter.reset`)."""
        self.rng = np.random.default_rng([self.seed, 37, episode])

    def landing_room(self, poses: np.ndarray) -> float:
        """The mean over rest poses (m, d) of the chain's headroom in the governor's
        workspace as a fraction of its longest slide, each in [-1, 1]; a failed push (NaN)
        counts 0."""
        ws = self.governor.workspace
        room = ws.headroom(poses, self.filter.lengths, self.governor.physics.joint_gap)
        room = np.clip(room / max(ws.slide_max, 1e-9), -1.0, 1.0)
        return float(np.mean(np.nan_to_num(room, nan=0.0)))

    def act(self, start: np.ndarray) -> np.ndarray:
        n = self.filter.candidates
        candidates = self.rng.uniform(-1, 1, size=(n, 2))
        candidates[:, 0] *= self.filter.config.max_push
        if self.governor is not None:
            lengths = self.filter.lengths
            candidates = np.array([self.governor(a, start, lengths) for a in candidates], float)
        ahead = self.filter.lookahead(start, candidates)
        scores = ahead.variance
        weight = self.filter.config.reach_weight
        if (
            weight > 0
            and self.governor is not None
            and len(self.filter.pushes) >= self.filter.config.reach_from
        ):
            landing = np.array([self.landing_room(poses) for poses in ahead.outcomes])
            scores = scores - weight * ahead.prior_variance * landing
        if self.reachable is not None:
            for i in np.argsort(scores, kind="stable"):
                if self.reachable(candidates[i], start, self.filter.lengths):
                    return candidates[i]
        return candidates[int(np.argmin(scores))]


def friction_prior(density: Any, friction_range: tuple[float, float]) -> tuple[float, float]:
    """The table frictions a filter weighing pushes with `density` may guess: the setting's
    `friction_range` within those the density's training episodes held (`friction_seen`;
    a density trained before it was recorded, or none: the whole range). Where the two do
    not overlap, the density's: it can weigh no other."""
    seen = None if density is None else getattr(density, "meta", {}).get("friction_seen")
    if seen is None:
        return float(friction_range[0]), float(friction_range[1])
    lo, hi = max(friction_range[0], seen[0]), min(friction_range[1], seen[1])
    return (float(lo), float(hi)) if lo <= hi else (float(seen[0]), float(seen[1]))


def config_difference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a - b for configurations, angles wrapped."""
    d = np.asarray(a, float) - np.asarray(b, float)
    d[..., 2:] = wrap_angle(d[..., 2:])
    return d


def chi2_quantile(q: float, dof: int) -> float:
    """The chi-square quantile, Wilson-Hilferty approximation (within 2 % for dof >= 3)."""
    z = NormalDist().inv_cdf(q)
    h = 2.0 / (9.0 * dof)
    return float(dof * (1 - h + z * np.sqrt(h)) ** 3)


def _weighted_quantile(values: np.ndarray, weights: np.ndarray, q: float) -> float:
    order = np.argsort(values)
    cdf = np.cumsum(weights[order])
    cdf /= cdf[-1]
    return float(values[order][min(np.searchsorted(cdf, q), len(values) - 1)])


def simplex_median(shares: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """The distribution x with the least expected L1 distance sum_j E|x_j - s_j| to weighted
    samples s of distributions. Without the constraint sum_j x_j = 1 each x_j would be its
    marginal median; with it, the Lagrange condition puts every x_j at its marginal quantile
    of one common level q (F_j(x_j) = q for all j), q found by bisection. Two links: q = 1/2,
    the medians. Marginal quantiles interpolate between samples, so x moves continuously."""
    order = np.argsort(shares, axis=0)
    values = np.take_along_axis(shares, order, axis=0)
    w = weights[order] / weights.sum()
    levels = np.cumsum(w, axis=0) - w / 2
    n = shares.shape[1]

    def point(q: float) -> np.ndarray:
        return np.array([np.interp(q, levels[:, j], values[:, j]) for j in range(n)])

    lo, hi = 0.0, 1.0
    for _ in range(40):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if point(mid).sum() < 1 else (lo, mid)
    x = point((lo + hi) / 2)
    return x / x.sum()


def failure_floor(log_lik: np.ndarray, failed: np.ndarray) -> np.ndarray:
    """Log-likelihoods with the `failed` particles' set 25 below the lowest of the others.
    A particle whose chain failed where the real one did not is far less likely, but a
    finite penalty keeps the weights defined when every particle failed."""
    ok = ~failed
    return np.where(ok, log_lik, (log_lik[ok].min() if ok.any() else 0) - 25)


def _expected_posterior_variance(log_w: np.ndarray, values: np.ndarray) -> float:
    """The mean over imagined outcomes (rows of `log_w`, (outcomes, particles)) of the
    posterior variance of `values` (particles, q), summed over q."""
    w = np.exp(log_w - log_w.max(axis=1, keepdims=True))
    w /= w.sum(axis=1, keepdims=True)
    mean = w @ values
    return float(np.mean(np.sum(w @ (values**2) - mean**2, axis=1)))


def _ess(w: np.ndarray) -> float:
    """Effective sample size of normalised weights."""
    return float(1.0 / np.sum(w * w))


def _systematic(weights: np.ndarray, rng: np.random.Generator, m: int | None = None) -> np.ndarray:
    m = m or len(weights)
    positions = (rng.uniform() + np.arange(m)) / m
    return np.minimum(np.searchsorted(np.cumsum(weights), positions), len(weights) - 1)


def _reflect(x: np.ndarray, lows: np.ndarray, highs: np.ndarray) -> np.ndarray:
    """Fold values back into [low, high] (a jittered particle stays inside the prior)."""
    span = highs - lows
    span = np.where(span > 0, span, 1.0)
    y = np.mod(x - lows, 2 * span)
    y = np.where(y > span, 2 * span - y, y)
    return np.where(highs > lows, lows + y, lows)


ARM_PARTICLES = (128, 256)
"""Particles where the filter simulates an arm: two links, three or more. With three links and
`kuka-far` (3link-0.1-1's pusher), on the tuning episodes (seed 1, 40) 256 particles erred
17.63 and covered 92 % against 19.82 and 84 % with 128, at 3.8 s an episode against 2.6 on
a 2-core Intel Xeon VM (docs/notebook/2026-12-01-arm-speed.md) [ours]."""

ARM_CONFIG = BayesConfig(particles=ARM_PARTICLES[0], lookahead_particles=16, candidates=4)
"""Where an arm pushes and the filter simulates it: an arm push costs ~11-17 ms of one core
against ~0.3 ms on the batch path, so fewer particles, lookahead particles and candidates
keep an episode within 10 s on two cores (docs/notebook) [ours]."""

ARM_LIKELIHOOD_POWER = (0.8, 0.35)
"""The likelihood power where the filter simulates an arm: two links, three or more. The
arm's contact makes outcomes less predictable than the stiff pusher's; on the tuning
episodes (seed 1, 40 each) 1 covered 82 % with two links and 0.6 covered 81 % with three;
0.6 and 0.35 covered 92 % and 88 %. With two links 0.6 drew heavy-link estimates towards
the middle; 0.8 estimated better on the first 100 episodes of seed 1 (8.14 against 8.85,
coverage 91 % both) and of 300 of seed 0 (10.01 against 11.13, coverage 85 % against
87 %) (docs/notebook, "300 paired episodes in the 2-link cells") [ours]."""

ARM_MAX_PUSH = 0.15
"""With `arm_model="surrogate"`, the information-seeking policy keeps to |a1| <= 0.15
(0.75 m/s). The KR 5 under the paper's control reaches ~2.6 m/s at most (torque limits), so
a faster command is not the push the stiff model simulates; below ~0.5 m/s the arm and the
stiff pusher leave a chain at nearly the same rest pose, at 1.6 m/s already 0.3-0.6 rad
apart in yaw (docs/bayes.md)."""

SURROGATE_LIKELIHOOD_POWER = 0.35
"""With `arm_model="surrogate"`, the surrogate is the filter's model of a push it does not
simulate: the likelihood counts for less. 0.35 gave 90 % coverage on the tuning episodes
of 2link-0.1-1 (seed 1; 77 % with 1; the error unchanged, docs/notebook)."""

SURROGATE_CONFIG = BayesConfig(
    arm_model="surrogate", max_push=ARM_MAX_PUSH, likelihood_power=SURROGATE_LIKELIHOOD_POWER
)
"""The filter's first version where an arm pushes: the stiff surrogate on the batch path."""

ARM_SURROGATE: dict[str, dict[str, float]] = {"kuka": {"push_speed_max": 3.0}}
"""With `arm_model="surrogate"`, the filter simulates a stiff pusher that reproduces the
arm's pushes best: the KR 5 moves a chain as a stiff pusher at 0.6 of the commanded speed
would (its operational-space controller lags the commanded velocity during the short
contact). Fitted by `experiments/bayes/fit_arm_surrogate.py` over speed scale, hold and ramp time
(docs/bayes.md)."""


LEARNED_CONFIG = BayesConfig(
    likelihood="learned", particles=4096, candidates=48, lookahead_particles=128, move_sweeps=2
)
"""With the learned likelihood a particle costs a network evaluation (~4 us), so thousands
fit where the arm's simulation allowed 128-256, and resample-move (exact, each move weighed
against every push so far) replaces the Liu-West jitter, since re-weighing is cheap. The
pushes gain most from the spare time: on the tuning episodes (seed 1) 48 candidates on 128
lookahead particles erred 5.05 (2 links, 300 episodes) and 10.70 (3 links, 100) against
6.05 and 13.09 with 16 on 64, at 0.5-0.8 s an episode; 96 candidates 5.00, 16384
particles 5.80 (docs/notebook/2026-12-04-learned-likelihood.md) [ours]."""

LEARNED_LIKELIHOOD_POWER = (0.7, 0.7)
"""The learned likelihood's power: two links, three or more. At power 1 the densities are
overconfident: on the tuning episodes (seed 1) their 90 % intervals covered 83 % (two links,
300 episodes) and 80 % (three, 40); at 0.7, 92 % and 88 %, with the least error of the
powers tried (1, 0.7, 0.5; two links 6.05 against 6.26 and 6.14, three 11.42 against 11.82
and 12.23) (docs/notebook/2026-12-04-learned-likelihood.md) [ours]."""


STATIONARY_REACH = {"reach_weight": 1.0, "reach_from": 2}
"""Where the robot stands still (its pusher has a workspace), the information-seeking
policy from the third push of an episode on also values leaving the chain where the next
push can be fast. The first two, which the paper's protocol scores, are chosen as before.
Over 32 pushes (16 runs of 2), on the same 750 chains of two simulated labs, the chains
lost fell from 29 to 9 and the lab-tuned posterior sorted 88.8 % against 88.3 % (McNemar
p = 0.79) (docs/notebook/2026-12-06-late-reach-weight.md) [ours]."""


def default_config(
    setting: Setting, pusher: str | None = None, likelihood: str = "simulator"
) -> BayesConfig:
    """The filter's configuration for chains of `setting` pushed by `pusher` (the
    setting's by default): with the learned likelihood `LEARNED_CONFIG` at
    `LEARNED_LIKELIHOOD_POWER`; else `ARM_CONFIG` with `ARM_LIKELIHOOD_POWER` and
    `ARM_PARTICLES` where an arm pushes, else `BayesConfig()`; `STATIONARY_REACH` where
    the robot stands still."""
    kind = pusher_kind(pusher or setting.pusher)
    reach = STATIONARY_REACH if kind.workspace is not None else {}
    if likelihood == "learned":
        power = LEARNED_LIKELIHOOD_POWER[0 if setting.n_links == 2 else 1]
        return replace(LEARNED_CONFIG, likelihood_power=power, **reach)
    if not kind.arm:
        return BayesConfig()
    longer = 0 if setting.n_links == 2 else 1
    return replace(
        ARM_CONFIG,
        likelihood_power=ARM_LIKELIHOOD_POWER[longer],
        particles=ARM_PARTICLES[longer],
        **reach,
    )


def filter_for(
    setting: Setting,
    pusher: str | None = None,
    config: BayesConfig | None = None,
    seed: int = 0,
    density: PushLikelihood | None = None,
) -> ParticleFilter:
    """The particle filter for chains of `setting` pushed by `pusher` (the setting's by
    default), configured by `config` (`default_config`'s by default). Where an arm pushes
    it simulates the arm, or with `arm_model="surrogate"` the stiff pusher fitted to it."""
    pusher = pusher or setting.pusher
    config = config or default_config(setting, pusher)
    physics = setting.physics()
    if pusher_kind(pusher).arm and config.arm_model == "surrogate":
        physics = replace(physics, **ARM_SURROGATE.get(pusher, {}))
        pusher = IDEAL_PUSHER
    return ParticleFilter(EnvConfig(physics=physics, pusher=pusher), config, seed, density)


def bayes_overrides(pairs: list[str] | tuple[str, ...] | None) -> dict | None:
    """KEY=VALUE pairs (`masspush evaluate --bayes`) into BayesConfig fields: numbers as
    numbers, "none" as None, text for the text fields (arm_model)."""
    from dataclasses import fields

    if not pairs:
        return None
    kinds = {f.name: str(f.type) for f in fields(BayesConfig)}
    options: dict = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        if not sep or key not in kinds:
            raise ValueError(f"--bayes wants KEY=VALUE, KEY one of {sorted(kinds)}; got {pair!r}")
        if kinds[key].startswith("tuple"):  # a range, LOW,HIGH
            options[key] = _range_override(key, text)
            continue
        if kinds[key].startswith("str"):  # text, or text or none (density)
            optional = "None" in kinds[key]
            options[key] = None if optional and text.lower() == "none" else text
            continue
        try:
            value = None if text.lower() == "none" else float(text)
        except ValueError:
            raise ValueError(f"--bayes {key} wants a number or none, got {text!r}") from None
        integer = kinds[key].startswith("int") and value is not None
        options[key] = int(value) if integer else value
    return options


def _range_override(key: str, text: str) -> tuple[float, float] | None:
    """`--bayes KEY=LOW,HIGH` (or none) as a pair of numbers."""
    if text.lower() == "none":
        return None
    try:
        low, high = (float(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--bayes {key} wants LOW,HIGH or none, got {text!r}") from None
    return low, high
