import warnings
from dataclasses import replace

import numpy as np
import pytest

from masspush.bayes.estimator import run_bayes_episode
from masspush.bayes.filter import (
    ARM_CONFIG,
    ARM_LIKELIHOOD_POWER,
    ARM_MAX_PUSH,
    ARM_PARTICLES,
    ARM_SURROGATE,
    FILTER_REVISION,
    LEARNED_CONFIG,
    LEARNED_LIKELIHOOD_POWER,
    SURROGATE_CONFIG,
    SURROGATE_LIKELIHOOD_POWER,
    BayesConfig,
    InfoSeekingPolicy,
    Lookahead,
    ParticleFilter,
    UnexplainedObservationWarning,
    _reflect,
    bayes_overrides,
    chi2_quantile,
    config_difference,
    default_config,
    filter_for,
    friction_prior,
    simplex_median,
)
from masspush.config import EnvConfig
from masspush.env import ChainEnv
from masspush.learn.push_density import rest_poses
from masspush.settings import get_setting

SETTING = get_setting("2link-1-10")  # stiff pusher: the filter's own
SMALL = BayesConfig(particles=48, lookahead_particles=8, candidates=3)


def env_config(noise: float = 0.01) -> EnvConfig:
    return EnvConfig(physics=SETTING.physics(), pusher="stiff", obs_noise=noise, action_noise=noise)


def small_filter() -> ParticleFilter:
    """The same small filter each time (seed 3), its prior drawn for 0.12 m links."""
    filt = ParticleFilter(env_config(), SMALL, seed=3)
    filt.reset(np.array([0.12, 0.12]), episode=0)
    return filt


class FixedPushes:
    def __init__(self, actions):
        self.actions = list(actions)

    def act(self, start):
        return np.array(self.actions.pop(0))


@pytest.mark.slow
def test_without_noise_the_posterior_concentrates_on_the_truth():
    cfg = EnvConfig(physics=SETTING.physics(), pusher="stiff", pushes=3, obs_noise=0.0,
                    action_noise=0.0)  # fmt: skip
    env = ChainEnv.from_config(cfg)
    filt = ParticleFilter(cfg, BayesConfig(particles=96), seed=1)
    # Pushes that do not make the links collide: those are chaotic (a 0.1 mm change of the
    # start pose turns the rest pose by 0.05 rad), which no estimator can undo.
    pushes = FixedPushes([(0.5, 0.8), (-0.5, -0.8), (0.5, 0.8)])
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnexplainedObservationWarning)
        result = run_bayes_episode(env, filt, pushes, seed=0, pushes=3)
    assert result["failure"] is None and len(result["posteriors"]) == 3
    first, last = result["posteriors"][0], result["posteriors"][-1]
    assert np.abs(last.mean - result["truth"]).max() < 0.02, (last.mean, result["truth"])
    width, first_width = last.high - last.low, first.high - first.low
    assert np.all(width < 0.1) and np.all(width < first_width / 3)
    assert np.all((last.low <= result["truth"]) & (result["truth"] <= last.high))


def test_an_observation_no_particle_explains_warns_and_leaves_no_nan():
    filt = ParticleFilter(env_config(), SMALL, seed=0)
    filt.reset(np.array([0.12, 0.12]))
    start = np.array([0.0, 0.0, 0.3, 0.2])
    impossible = start + np.array([0.8, -0.8, 2.0, 1.0])  # far off any push's reach
    with pytest.warns(UnexplainedObservationWarning, match="tempered"):
        posterior = filt.update(start, np.array([0.2, 0.5]), impossible)
    assert np.all(np.isfinite(posterior.mean)) and np.all(np.isfinite(filt.log_w))
    assert posterior.mean.sum() == pytest.approx(1.0)
    assert posterior.ess >= 0.1 * SMALL.particles - 1e-6
    assert filt.warnings == 1


def test_resampling_rejuvenates_inside_the_prior():
    filt = ParticleFilter(env_config(), SMALL, seed=0)
    filt.reset(np.array([0.12, 0.12]))
    filt.log_w = np.full(SMALL.particles, -50.0)
    filt.log_w[:3] = 0.0  # three particles hold all the weight
    filt._resample_and_rejuvenate()
    assert len(np.unique(filt.masses[:, 0])) > 10  # rejuvenated, not 3 copies
    lo, hi = SETTING.mass_range
    assert filt.masses.min() >= lo - 1e-9 and filt.masses.max() <= hi + 1e-9
    assert filt.ess == pytest.approx(SMALL.particles)


def test_reflect_folds_values_back_into_range():
    x = np.array([[-0.5, 1.2, 0.3]])
    y = _reflect(x, np.zeros(3), np.ones(3))
    np.testing.assert_allclose(y, [[0.5, 0.8, 0.3]])


def test_chi2_quantile_approximation():
    # Reference values of the chi-square distribution.
    assert chi2_quantile(0.999, 4) == pytest.approx(18.467, rel=0.02)
    assert chi2_quantile(0.95, 5) == pytest.approx(11.070, rel=0.02)


@pytest.mark.slow
def test_the_information_seeking_policy_prefers_an_informative_push():
    # A push that misses the chain teaches nothing; a push of a link teaches something.
    filt = ParticleFilter(env_config(), BayesConfig(particles=48, lookahead_particles=16),
                          seed=0)  # fmt: skip
    filt.reset(np.array([0.12, 0.12]))
    start = np.array([0.0, 0.0, 0.0, 0.0])
    scores = filt.expected_variance(start, np.array([[0.02, 0.0], [0.8, 0.6]]))
    assert scores[1] < scores[0]
    assert InfoSeekingPolicy(filt).act(start).shape == (2,)


def test_expected_variance_scores_given_values_in_place_of_the_mass_distribution():
    # The same lookahead (same seed) scored on the particles' own shares gives the default's
    # numbers; one-hot classes score the class posterior's impurity, at most 1 - 1/classes.
    start, pushes = np.zeros(4), np.array([[0.02, 0.0], [0.8, 0.6]])
    default = small_filter().expected_variance(start, pushes)
    filt = small_filter()
    same = filt.expected_variance(start, pushes, values=filt.shares(filt.masses))
    np.testing.assert_allclose(same, default, rtol=1e-12)
    filt = small_filter()
    onehot = np.eye(2)[(filt.shares(filt.masses)[:, 0] > 0.5).astype(int)]
    gini = filt.expected_variance(start, pushes, values=onehot)
    assert np.all((gini >= 0) & (gini <= 0.5 + 1e-12))
    assert not np.allclose(gini, default)  # the same lookahead, other values
    with pytest.raises(ValueError, match="values must be"):
        filt.expected_variance(start, pushes, values=np.ones((5, 2)))


def test_heavy_tails_let_one_bad_component_count_less():
    gauss = ParticleFilter(env_config(), BayesConfig(particles=48, tail_dof=None), seed=0)
    student = ParticleFilter(env_config(), BayesConfig(particles=48, tail_dof=4), seed=0)
    residual = np.array([[0.0, 0.0, 0.0, 0.0], [8.0, 0.0, 0.0, 0.0], [3.0, 3.0, 3.0, 3.0]])
    g, t = gauss._log_lik(residual), student._log_lik(residual)
    assert g[0] == t[0] == 0.0
    assert g[1] - g[0] == pytest.approx(-32.0)
    # Under the Gaussian one 8-sigma miss is worse than four 3-sigma ones; with heavy tails
    # it is the other way round: a single bad component no longer decides.
    assert g[1] < g[2] and t[1] > t[2]


def test_where_an_arm_pushes_the_filter_simulates_the_arm_or_its_surrogate():
    setting = get_setting("2link-0.1-1")  # the KR 5 pushes
    filt = filter_for(setting)
    assert filt.env.pusher == "kuka" and filt.arm is not None
    assert filt.config == replace(ARM_CONFIG, likelihood_power=ARM_LIKELIHOOD_POWER[0])
    longer = filter_for(get_setting("3link-0.1-1"))
    assert longer.likelihood_power == ARM_LIKELIHOOD_POWER[1]
    assert longer.config.particles == ARM_PARTICLES[1] != filt.config.particles
    assert filt.settings()["simulated_pusher"] == "kuka"
    surrogate = filter_for(setting, config=SURROGATE_CONFIG)
    assert surrogate.physics.push_speed_max == ARM_SURROGATE["kuka"]["push_speed_max"]
    assert surrogate.config.max_push == ARM_MAX_PUSH and surrogate.env.pusher == "stiff"
    assert surrogate.likelihood_power == SURROGATE_LIKELIHOOD_POWER < 1
    assert surrogate.arm is None
    stiff = filter_for(setting, pusher="stiff")
    assert stiff.physics == replace(setting.physics(), settle_time_cap=stiff.config.settle_cap)
    with pytest.raises(ValueError, match="arm_model"):
        BayesConfig(arm_model="puppet")


@pytest.mark.slow
def test_the_arm_filter_weighs_the_true_chain_highest():
    from masspush.bayes.arm_scenes import ArmScene

    setting = get_setting("2link-0.1-1")
    config = BayesConfig(particles=8, lookahead_particles=4, nthread=1)
    filt = filter_for(setting, config=config)
    lengths = (0.12, 0.14)
    filt.reset(np.array(lengths))
    truth = np.array([0.3, 0.9])
    filt.masses[0], filt.friction[0] = truth, 0.7
    scene = ArmScene(filt.physics, "kuka", lengths)
    start, action = np.array([0.0, 0.0, 0.3, 0.4]), np.array([0.5, 0.6])
    observed, failure, _ = scene.push(start, action, truth, 0.7)
    assert failure is None
    posterior = filt.update(start, action, observed)
    assert np.argmax(filt.weights) == 0
    assert np.isfinite(posterior.mean).all() and posterior.ess >= 1


def test_random_pushes_keep_to_the_filter_s_push_range():
    cfg = BayesConfig(particles=16, lookahead_particles=4, max_push=0.1)
    env = ChainEnv.from_config(env_config())
    result = run_bayes_episode(env, ParticleFilter(env_config(), cfg), None, seed=3, pushes=2)
    actions = np.array(result["actions"])
    assert len(actions) == 2 and np.all(np.abs(actions[:, 0]) <= 0.1)
    assert np.abs(actions[:, 1]).max() > 0.1  # the contact point still spans the links


class SlowGovernor:
    """A stationary robot's governor in miniature: every push slowed to at most 0.05."""

    def __init__(self):
        self.calls = []

    def __call__(self, action, config, lengths):
        self.calls.append((np.array(action), np.array(config), np.array(lengths)))
        return np.array([np.clip(action[0], -0.05, 0.05), action[1]])


def test_a_stationary_robot_s_pushes_go_through_its_governor():
    env = ChainEnv.from_config(env_config())
    governor = SlowGovernor()
    cfg = BayesConfig(particles=16, lookahead_particles=4, candidates=3)
    result = run_bayes_episode(env, ParticleFilter(env_config(), cfg), None, seed=3, pushes=2,
                               governor=governor)  # fmt: skip
    actions = np.array(result["actions"])
    assert len(governor.calls) == 2 and np.all(np.abs(actions[:, 0]) <= 0.05)
    # The governor sees the pose the push starts from and the chain's observed lengths.
    assert governor.calls[0][1].shape == (SETTING.physics().obs_dim,)
    assert governor.calls[0][2].shape == (2,)

    filt = ParticleFilter(env_config(), cfg, seed=0)
    filt.reset(np.array([0.12, 0.12]), episode=0)
    governor = SlowGovernor()
    action = InfoSeekingPolicy(filt, 0, governor).act(np.zeros(SETTING.physics().obs_dim))
    assert len(governor.calls) == 3 and abs(action[0]) <= 0.05  # every candidate governed


def test_the_best_push_the_robot_can_make_is_chosen():
    def seeking(reachable=None) -> InfoSeekingPolicy:  # the same filter and draws each time
        cfg = BayesConfig(particles=16, lookahead_particles=4, candidates=4)
        filt = ParticleFilter(env_config(), cfg, seed=0)
        filt.reset(np.array([0.12, 0.12]), episode=0)
        policy = InfoSeekingPolicy(filt, 0)
        policy.reachable = reachable
        return policy

    start = np.zeros(SETTING.physics().obs_dim)
    best = seeking().act(start)
    asked = []

    def not_the_best(action, pose, lengths):
        asked.append(action)
        return not np.array_equal(action, best)

    second = seeking(not_the_best).act(start)
    # the best is asked first and refused, the next best pushed
    assert len(asked) == 2 and np.array_equal(asked[0], best)
    assert not np.array_equal(second, best) and np.array_equal(second, asked[1])
    never = seeking(lambda action, pose, lengths: False).act(start)
    assert np.array_equal(never, best)  # none it can make: the best, as before


def test_the_lookahead_keeps_where_each_candidate_s_outcomes_left_the_chain():
    start, pushes = np.zeros(4), np.array([[0.02, 0.0], [0.8, 0.6]])
    ahead = small_filter().lookahead(start, pushes)
    np.testing.assert_allclose(ahead.variance, small_filter().expected_variance(start, pushes))
    assert len(ahead.outcomes) == 2 and ahead.outcomes[0].shape == (SMALL.lookahead_particles, 4)
    assert ahead.prior_variance >= ahead.variance.max() - 1e-12
    # a push that misses leaves the chain about where it was; a hard one carries it away
    moved = [np.nanmean(np.hypot(o[:, 0], o[:, 1])) for o in ahead.outcomes]
    assert moved[0] < 0.05 < moved[1]


def test_a_reach_weight_prefers_pushes_that_leave_the_chain_with_room():
    """Two candidates that teach alike, one landing near the far edge of the stationary
    UR10's reach, one in its middle: without a reach weight the (slightly) better teacher
    is pushed, with one the push that leaves room."""
    from masspush.sim.pushers import reach_governor

    real = reach_governor("ur10-stationary", get_setting("real-ur10").physics())
    middle, edge = np.zeros(4), np.array([0.0, 0.25, 0.0, 0.0])  # 0.7 and 0.95 m out

    class Unslowed:  # the workspace's governor, without slowing the candidates
        workspace, physics = real.workspace, real.physics

        def __call__(self, action, config, lengths):
            return np.asarray(action)

    def chosen(weight: float, reach_from: int = 0, weighed: int = 0):
        config = replace(SMALL, candidates=2, reach_weight=weight, reach_from=reach_from)
        filt = ParticleFilter(env_config(), config)
        filt.reset(np.array([0.12, 0.12]), episode=0)
        filt.pushes.extend([None] * weighed)  # pushes already weighed this episode
        asked = []

        def lookahead(start, actions, values=None):
            asked.append(actions)
            outcomes = [np.tile(edge, (4, 1)), np.tile(middle, (4, 1))]
            return Lookahead(np.array([0.010, 0.011]), 0.02, outcomes)

        filt.lookahead = lookahead
        policy = InfoSeekingPolicy(filt, 0, Unslowed())
        return policy.act(middle), asked[0]

    assert real.workspace.headroom(edge, [0.12, 0.12], 0.005) < 0.1
    assert real.workspace.headroom(middle, [0.12, 0.12], 0.005) > 0.2
    action, candidates = chosen(0.0)
    assert np.array_equal(action, candidates[0])
    action, candidates = chosen(0.5)
    assert np.array_equal(action, candidates[1])
    # from the third push on: the first two for their information alone
    action, candidates = chosen(0.5, reach_from=2, weighed=1)
    assert np.array_equal(action, candidates[0])
    action, candidates = chosen(0.5, reach_from=2, weighed=2)
    assert np.array_equal(action, candidates[1])


def test_a_stationary_robot_weighs_the_reach_from_the_third_push_by_default():
    from masspush.models import load_estimator

    real = get_setting("real-ur10")
    for likelihood in ("learned", "simulator"):
        config = default_config(real, likelihood=likelihood)
        assert (config.reach_weight, config.reach_from) == (1.0, 2)
    # a robot whose base follows the chain has no reach to keep
    for name in ("2link-0.1-1", "2link-1-10"):
        assert default_config(get_setting(name)).reach_weight == 0
    assert default_config(real, pusher="ur10").reach_weight == 0
    off = load_estimator("bayes", real, bayes={"reach_weight": 0.0}, progress=False)
    assert off.config.reach_weight == 0  # a lab may turn it off (--bayes reach_weight=0)


def test_a_chain_still_creeping_at_the_settle_cap_is_taken_where_it_is():
    short = ParticleFilter(env_config(), BayesConfig(particles=8, settle_cap=0.02), seed=0)
    full = ParticleFilter(env_config(), BayesConfig(particles=8, settle_cap=10.0), seed=0)
    assert short.physics.settle_time_cap == 0.02 and full.physics.settle_time_cap == 10.0
    obs, _ = ChainEnv.from_config(env_config(0.0)).reset(seed=0)
    d = SETTING.physics().obs_dim
    for filt in (short, full):
        filt.reset(obs[d:])
    start = obs[:d].astype(float)
    actions = np.tile([[0.5, 0.5]], (8, 1))  # 2.5 m/s: the chain slides on for > 0.1 s
    masses, friction = full.masses, full.friction
    cut, cut_failed = short.simulate(start, actions, masses, friction)
    rest, rest_failed = full.simulate(start, actions, masses, friction)
    assert not cut_failed.any() and not rest_failed.any()
    assert np.abs(config_difference(cut, rest)).max() > 0.01  # stopped mid-slide, not failed


def test_a_power_below_one_flattens_the_likelihood():
    residual = np.array([[0.5, 1.0], [2.0, 3.0]])
    full = ParticleFilter(env_config(), BayesConfig(particles=8, likelihood_power=1.0))
    half = ParticleFilter(env_config(), BayesConfig(particles=8, likelihood_power=0.5))
    np.testing.assert_allclose(half._log_lik(residual), 0.5 * full._log_lik(residual))


def test_bad_configs_are_refused():
    with pytest.raises(ValueError, match="particles"):
        BayesConfig(particles=2)
    with pytest.raises(ValueError, match="credible"):
        BayesConfig(credible=1.5)
    with pytest.raises(ValueError, match="tail_dof"):
        BayesConfig(tail_dof=0)
    with pytest.raises(ValueError, match="likelihood_power"):
        BayesConfig(likelihood_power=1.5)
    with pytest.raises(ValueError, match="settle_cap"):
        BayesConfig(settle_cap=0)
    # off, it is left out of the settings a cached measurement is compared with
    assert "reach_weight" not in ParticleFilter(env_config(), SMALL).settings()
    weighted = ParticleFilter(env_config(), replace(SMALL, reach_weight=0.5)).settings()
    assert weighted["reach_weight"] == 0.5
    for weight in (-0.1, float("inf"), float("nan")):
        with pytest.raises(ValueError, match="reach_weight"):
            BayesConfig(reach_weight=weight)
    assert "reach_from" not in ParticleFilter(env_config(), SMALL).settings()
    assert ParticleFilter(env_config(), replace(SMALL, reach_from=2)).settings()["reach_from"] == 2
    with pytest.raises(ValueError, match="reach_from"):
        BayesConfig(reach_from=-1)


def test_longer_chains_get_a_wider_likelihood_and_fewer_candidates_by_default():
    seen, slack, power = {}, {}, {}
    for links in (2, 3):
        cfg = EnvConfig(physics=get_setting(f"{links}link-1-10").physics(), pusher="stiff")
        filt = ParticleFilter(cfg, BayesConfig(particles=16, lookahead_particles=4))
        slack[links] = filt.motion_slack
        power[links] = filt.likelihood_power

        def record(start, actions, values=None, n=links):
            seen[n] = len(actions)
            return Lookahead(np.zeros(len(actions)), 0.0, [np.zeros((4, 4))] * len(actions))

        filt.lookahead = record
        InfoSeekingPolicy(filt).act(np.zeros(cfg.physics.obs_dim))
    assert seen == {2: 8, 3: 6} and slack == {2: 0.05, 3: 0.1} and power == {2: 1.0, 3: 0.6}


def test_the_simplex_median_has_the_least_expected_absolute_error():
    rng = np.random.default_rng(0)
    shares, w = rng.dirichlet([1.0, 2.0, 3.0], size=400), rng.uniform(size=400)
    x = simplex_median(shares, w)
    assert x.sum() == pytest.approx(1.0) and np.all(x > 0)

    def loss(p):
        return float(w @ np.abs(shares - p).sum(axis=1) / w.sum())

    for _ in range(200):  # no nearby distribution does better
        y = np.abs(x + rng.normal(0.0, 0.02, 3))
        assert loss(x) <= loss(y / y.sum()) + 1e-9
    assert loss(x) < loss(w @ shares / w.sum())  # and the mean does worse
    # Two links: the weighted median of each share.
    two = rng.dirichlet([1.0, 4.0], size=301)
    np.testing.assert_allclose(simplex_median(two, np.ones(301)), np.median(two, axis=0))


def test_the_reported_point_is_the_configured_one():
    for point in ("median", "mean"):
        filt = ParticleFilter(env_config(), BayesConfig(particles=64, point=point), seed=0)
        filt.reset(np.array([0.12, 0.14]))
        filt.log_w = np.random.default_rng(1).normal(0.0, 2.0, 64)
        post = filt.posterior()
        np.testing.assert_array_equal(post.estimate, getattr(post, point))
        assert not np.allclose(post.mean, post.median)
    with pytest.raises(ValueError, match="point"):
        BayesConfig(point="mode")


def test_the_estimate_is_taken_before_resampling(monkeypatch):
    filt = ParticleFilter(env_config(), SMALL, seed=0)
    filt.reset(np.array([0.12, 0.12]))
    before = []
    resample = filt._resample_and_rejuvenate

    def spy():
        before.append(filt.posterior())
        resample()

    monkeypatch.setattr(filt, "_resample_and_rejuvenate", spy)
    start = np.array([0.0, 0.0, 0.3, 0.2])
    predicted, _ = filt.simulate(start, np.array([[0.3, 0.5]]), np.array([[1.0, 6.0]]),
                                 np.array([0.8]))  # fmt: skip
    posterior = filt.update(start, np.array([0.3, 0.5]), predicted[0])
    assert before, "one push from the prior should make the weights degenerate"
    np.testing.assert_array_equal(posterior.estimate, before[0].estimate)
    np.testing.assert_array_equal(posterior.low, before[0].low)
    # The resampled cloud's own estimate differs: the jitter moved the particles.
    assert not np.allclose(filt.posterior().estimate, posterior.estimate)
    assert filt.settings()["revision"] == FILTER_REVISION


def test_the_posterior_under_other_weights_is_theirs():
    filt = ParticleFilter(env_config(), BayesConfig(particles=64), seed=0)
    filt.reset(np.array([0.12, 0.14]))
    np.testing.assert_array_equal(filt.posterior(filt.weights).estimate, filt.posterior().estimate)
    one = np.zeros(64)
    one[5] = 1.0
    post = filt.posterior(one)
    np.testing.assert_allclose(post.estimate, filt.shares()[5])
    np.testing.assert_allclose([post.low, post.high], [filt.shares()[5]] * 2)
    assert post.ess == pytest.approx(1.0)


def pushes_log_lik(filt: ParticleFilter) -> np.ndarray:
    """Each particle's log-likelihood under the filter's pushes so far, simulated afresh."""
    total = np.zeros(len(filt.masses))
    for start, action, observed, sigma, power in filt.pushes:
        actions = np.repeat(action[None], len(filt.masses), 0)
        predicted, failed = filt.simulate(start, actions, filt.masses, filt.friction)
        term = power * filt._log_lik(config_difference(observed[None], predicted) / sigma)
        total += np.where(failed, -np.inf, term)
    return total


@pytest.mark.slow
def test_resample_move_keeps_each_particle_s_likelihood_of_the_pushes_made():
    filt = ParticleFilter(env_config(), replace(SMALL, move_sweeps=2), seed=0)
    filt.reset(np.array([0.12, 0.12]))
    seen = np.array([0.0, 0.0, 0.3, 0.2])
    truth = (np.array([[1.0, 6.0]]), np.array([0.8]))
    for action in ([0.3, 0.5], [-0.4, -0.6]):
        predicted, _ = filt.simulate(seen, np.array([action]), *truth)
        filt.update(seen, np.array(action), predicted[0])
        seen = predicted[0]
    assert filt.accepted and all(0 <= a <= 1 for a in filt.accepted)
    assert max(filt.accepted) > 0, "the walk never moved a particle"
    np.testing.assert_allclose(filt.past_log_lik, pushes_log_lik(filt), atol=1e-6)


@pytest.mark.slow
def test_resample_move_stays_in_the_prior_where_the_pushes_made_are_likely():
    likely = {}
    for sweeps in (0, 3):
        filt = ParticleFilter(env_config(), replace(SMALL, particles=96, move_sweeps=sweeps),
                              seed=2)  # fmt: skip
        filt.reset(np.array([0.12, 0.12]))
        start = np.array([0.0, 0.0, 0.3, 0.2])
        predicted, _ = filt.simulate(start, np.array([[0.5, 0.8]]), np.array([[1.0, 6.0]]),
                                     np.array([0.8]))  # fmt: skip
        filt.update(start, np.array([0.5, 0.8]), predicted[0])
        filt._resample_and_rejuvenate()
        low, high = filt.physics.mass_range
        assert np.all((filt.masses >= low) & (filt.masses <= high))
        likely[sweeps] = np.median(pushes_log_lik(filt))
    # The jitter moves particles without asking the push; the walk's moves must answer it.
    assert likely[3] > likely[0], likely


def test_bayes_overrides_become_typed_filter_fields():
    assert bayes_overrides(None) is None
    got = bayes_overrides(["particles=512", "likelihood_power=0.6", "tail_dof=none"])
    assert got == {"particles": 512, "likelihood_power": 0.6, "tail_dof": None}
    assert isinstance(got["particles"], int)
    with pytest.raises(ValueError, match="KEY one of"):
        bayes_overrides(["particle=5"])
    with pytest.raises(ValueError, match="a number"):
        bayes_overrides(["particles=many"])
    assert bayes_overrides(["arm_model=surrogate"]) == {"arm_model": "surrogate"}


def test_replaying_a_recorded_episode_is_its_updates_in_turn():
    start = np.array([0.0, 0.0, 0.3, 0.2])
    observations = start + np.array([[0, 0, 0, 0], [0.05, 0.02, 0.1, 0.0], [0.8, -0.8, 2.0, 1.0]])
    actions = [(0.2, 0.5), (-0.3, 0.6), (0.4, 0.4)]  # the last one's outcome unseen
    filters = [ParticleFilter(env_config(), SMALL, seed=0) for _ in range(2)]
    for filt in filters:
        filt.reset(np.array([0.12, 0.12]), episode=3)
    with pytest.warns(UnexplainedObservationWarning):
        by_hand = [filters[0].update(observations[k], np.array(actions[k]), observations[k + 1])
                   for k in range(2)][-1]  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnexplainedObservationWarning)
        replayed = filters[1].replay(observations, actions)
    np.testing.assert_array_equal(replayed.mean, by_hand.mean)
    np.testing.assert_array_equal(filters[1].log_w, filters[0].log_w)
    assert filters[1].warnings == filters[0].warnings >= 1
    assert filters[1].replay(observations[:1], actions) is None


class ShareDensity:
    """A known likelihood in the density's place: a push moves the chain along its first
    link by the first link's share of the mass, seen with noise 0.01."""

    def digest(self):
        return "share"

    def _mean(self, start, masses):
        out = np.zeros((len(masses), 4))
        out[:, 0] = masses[:, 0] / masses.sum(axis=1)
        return rest_poses(start, out)

    def log_prob(self, start, action, observed, masses, friction, lengths):
        return -0.5 * np.sum(((observed - self._mean(start, masses)) / 0.01) ** 2, axis=1)

    def cross_log_prob(self, start, action, observed, masses, friction, lengths):
        mean = self._mean(start, masses)
        return -0.5 * np.sum(((observed[:, None] - mean[None]) / 0.01) ** 2, axis=2)

    def sample(self, start, action, masses, friction, lengths, rng):
        return self._mean(start, masses) + rng.normal(0, 0.01, (len(masses), 4))


def test_the_learned_likelihood_concentrates_the_filter_on_the_truth():
    env = EnvConfig(physics=SETTING.physics(), pusher="stiff")
    config = BayesConfig(likelihood="learned", density="any", particles=2000, move_sweeps=2,
                         lookahead_particles=16, candidates=2)  # fmt: skip
    filt = ParticleFilter(env, config, seed=0, density=ShareDensity())
    assert filt.arm is None and "density_digest" in filt.settings()
    filt.reset(np.array([0.12, 0.12]), episode=3)
    truth = np.array([0.3, 0.7])
    start = np.array([0.0, 0.0, 0.4, 0.1])
    observed = ShareDensity()._mean(start, truth[None])[0]
    for _ in range(3):
        posterior = filt.update(start, np.array([0.5, 0.5]), observed)
    assert np.abs(posterior.estimate - truth).max() < 0.02, posterior.estimate
    assert np.all(posterior.low <= truth + 0.01) and np.all(truth - 0.01 <= posterior.high)
    assert filt.accepted and max(filt.accepted) > 0  # resample-move ran, with the density
    scores = filt.expected_variance(start, np.array([[0.5, 0.5], [-0.5, 0.5]]))
    assert scores.shape == (2,) and np.all(scores >= 0)


def test_the_learned_likelihood_is_chosen_by_name():
    two, three = (default_config(get_setting(name), likelihood="learned")
                  for name in ("2link-0.1-1", "3link-0.1-1"))  # fmt: skip
    assert replace(two, likelihood_power=None) == LEARNED_CONFIG
    assert (two.likelihood_power, three.likelihood_power) == LEARNED_LIKELIHOOD_POWER
    got = bayes_overrides(["likelihood=learned", "density=m.pt"])
    assert got == {"likelihood": "learned", "density": "m.pt"}
    assert bayes_overrides(["density=none"]) == {"density": None}
    with pytest.raises(ValueError, match="likelihood"):
        BayesConfig(likelihood="guess")
    with pytest.raises(ValueError, match="needs a push density"):
        ParticleFilter(EnvConfig(physics=SETTING.physics(), pusher="stiff"),
                       BayesConfig(likelihood="learned"))  # fmt: skip


def test_a_density_s_filter_guesses_only_the_frictions_its_data_held():
    env = EnvConfig(physics=SETTING.physics(), pusher="stiff")
    config = BayesConfig(likelihood="learned", density="any", particles=500, move_sweeps=1,
                         lookahead_particles=16, candidates=2)  # fmt: skip
    lo, hi = SETTING.physics().friction_range
    assert friction_prior(None, (lo, hi)) == (lo, hi)
    assert friction_prior(ShareDensity(), (lo, hi)) == (lo, hi)  # nothing recorded: all
    one_lab = ShareDensity()
    one_lab.meta = {"friction_seen": [0.7, 0.7]}
    assert friction_prior(one_lab, (0.5, 1.0)) == (0.7, 0.7)
    assert friction_prior(one_lab, (0.8, 1.0)) == (0.7, 0.7)  # no overlap: the density's
    one_lab.meta = {"friction_seen": [0.6, 2.0]}
    assert friction_prior(one_lab, (0.5, 1.0)) == (0.6, 1.0)
    one_lab.meta = {"friction_seen": [0.7, 0.7]}
    filt = ParticleFilter(env, config, seed=0, density=one_lab)
    filt.reset(np.array([0.12, 0.12]), episode=1)
    start = np.array([0.0, 0.0, 0.4, 0.1])
    observed = one_lab._mean(start, np.array([[0.3, 0.7]]))[0]
    for _ in range(3):  # resampled and moved: still the one friction
        filt.update(start, np.array([0.5, 0.5]), observed)
        np.testing.assert_allclose(filt.friction, 0.7)


def test_a_named_friction_range_widens_the_particles_beyond_the_density_s():
    env = EnvConfig(physics=SETTING.physics(), pusher="stiff")
    density = ShareDensity()
    density.meta = {"friction_seen": [0.5, 1.0]}
    config = BayesConfig(likelihood="learned", density="any", particles=500, move_sweeps=1,
                         lookahead_particles=16, candidates=2)  # fmt: skip
    plain = ParticleFilter(env, config, seed=0, density=density)
    wide = ParticleFilter(env, replace(config, friction_range=(0.3, 1.2)), seed=0,
                          density=density)  # fmt: skip
    assert plain.friction_range == (0.5, 1.0)
    assert "friction_range" not in plain.settings()  # off: caches made before stay valid
    assert wide.settings()["friction_range"] == (0.3, 1.2)
    start = np.array([0.0, 0.0, 0.4, 0.1])
    for filt in (plain, wide):
        filt.reset(np.array([0.12, 0.12]), episode=1)
        filt.update(start, np.array([0.5, 0.5]), density._mean(start, np.array([[0.3, 0.7]]))[0])
    assert plain.friction.min() >= 0.5 and plain.friction.max() <= 1.0
    assert wide.friction.min() >= 0.3 and wide.friction.max() <= 1.2
    assert wide.friction.min() < 0.5 or wide.friction.max() > 1.0
    assert bayes_overrides(["friction_range=0.3,1.2"]) == {"friction_range": (0.3, 1.2)}
    assert bayes_overrides(["friction_range=none"]) == {"friction_range": None}
    for bad in ("friction_range=0.3", "friction_range=a,b"):
        with pytest.raises(ValueError, match="LOW,HIGH"):
            bayes_overrides([bad])
    for bad in ((1.2, 0.3), (0.0, 1.0), (0.3, float("nan"))):
        with pytest.raises(ValueError, match="friction_range"):
            BayesConfig(friction_range=bad)
