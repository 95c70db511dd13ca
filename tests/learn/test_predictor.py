import re
from dataclasses import replace

import numpy as np
import pytest
import torch

from masspush.config import EnvConfig
from masspush.data.rollout import EVAL, TRAIN, RandomPolicy, run_batch
from masspush.learn.predictor import (
    MassPredictor,
    ModelMismatchError,
    PredictorEnsemble,
    TrainConfig,
    load_model,
    predictor_digest,
    save_model,
    step_inputs,
    train_ensemble,
    train_predictor,
)
from masspush.metrics import all_metrics
from masspush.settings import get_setting

SETTING = get_setting("2link-0.1-1")


@pytest.fixture(scope="module")
def episodes():
    config = EnvConfig(physics=SETTING.physics(), pusher="stiff")
    return run_batch(config, RandomPolicy(), np.arange(3000), TRAIN, 0)


def test_architecture_is_the_papers():
    model = MassPredictor(n_links=3, q0_dim=8, step_dim=12)
    assert (model.embed.out_features, model.lstm.hidden_size) == (128, 64)
    assert (model.init_h.out_features, model.init_c.out_features, model.head.out_features) == (
        64,
        64,
        3,
    )
    out = model(torch.zeros(5, 8), torch.zeros(5, 3, 12))
    assert out.shape == (5, 3, 3)
    torch.testing.assert_close(out.sum(-1), torch.ones(5, 3))


def test_a_width_makes_every_layer_that_wide_with_two_lstm_layers(tmp_path):
    torch.manual_seed(0)
    model = MassPredictor(3, 8, 12, "relative", width=32)
    assert (model.lstm.hidden_size, model.lstm.num_layers) == (32, 2)
    assert model.init_h.out_features == 2 * 32  # one initial state per LSTM layer
    q0, steps = torch.randn(5, 8), torch.randn(5, 4, 12)
    with torch.no_grad():
        features, out = model.features(q0, steps), model(q0, steps)
    assert features.shape == (5, 4, 32) and out.shape == (5, 4, 3)
    torch.testing.assert_close(out.sum(-1), torch.ones(5, 4))
    # The file says the width; a paper-size file says nothing, as files made before.
    save_model(tmp_path / "w.pt", model, {})
    loaded, _ = load_model(tmp_path / "w.pt")
    assert loaded.width == 32 and torch.load(tmp_path / "w.pt")["arch"]["width"] == 32
    with torch.no_grad():
        torch.testing.assert_close(loaded(q0, steps), out)
    save_model(tmp_path / "p.pt", MassPredictor(3, 8, 12), {})
    assert "width" not in torch.load(tmp_path / "p.pt")["arch"]
    assert load_model(tmp_path / "p.pt")[0].width is None
    # Members of one ensemble share a width (its file holds one architecture).
    with pytest.raises(ValueError, match="at one width"):
        PredictorEnsemble([model, MassPredictor(3, 8, 12, "relative")])
    wide = PredictorEnsemble([model, MassPredictor(3, 8, 12, "relative", width=32)])
    save_model(tmp_path / "e.pt", wide, {})
    assert load_model(tmp_path / "e.pt")[0].width == 32


def test_the_width_is_validated_and_kept_out_of_old_records(episodes, tmp_path):
    from masspush.learn.predictor import recorded_config

    for bad in (0, 7, 2000):
        with pytest.raises(ValueError, match=f"width must be in 8..1024.*got {bad}"):
            TrainConfig(width=bad)
    assert "width" not in recorded_config(TrainConfig())  # runs before the field resume
    assert recorded_config(TrainConfig(width=64))["width"] == 64
    small = episodes.select(np.arange(len(episodes)) < 100)
    config = TrainConfig(optimizer="adam", steps=4, batch_size=8, eval_every=2, width=16,
                         features="relative")  # fmt: skip
    model, summary = train_predictor(small, tmp_path / "w", config, progress=False)
    assert model.width == 16 and summary["train_config"]["width"] == 16
    with pytest.raises(ValueError, match=r"keeps the network's width \(16\), not None"):
        train_predictor(small, tmp_path / "x", replace(config, width=None), False, init=model)


@pytest.mark.slow
def test_predictor_overfits_a_tiny_dataset(episodes, tmp_path):
    tiny = episodes.select(np.arange(len(episodes)) < 24)
    config = TrainConfig(
        optimizer="adam",
        steps=1500,
        batch_size=16,
        lr=1e-2,
        validation_fraction=0.0,
        eval_every=1500,
        features="relative",
    )
    model, _ = train_predictor(tiny, tmp_path / "run", config, progress=False)
    good = tiny.select(tiny.ok)
    error = np.abs(model.predict(good)[:, -1] - good.mass_distribution).mean()
    assert error < 0.02  # memorised (the constant prediction is off by ~0.15)


@pytest.mark.slow
def test_short_training_beats_the_constant_floor_on_held_out_episodes(episodes, tmp_path):
    config = TrainConfig(
        optimizer="adam", steps=2500, batch_size=128, lr=3e-3, eval_every=500, features="relative"
    )
    model, _ = train_predictor(episodes, tmp_path / "run", config, progress=False)
    fresh = run_batch(EnvConfig(physics=SETTING.physics()), RandomPolicy(), np.arange(400), EVAL, 0)
    fresh = fresh.select(fresh.ok)
    result = all_metrics(model.predict(fresh)[:, -1], fresh.mass_distribution)
    assert result["percentage_error"] < 0.85 * result["constant_floor"], result


@pytest.mark.slow
def test_training_resumes_exactly_where_it_stopped(episodes, tmp_path):
    small = episodes.select(np.arange(len(episodes)) < 200)
    full = TrainConfig(
        optimizer="adam", steps=60, batch_size=8, lr=1e-3, eval_every=20, checkpoint_every=30
    )
    straight, _ = train_predictor(small, tmp_path / "a", full, progress=False)
    # A run killed right after its checkpoint at step 30, then started again, ends the same.
    interrupted = tmp_path / "c"
    _run_until(small, interrupted, full, 30)
    resumed, summary = train_predictor(small, interrupted, full, progress=False)
    assert summary["steps"] == 60
    for a, b in zip(straight.state_dict().values(), resumed.state_dict().values(), strict=True):
        torch.testing.assert_close(a, b)


def test_the_l1_loss_trains_otherwise_and_a_checkpoint_keeps_its_loss(episodes, tmp_path):
    with pytest.raises(ValueError, match="loss must be one of"):
        TrainConfig(loss="huber")
    small = episodes.select(np.arange(len(episodes)) < 200)
    mse = TrainConfig(optimizer="adam", steps=20, batch_size=8, lr=1e-3, eval_every=10,
                      checkpoint_every=10)  # fmt: skip
    a, _ = train_predictor(small, tmp_path / "mse", mse, progress=False)
    b, summary = train_predictor(small, tmp_path / "l1", replace(mse, loss="l1"), progress=False)
    assert summary["train_config"]["loss"] == "l1"
    assert not torch.equal(a.head.weight, b.head.weight)  # same seed and batches, other loss
    # A checkpoint records the loss as runs before the field did (mse: not at all), and a
    # run resumed with another loss is refused instead of mixing the two.
    _run_until(small, tmp_path / "c", replace(mse, steps=40), 10)
    assert "loss" not in torch.load(tmp_path / "c" / "checkpoint.pt", weights_only=False)["config"]
    with pytest.raises(ValueError, match="another config"):
        train_predictor(small, tmp_path / "c", replace(mse, steps=40, loss="l1"), progress=False)


def _run_until(episodes, run_dir, config, stop_step):
    """Train with `config` but stop (as if killed) right after the checkpoint at stop_step."""
    import masspush.learn.predictor as predictor

    class Stop(Exception):
        pass

    real_replace = predictor.os.replace

    def replace_then_stop(src, dst):
        real_replace(src, dst)
        if str(dst).endswith("checkpoint.pt"):
            if torch.load(dst, weights_only=False)["step"] >= stop_step:
                raise Stop

    predictor.os.replace = replace_then_stop
    try:
        train_predictor(episodes, run_dir, config, progress=False)
    except Stop:
        pass
    finally:
        predictor.os.replace = real_replace


@pytest.mark.slow
def test_model_files_round_trip_and_refuse_other_settings(episodes, tmp_path):
    q0, steps = step_inputs(episodes.select(episodes.ok), "relative")
    model = MassPredictor(2, q0.shape[1], steps.shape[2], "relative")
    model.set_normaliser(q0, steps)
    path = tmp_path / "m.pt"
    save_model(path, model, {"setting": SETTING.as_dict(), "pusher": "stiff", "policy": "random"})
    loaded, meta = load_model(path, setting="2link-0.1-1", pusher="stiff")
    for a, b in zip(model.state_dict().values(), loaded.state_dict().values(), strict=True):
        torch.testing.assert_close(a, b)
    assert loaded.features_kind == "relative" and meta["policy"] == "random"
    with pytest.raises(ModelMismatchError, match=re.escape("trained for setting '2link-0.1-1'")):
        load_model(path, setting="3link-0.1-1")
    with pytest.raises(ModelMismatchError, match="'stiff' pusher"):
        load_model(path, pusher="kuka")
    path.write_bytes(b"not a model")
    with pytest.raises(ValueError, match="not a readable model file"):
        load_model(path)


def _random_members(count: int, n_links: int = 3) -> list[MassPredictor]:
    members = []
    for seed in range(count):
        torch.manual_seed(seed)
        members.append(MassPredictor(n_links, 8, 12, "relative"))
    return members


def test_an_ensemble_averages_its_members_estimates():
    members = _random_members(3)
    ensemble = PredictorEnsemble(members)
    q0, steps = torch.randn(5, 8), torch.randn(5, 2, 12)
    with torch.no_grad():
        out = ensemble(q0, steps)
        singles = torch.stack([m(q0, steps) for m in members])
        features = ensemble.features(q0, steps)
        log = ensemble.log_estimate(features)
    torch.testing.assert_close(out, singles.mean(0))
    assert not torch.allclose(singles[0], singles[1])  # the members differ
    assert features.shape == (5, 2, 3 * 64)  # each member's LSTM output, side by side
    torch.testing.assert_close(log, torch.log(out))
    assert (ensemble.n_links, ensemble.features_kind) == (3, "relative")


def test_an_ensemble_refuses_one_member_and_members_of_other_inputs():
    with pytest.raises(ValueError, match="at least 2 predictors, got 1"):
        PredictorEnsemble(_random_members(1))
    other = MassPredictor(3, 8, 12, "paper")
    with pytest.raises(ValueError, match="must read the same inputs"):
        PredictorEnsemble([*_random_members(1), other])


def test_ensemble_files_round_trip_and_a_newer_version_is_refused(tmp_path):
    ensemble = PredictorEnsemble(_random_members(2))
    path = tmp_path / "e.pt"
    save_model(path, ensemble, {"setting": {"name": "3link-0.1-1"}, "pusher": "kuka"})
    loaded, meta = load_model(path, setting="3link-0.1-1")
    assert meta["pusher"] == "kuka"
    assert isinstance(loaded, PredictorEnsemble) and len(loaded.members) == 2
    assert predictor_digest(loaded) == predictor_digest(ensemble)
    assert torch.load(path, weights_only=True)["version"] == 2
    single = tmp_path / "s.pt"
    save_model(single, _random_members(1)[0], {})
    assert torch.load(single, weights_only=True)["version"] == 1  # as files made before
    payload = torch.load(path, weights_only=True)
    torch.save({**payload, "version": 3}, path)
    with pytest.raises(ValueError, match="version 3, this masspush reads 1 and 2"):
        load_model(path)


@pytest.mark.slow
def test_train_ensemble_trains_members_apart_and_saves_their_average(episodes, tmp_path):
    small = episodes.select(np.arange(len(episodes)) < 300)
    config = TrainConfig(optimizer="adam", steps=40, batch_size=16, lr=1e-3, eval_every=20,
                         features="relative", seed=5)  # fmt: skip
    ensemble, summary = train_ensemble(small, tmp_path / "e", config, 3, {"x": 1}, False)
    seeds = [m["train_config"]["seed"] for m in summary["members"]]
    assert seeds == [5, 6, 7]
    loaded, meta = load_model(tmp_path / "e" / "predictor.pt")
    assert meta["x"] == 1 and len(loaded.members) == 3
    good = small.select(small.ok)
    np.testing.assert_allclose(loaded.predict(good), ensemble.predict(good), atol=1e-6)
    alone, _ = train_predictor(small, tmp_path / "alone", replace(config, seed=6), progress=False)
    np.testing.assert_allclose(  # member 1 is the predictor trained alone with seed 6
        ensemble.members[1].predict(good), alone.predict(good), atol=1e-6
    )
    with pytest.raises(ValueError, match="from one predictor, not an ensemble"):
        train_predictor(small, tmp_path / "f", config, progress=False, init=ensemble)
    with pytest.raises(ValueError, match="at least 2 predictors"):
        train_ensemble(small, tmp_path / "g", config, 1)


def test_a_batch_larger_than_the_memory_is_refused_with_the_estimate():
    from masspush.learn.predictor import check_batch_memory

    check_batch_memory(256, 2)  # the fast option's batch fits anywhere
    with pytest.raises(ValueError, match=r"batch_size 1,000,000,000,000: .* needs about"):
        check_batch_memory(10**12, 2)
