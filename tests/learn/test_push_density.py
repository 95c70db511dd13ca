from dataclasses import replace

import numpy as np
import pytest
import torch
import tqdm

from masspush.config import EnvConfig
from masspush.data.dataset import CollectConfig, collect_dataset, load_dataset
from masspush.learn.push_density import (
    DensityConfig,
    PushDensity,
    check_density,
    density_for,
    episode_pushes,
    load_push_density,
    push_inputs,
    push_outputs,
    rest_poses,
    train_push_density,
)
from masspush.settings import get_setting

SETTING = get_setting("2link-1-10")  # the stiff pusher: cheap episodes


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("density") / "ds"
    collect_dataset(CollectConfig(setting="2link-1-10", out=str(root), episodes=40,
                                  shard_size=20), progress=False)  # fmt: skip
    return root


def test_outputs_in_the_start_frame_invert_to_rest_poses():
    rng = np.random.default_rng(0)
    start = np.column_stack([rng.normal(size=(50, 2)), rng.uniform(-3, 3, (50, 2))])
    observed = start + rng.normal(0, 0.3, start.shape)
    back = rest_poses(start, push_outputs(start, observed))
    assert np.allclose(back[:, [0, 1, 3]], observed[:, [0, 1, 3]])
    assert np.allclose(np.cos(back[:, 2] - observed[:, 2]), 1)
    # The outcome in the start's frame does not depend on where the chain lies or points.
    turned = start.copy()
    turned[:, 2] += 1.0
    moved = observed.copy()
    c, s = np.cos(1.0), np.sin(1.0)
    d = observed[:, :2] - start[:, :2]
    moved[:, :2] = start[:, :2] + d @ np.array([[c, s], [-s, c]])
    moved[:, 2] += 1.0
    assert np.allclose(push_outputs(turned, moved), push_outputs(start, observed))


def test_inputs_broadcast_one_push_over_the_particles():
    x = push_inputs(np.zeros(4), np.array([0.5, -0.5]), np.full((6, 2), 0.5), np.full(6, 0.7),
                    np.array([0.12, 0.12]))  # fmt: skip
    assert x.shape == (6, 1 + 2 + 2 + 1 + 2)
    assert np.allclose(x[:, 3:5], np.log(0.5)) and np.allclose(x[:, -2:], 1.2)


def test_failed_pushes_and_those_after_are_left_out():
    class Episodes:
        observations = np.zeros((3, 3, 4))
        actions = np.zeros((3, 2, 2))
        masses = np.ones((3, 2))
        friction = np.ones(3)
        lengths = np.full((3, 2), 0.12)
        failure = np.array([[0, 0], [1, 0], [0, 2]])

    x, y = episode_pushes(Episodes)
    assert len(x) == len(y) == 2 + 0 + 1


def test_a_density_may_read_the_pushes_as_executed():
    class Episodes:
        observations = np.zeros((1, 2, 4))
        actions = np.array([[[0.5, -0.5]]])
        executed = np.array([[[0.6, -0.3]]])
        masses, friction, lengths = np.ones((1, 2)), np.ones(1), np.full((1, 2), 0.12)
        failure = np.zeros((1, 1), int)

    # push_inputs: the joint angle (2 links), then the action
    def action(which):
        x = episode_pushes(Episodes, which=which)[0]
        return x[0, 1:3]

    np.testing.assert_allclose(action("commanded"), [0.5, -0.5])
    np.testing.assert_allclose(action("executed"), [0.6, -0.3])
    np.testing.assert_allclose(action("executed-speed"), [0.6, -0.5])
    np.testing.assert_array_equal(Episodes.actions, [[[0.5, -0.5]]])  # the dataset untouched
    with pytest.raises(ValueError, match="actions must be one of"):
        DensityConfig(data=("d",), out="x.pt", actions="planned")


def test_training_writes_a_density_that_resumes_to_the_same_weights(dataset, tmp_path, monkeypatch):
    whole = DensityConfig(data=(str(dataset),), out=str(tmp_path / "a.pt"), steps=30,
                          batch_size=64, width=16, depth=2, components=2, checkpoint_every=10,
                          held_out=0.1)  # fmt: skip
    summary = train_push_density(whole, progress=False)
    assert summary["pushes"] > 0 and summary["held_out_pushes"] > 0
    assert np.isfinite(summary["held_out_log_likelihood"])
    net = load_push_density(whole.out)
    assert net.meta["n_links"] == 2 and net.meta["pusher"] == "stiff"
    assert net.meta["mass_range"] == list(SETTING.physics().mass_range)
    _, episodes = load_dataset(dataset)  # the frictions it saw, for the filter's prior
    assert net.meta["friction_seen"] == [episodes.friction.min(), episodes.friction.max()]

    stopped = DensityConfig(**{**whole.__dict__, "out": str(tmp_path / "b.pt")})
    calls = {"n": 0}
    real_update = tqdm.tqdm.update

    def stop_at_25(self, n=1):
        calls["n"] += 1
        if calls["n"] == 25:
            raise KeyboardInterrupt
        return real_update(self, n)

    monkeypatch.setattr(tqdm.tqdm, "update", stop_at_25)
    with pytest.raises(KeyboardInterrupt):
        train_push_density(stopped, progress=False)
    monkeypatch.setattr(tqdm.tqdm, "update", real_update)
    assert (tmp_path / "b.pt.ckpt").is_file() and not (tmp_path / "b.pt").exists()
    train_push_density(stopped, progress=False)  # resumes at step 20
    assert not (tmp_path / "b.pt.ckpt").exists()
    resumed = load_push_density(stopped.out)
    for key, value in net.state_dict().items():
        assert torch.equal(value, resumed.state_dict()[key]), key


def test_a_density_records_the_physics_its_data_was_collected_in(tmp_path):
    # A settings file's own prior and tool, not those of the built-in setting of that name.
    settings = tmp_path / "s.toml"
    settings.write_text("[2link-1-10]\nlinks = 2\nmass_range = [1.0, 10.0]\npusher = 'stiff'\n"
                        "friction_range = [0.4, 0.9]\ntool_friction = 0.5\n")  # fmt: skip
    data = tmp_path / "ds"
    collect_dataset(CollectConfig(setting="2link-1-10", out=str(data), episodes=10,
                                  settings_file=str(settings)), progress=False)  # fmt: skip
    config = DensityConfig(data=(str(data),), out=str(tmp_path / "d.pt"), steps=2,
                           batch_size=4, width=8, depth=1, components=1, held_out=0.3)  # fmt: skip
    train_push_density(config, progress=False)
    meta = load_push_density(config.out).meta
    assert (meta["friction_range"], meta["tool_friction"]) == ([0.4, 0.9], 0.5)
    built_in = DensityConfig(**{**config.__dict__, "out": str(tmp_path / "e.pt")})
    train_push_density(replace(built_in, data=(str(_built_in(tmp_path)),)), progress=False)
    meta = load_push_density(built_in.out).meta
    assert (meta["friction_range"], meta["tool_friction"]) == ([0.5, 1.0], 1.0)


def test_data_too_small_to_hold_pushes_out_is_refused_before_training(tmp_path):
    data = tmp_path / "one"  # its one episode held out, nothing left to train on
    collect_dataset(CollectConfig(setting="2link-1-10", out=str(data), episodes=1,
                                  pusher="stiff"), progress=False)  # fmt: skip
    config = DensityConfig(data=(str(data),), out=str(tmp_path / "d.pt"), steps=2)
    with pytest.raises(ValueError, match="0 pushes to train on"):
        train_push_density(config, progress=False)
    assert not (tmp_path / "d.pt").exists() and not (tmp_path / "d.pt.ckpt").exists()


def _built_in(tmp_path):
    data = tmp_path / "built-in"
    collect_dataset(CollectConfig(setting="2link-1-10", out=str(data), episodes=10,
                                  pusher="stiff"), progress=False)  # fmt: skip
    return data


def test_a_checkpoint_of_another_run_is_refused(dataset, tmp_path, monkeypatch):
    config = DensityConfig(data=(str(dataset),), out=str(tmp_path / "c.pt"), steps=20,
                           batch_size=32, width=8, depth=1, components=1,
                           checkpoint_every=5)  # fmt: skip

    def stop(self, n=1):
        raise KeyboardInterrupt

    real_update = tqdm.tqdm.update
    calls = {"n": 0}

    def stop_after_5(self, n=1):
        calls["n"] += 1
        if calls["n"] > 6:
            stop(self, n)
        return real_update(self, n)

    monkeypatch.setattr(tqdm.tqdm, "update", stop_after_5)
    with pytest.raises(KeyboardInterrupt):
        train_push_density(config, progress=False)
    monkeypatch.setattr(tqdm.tqdm, "update", real_update)
    other = DensityConfig(**{**config.__dict__, "lr": 1e-3})
    with pytest.raises(ValueError, match="another training run"):
        train_push_density(other, progress=False)


def test_datasets_of_other_settings_are_refused_before_training(dataset, tmp_path):
    other = tmp_path / "other"
    collect_dataset(CollectConfig(setting="2link-0.1-10", out=str(other), episodes=2,
                                  pusher="stiff"), progress=False)  # fmt: skip
    config = DensityConfig(data=(str(dataset), str(other)), out=str(tmp_path / "m" / "d.pt"))
    with pytest.raises(ValueError, match="has setting"):
        train_push_density(config, progress=False)
    assert not (tmp_path / "m").exists()


def test_bad_configs_and_files_are_one_line_errors(tmp_path):
    with pytest.raises(ValueError, match="data"):
        DensityConfig(data=(), out="x.pt")
    with pytest.raises(ValueError, match="held_out"):
        DensityConfig(data=("d",), out="x.pt", held_out=0.7)
    with pytest.raises(ValueError, match="directory"):
        DensityConfig(data=("d",), out=str(tmp_path))
    with pytest.raises(ValueError, match=r"batch_size 1,000,000,000,000: a step on pushes"):
        DensityConfig(data=("d",), out="x.pt", batch_size=10**12)
    with pytest.raises(ValueError, match="no such file"):
        load_push_density(tmp_path / "none.pt")
    with pytest.raises(ValueError, match="a directory, not a model file"):
        load_push_density(tmp_path)
    garbage = tmp_path / "g.pt"
    garbage.write_bytes(b"\x00not a model")
    with pytest.raises(ValueError, match="cannot be read"):
        load_push_density(garbage)
    net = PushDensity(7, 4, 1, 8, 1, meta={"n_links": 2, "pusher": "kuka", "obs_noise": 0.01})
    check_density(net, "f.pt", {"n_links": 2, "pusher": "kuka", "obs_noise": 0.010000001})
    with pytest.raises(ValueError, match="trained for pusher 'kuka', not 'stiff'"):
        check_density(net, "f.pt", {"n_links": 2, "pusher": "stiff"})


def test_a_density_loads_only_for_the_chains_and_pusher_it_was_trained_for(dataset, tmp_path):
    config = DensityConfig(data=(str(dataset),), out=str(tmp_path / "d.pt"), steps=2,
                           batch_size=8, width=8, depth=1, components=1)  # fmt: skip
    train_push_density(config, progress=False)
    env = EnvConfig(physics=SETTING.physics(), pusher="stiff")
    assert density_for(config.out, env).meta["setting"] == "2link-1-10"
    with pytest.raises(ValueError, match="n_links 2, not 3"):
        density_for(config.out, EnvConfig(physics=get_setting("3link-1-10").physics(),
                                          pusher="stiff"))  # fmt: skip
    with pytest.raises(ValueError, match="obs_noise"):
        density_for(config.out, EnvConfig(physics=SETTING.physics(), pusher="stiff",
                                          obs_noise=0.0))  # fmt: skip
    executed = replace(config, out=str(tmp_path / "e.pt"), actions="executed")
    train_push_density(executed, progress=False)
    with pytest.warns(UserWarning, match="contact point as commanded"):
        assert density_for(executed.out, env).meta["actions"] == "executed"


def test_placed_inputs_add_where_the_chain_lies():
    start = np.array([0.7, -0.1, 0.5, 0.2])
    args = (np.array([0.5, -0.5]), np.full((3, 2), 0.5), np.full(3, 0.7), np.array([0.12, 0.12]))
    plain, placed = push_inputs(start, *args), push_inputs(start, *args, placed=True)
    assert placed.shape == (3, plain.shape[1] + 4)
    np.testing.assert_array_equal(placed[:, : plain.shape[1]], plain)
    np.testing.assert_allclose(placed[0, -4:], [0.7, -0.1, np.cos(0.5), np.sin(0.5)])


def test_a_density_sees_the_chains_place_only_where_asked_or_the_robot_stands_still(
    dataset, tmp_path
):
    small = dict(data=(str(dataset),), steps=2, batch_size=16, width=8, depth=1, components=1)
    train_push_density(DensityConfig(out=str(tmp_path / "a.pt"), **small), progress=False)
    plain = load_push_density(tmp_path / "a.pt")  # the stiff pusher: the table is uniform
    assert not plain.placed and plain.arch["inputs"] == 8
    train_push_density(DensityConfig(out=str(tmp_path / "b.pt"), placed=True, **small),
                       progress=False)  # fmt: skip
    placed = load_push_density(tmp_path / "b.pt")
    assert placed.placed and placed.arch["inputs"] == 12
    start, masses = np.array([0.1, 0.0, 0.3, 0.2]), np.full((5, 2), 0.5)
    logp = placed.log_prob(start, np.array([0.5, 0.5]), start, masses, np.full(5, 0.7),
                           np.array([0.12, 0.12]))  # fmt: skip
    assert logp.shape == (5,) and np.all(np.isfinite(logp))
