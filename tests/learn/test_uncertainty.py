import shutil

import numpy as np
import pytest

from masspush import models as models_module
from masspush.config import EnvConfig
from masspush.data.rollout import EVAL, TRAIN, RandomPolicy, run_episodes
from masspush.evaluate import EvaluateConfig
from masspush.learn.predictor import load_model, predictor_digest
from masspush.learn.uncertainty import (
    HeadConfig,
    LearnedPosterior,
    PrecisionHead,
    StaleHeadError,
    concentration,
    coverage,
    fit_head,
    head_path,
    intervals,
    load_head,
    save_head,
)
from masspush.models import SHIPPED_DIR, evaluate_model, resolve_model
from masspush.settings import get_setting

SETTING = get_setting("2link-1-10")


@pytest.fixture(scope="module")
def fitted():
    predictor, _ = load_model(SHIPPED_DIR / SETTING.name / "rp+.pt", SETTING.name)
    env = EnvConfig(physics=SETTING.physics(), pusher="stiff")
    train = run_episodes(env, RandomPolicy(), np.arange(400), TRAIN, 7919)
    test = run_episodes(env, RandomPolicy(), np.arange(300), EVAL, 5)
    head = fit_head(predictor, train.select(train.ok), HeadConfig(steps=300))
    return predictor, head, test.select(test.ok)


@pytest.mark.slow
def test_fitted_intervals_cover_near_their_nominal_share_on_fresh_episodes(fitted):
    predictor, head, test = fitted
    share = coverage(predictor, head, test, 0.9)
    assert 0.8 <= share <= 0.97, share
    # Narrower claims cover less: the intervals carry information, not just width.
    assert coverage(predictor, head, test, 0.5) < share - 0.2


def test_beta_quantiles_of_a_flat_dirichlet():
    # Dirichlet(1, 1): each share is uniform on [0, 1].
    low, high = intervals(np.array([[1.0, 1.0]]), 0.9, samples=40_000)
    np.testing.assert_allclose(low, [[0.05, 0.05]], atol=0.01)
    np.testing.assert_allclose(high, [[0.95, 0.95]], atol=0.01)


@pytest.mark.slow
def test_a_head_round_trips_and_refuses_another_setting(fitted, tmp_path):
    predictor, head, test = fitted
    path = save_head(tmp_path / "m.dirichlet.pt", head, {"setting": SETTING.name})
    again = load_head(path, SETTING.name)
    assert coverage(predictor, again, test) == coverage(predictor, head, test)
    with pytest.raises(ValueError, match="belongs to setting"):
        load_head(path, "2link-0.1-1")


@pytest.mark.slow
def test_a_head_fits_an_ensemble_and_refuses_to_serve_one_member(fitted, tmp_path, perturbed_pair):
    predictor, _, test = fitted
    ensemble = perturbed_pair(predictor)
    head = fit_head(ensemble, test, HeadConfig(steps=100))
    assert head.net[0].in_features == 2 * 64  # both members' features
    alpha = concentration(ensemble, head, test)
    np.testing.assert_allclose(alpha / alpha.sum(-1, keepdims=True), ensemble.predict(test),
                               rtol=1e-5)  # fmt: skip
    meta = {"setting": SETTING.name, "predictor": predictor_digest(ensemble)}
    path = save_head(tmp_path / "e.dirichlet.pt", head, meta)
    assert coverage(ensemble, load_head(path, SETTING.name, ensemble), test) > 0.5
    with pytest.raises(StaleHeadError, match="another predictor"):
        load_head(path, SETTING.name, predictor)


@pytest.mark.slow
def test_evaluate_reports_coverage_when_the_model_has_a_head(fitted, tmp_path, monkeypatch):
    predictor, head, _ = fitted
    models = tmp_path / "models"
    shutil.copytree(SHIPPED_DIR / SETTING.name, models / SETTING.name,
                    ignore=shutil.ignore_patterns("*.dirichlet.pt"))  # fmt: skip
    monkeypatch.setattr(models_module, "SHIPPED_DIR", models)
    assert (
        "coverage" not in evaluate_model(EvaluateConfig(SETTING.name, "rp+", episodes=20)).to_dict()
    )
    meta = {"setting": SETTING.name, "predictor": predictor_digest(predictor)}
    save_head(head_path(models / SETTING.name / "rp+.pt"), head, meta)
    assert (
        0
        <= evaluate_model(EvaluateConfig(SETTING.name, "rp+", episodes=20)).to_dict()["coverage"]
        <= 1
    )


@pytest.mark.slow
def test_the_learned_density_peaks_at_the_models_estimate(fitted):
    predictor, head, test = fitted
    learned = LearnedPosterior(predictor, head)
    one = test.select(np.arange(len(test)) == 0)
    history = one.history(one.observations, one.actions, one.lengths)
    alpha = learned.concentration(history)
    estimate = predictor.predict(one)[0, -1]
    np.testing.assert_allclose(alpha / alpha.sum(), estimate, atol=1e-5)
    # The Dirichlet's mode, near its mean for a sharp one, beats points away from it.
    mode = (alpha - 1) / (alpha.sum() - len(alpha))
    shares = np.array([mode, [0.5, 0.5], [0.9, 0.1], [0.1, 0.9]])
    density = learned.log_density(history, shares)
    assert np.argmax(density) == 0 and np.all(np.isfinite(density))


def test_a_model_without_a_head_is_refused_with_the_command_that_fits_one():
    with pytest.raises(ValueError, match="masspush calibrate --setting 2link-1-10 --model rp"):
        LearnedPosterior.load(resolve_model("rp", SETTING.name), SETTING.name)


def test_bad_head_configs_are_refused():
    with pytest.raises(ValueError, match="credible"):
        HeadConfig(credible=0.0)


def _models_without_heads(tmp_path, monkeypatch):
    models = tmp_path / "models"
    shutil.copytree(SHIPPED_DIR / SETTING.name, models / SETTING.name,
                    ignore=shutil.ignore_patterns("*.dirichlet.pt"))  # fmt: skip
    monkeypatch.setattr(models_module, "SHIPPED_DIR", models)
    return models / SETTING.name


def test_a_head_fitted_on_another_predictor_is_refused_and_evaluate_drops_it(tmp_path, monkeypatch):
    folder = _models_without_heads(tmp_path, monkeypatch)
    rp_plus, _ = load_model(folder / "rp+.pt", SETTING.name)
    tp_plus, _ = load_model(folder / "tp+.pt", SETTING.name)
    assert predictor_digest(rp_plus) != predictor_digest(tp_plus)
    head = PrecisionHead()
    meta = {"setting": SETTING.name, "model": "rp+", "predictor": predictor_digest(rp_plus)}
    path = save_head(head_path(folder / "rp+.pt"), head, meta)
    load_head(path, SETTING.name, rp_plus)
    refit = r"masspush calibrate --setting 2link-1-10 --model rp\+"
    with pytest.raises(StaleHeadError, match=refit):
        load_head(path, SETTING.name, tp_plus)
    legacy = save_head(tmp_path / "old.dirichlet.pt", head, {"setting": SETTING.name})
    with pytest.raises(StaleHeadError):  # fitted before heads recorded their predictor
        load_head(legacy, SETTING.name, rp_plus)
    # The same head beside TP+: its estimate still counts, its intervals are not reported.
    shutil.copy(path, head_path(folder / "tp+.pt"))
    with pytest.warns(UserWarning, match="fitted on another predictor"):
        result = evaluate_model(EvaluateConfig(SETTING.name, "tp+", episodes=3)).to_dict()
    assert "coverage" not in result and result["episodes"] > 0


def test_shipping_a_model_removes_the_head_of_the_one_it_replaces(tmp_path, monkeypatch):
    from masspush.models import ship_model

    folder = _models_without_heads(tmp_path, monkeypatch)
    rp_plus, _ = load_model(folder / "rp+.pt", SETTING.name)
    meta = {"setting": SETTING.name, "model": "rp+", "predictor": predictor_digest(rp_plus)}
    save_head(head_path(folder / "rp+.pt"), PrecisionHead(), meta)
    ship_model(folder / "rp+.pt", folder / "rp+.pt")  # the same predictor: its head stays
    assert head_path(folder / "rp+.pt").exists()
    with pytest.warns(UserWarning, match="removed .*rp\\+.dirichlet.pt"):
        ship_model(folder / "rp.pt", folder / "rp+.pt")  # another one: the head goes
    assert not head_path(folder / "rp+.pt").exists()
