import json
from dataclasses import replace

import numpy as np
import pytest

from masspush.data.dataset import shard_path
from masspush.real.randomisation import (
    RandomiseConfig,
    collect_randomised,
    randomise,
    run_randomised,
)
from masspush.real.target_world import TargetWorld, TargetWorldRobot, WorldRanges

SETTING = "2link-1-10"  # the stiff pusher keeps these tests fast
TINY = RandomiseConfig(setting=SETTING, episodes=4, shard_size=2, steps=4)


def test_each_drawn_world_lies_within_the_ranges_and_follows_the_seed():
    ranges = WorldRanges()
    worlds = [ranges.sample(np.random.default_rng(s)) for s in range(40)]
    assert worlds[0] == ranges.sample(np.random.default_rng(0))
    assert {w.solver for w in worlds} == set(ranges.solvers)
    assert {w.cone for w in worlds} == set(ranges.cones)
    for w in worlds:
        assert isinstance(w, TargetWorld)
        assert ranges.link_width[0] <= w.link_width <= ranges.link_width[1]
        assert ranges.solver_iterations[0] <= w.solver_iterations <= ranges.solver_iterations[1]
        assert 0 <= w.obs_bias[1] <= ranges.obs_bias[1]
        assert w.timestep in ranges.timesteps


@pytest.mark.parametrize(
    "field, value, match",
    [
        ("solvers", ("Newton", "Euler"), "unknown solver"),
        ("cones", (), "must not be empty"),
        ("link_width", (0.05, 0.04), "low <= high"),
    ],
)
def test_bad_ranges_are_refused(field, value, match):
    with pytest.raises(ValueError, match=match):
        WorldRanges(**{field: value})


def test_the_robot_draws_a_new_world_for_each_episode():
    robot = TargetWorldRobot(SETTING, world=WorldRanges(), seed=5)
    seen = set()
    for _ in range(6):
        robot.start()
        world = robot.world
        # The simulation runs the drawn world, not the default target world.
        assert robot.sim.model.opt.timestep == world.timestep
        assert robot.physics.link_width == world.link_width
        seen.add((world.solver, world.link_width))
    assert len(seen) == 6


def test_episodes_are_what_the_robot_saw_and_follow_their_index():
    from masspush.models import resolve_model

    model = resolve_model("tp+", SETTING)
    eps = run_randomised(SETTING, model, WorldRanges(), np.array([3, 4]), 11)
    again = run_randomised(SETTING, model, WorldRanges(), np.array([4]), 11)
    np.testing.assert_array_equal(eps.observations[1], again.observations[0])
    assert list(eps.index) == [3, 4]
    seen = ~np.isnan(eps.observations[:, :, 0])
    # Observations carry the world's noise and bias; configs are the truth.
    assert np.abs(eps.observations - eps.configs)[seen].max() > 1e-3
    assert (eps.masses > 0).all() and eps.lengths.shape == (2, 2)


@pytest.mark.slow
def test_a_stopped_collection_resumes_to_the_same_episodes(tmp_path):
    first = collect_randomised(TINY, tmp_path, workers=1, progress=False)
    shard_path(tmp_path, 1).unlink()
    again = collect_randomised(TINY, tmp_path, workers=1, progress=False)
    np.testing.assert_array_equal(first.observations, again.observations)
    assert len(again) == 4
    with pytest.raises(ValueError, match="another randomisation"):
        collect_randomised(
            RandomiseConfig(setting=SETTING, episodes=4, shard_size=2, base_seed=1),
            tmp_path, workers=1, progress=False,
        )  # fmt: skip
    assert json.loads((tmp_path / "randomise.json").read_text())["setting"] == SETTING


def test_randomised_episodes_are_a_dataset_a_density_trains_on(tmp_path):
    from masspush.data.dataset import CollectConfig, collect_dataset, load_dataset
    from masspush.learn.push_density import (
        DensityConfig,
        load_push_density,
        train_push_density,
    )

    episodes = collect_randomised(replace(TINY, model="rp"), tmp_path / "r", workers=1,
                                  progress=False)  # fmt: skip
    manifest, loaded = load_dataset(tmp_path / "r")
    assert (manifest.worlds, manifest.policy, manifest.episodes) == ("randomised", "random", 4)
    np.testing.assert_array_equal(loaded.observations, episodes.observations)
    small = dict(steps=2, batch_size=8, width=8, depth=1, components=1)
    out = tmp_path / "d.pt"
    train_push_density(DensityConfig(data=(str(tmp_path / "r"),), out=str(out), **small),
                       progress=False)  # fmt: skip
    assert load_push_density(out).meta["worlds"] == "randomised"
    collect_dataset(CollectConfig(setting=SETTING, out=str(tmp_path / "s"), episodes=4),
                    progress=False)  # fmt: skip
    mixed = DensityConfig(data=(str(tmp_path / "s"), str(tmp_path / "r")), out=str(out), **small)
    with pytest.raises(ValueError, match="has worlds 'randomised'"):
        train_push_density(mixed, progress=False)
    # A collected dataset is never overwritten by randomised episodes.
    with pytest.raises(ValueError, match="holds a dataset of `masspush collect`"):
        collect_randomised(TINY, tmp_path / "s", workers=1, progress=False)


def test_the_fine_tuned_predictor_keeps_its_policy_and_names_its_worlds(tmp_path):
    from masspush.learn.predictor import load_model

    path = randomise(TINY, tmp_path, workers=1, progress=False)
    _, meta = load_model(path, SETTING)
    assert list(meta["randomised"]["ranges"]["solvers"]) == list(WorldRanges().solvers)
    assert meta["finetuned_from"].endswith("tp+.pt")
    assert meta["policy"] == "learned"
    with pytest.raises(ValueError, match="ships the shipped tp"):
        randomise(replace(TINY, model="rp"), tmp_path / "rp", ship=True, progress=False)
    with pytest.raises(ValueError, match="ships the shipped tp"):
        randomise(
            RandomiseConfig(setting=SETTING, model=str(path), episodes=4, shard_size=2, steps=4),
            tmp_path / "again", workers=1, ship=True, progress=False,
        )  # fmt: skip


@pytest.mark.slow
def test_the_tuned_predictor_pushes_with_its_policy_where_it_is_and_where_it_ships(
    tmp_path, monkeypatch
):
    import shutil

    from masspush import models
    from masspush.models import model_and_policy

    shipped = tmp_path / "models" / SETTING
    shipped.mkdir(parents=True)
    for name in ("tp+.pt", "tp+.policy.zip"):
        shutil.copyfile(models.SHIPPED_DIR / SETTING / name, shipped / name)
    monkeypatch.setattr(models, "SHIPPED_DIR", tmp_path / "models")
    trained = randomise(TINY, tmp_path / "run", workers=1, progress=False)
    path = randomise(TINY, tmp_path / "run", workers=1, ship=True, progress=False)
    assert path == shipped / "tp+dr.pt"
    for model in (trained, path):
        _, meta, policy = model_and_policy(model, SETTING)
        assert type(policy).__name__ == "LearnedPolicy"
        assert (model.parent / meta["policy_file"]).resolve() == shipped / "tp+.policy.zip"
    assert model_and_policy(path, SETTING)[1]["policy_file"] == "tp+.policy.zip"


@pytest.mark.slow
def test_episodes_can_come_from_the_target_world_itself_but_do_not_ship(tmp_path):
    config = replace(TINY, world="target")
    assert config.worlds == TargetWorld() and TINY.worlds == WorldRanges()
    target = collect_randomised(config, tmp_path / "target", workers=1, progress=False)
    drawn = collect_randomised(TINY, tmp_path / "drawn", workers=1, progress=False)
    # The same seeds, other episodes: the target world's are those of that world's robot.
    assert not np.array_equal(target.observations, drawn.observations)
    robot = TargetWorldRobot(SETTING, world=config.worlds, seed=int(target.seed[0]))
    robot.start()
    np.testing.assert_allclose(robot.truth["masses"], target.masses[0], rtol=1e-6)
    with pytest.raises(ValueError, match="not a model to ship"):
        randomise(config, tmp_path / "target", ship=True, progress=False)
    with pytest.raises(ValueError, match="world must be one of"):
        RandomiseConfig(world="real")


@pytest.mark.slow
def test_the_policy_can_be_trained_on_in_randomised_worlds(tmp_path):
    from masspush.models import model_and_policy
    from masspush.real.randomisation import SHIPPED_POLICY_NAME

    config = replace(TINY, policy_steps=8, policy_envs=1, policy_rollout=4)
    assert config.shipped_name == SHIPPED_POLICY_NAME
    path = randomise(config, tmp_path, workers=1, progress=False)
    _, meta, policy = model_and_policy(path, SETTING)
    assert type(policy).__name__ == "LearnedPolicy"
    assert (tmp_path / "policy" / "policy.zip").exists()
    assert (path.parent / meta["policy_file"]).resolve() == tmp_path / "policy" / "policy.zip"
    assert meta["randomised"]["policy_steps"] == 8
    # The episodes are the new policy's pushes, not the model's own.
    kept = collect_randomised(TINY, tmp_path / "kept", workers=1, progress=False)
    trained = collect_randomised(config, tmp_path, workers=1, progress=False,
                                 model_file=tmp_path / "pushing-model.pt")  # fmt: skip
    assert not np.array_equal(kept.actions, trained.actions)
    with pytest.raises(ValueError, match="policy_steps"):
        RandomiseConfig(policy_steps=-1)


def test_episodes_can_all_come_from_one_lab_of_the_target_world():
    from masspush.models import resolve_model
    from masspush.real.target_world import Lab

    model = resolve_model("rp", SETTING)
    one = run_randomised(SETTING, model, TargetWorld(), np.array([0, 1, 2]), 11, lab=5)
    many = run_randomised(SETTING, model, TargetWorld(), np.array([0, 1, 2]), 11)
    robot = TargetWorldRobot(SETTING, seed=0, lab=5)
    lab = Lab(5, robot.world, robot.physics)
    # The lab's constants in every episode (its friction, its chain); a new lab otherwise.
    np.testing.assert_allclose(one.friction, lab.friction, rtol=1e-6)
    np.testing.assert_allclose(one.lengths, np.tile(lab.told_lengths, (3, 1)), rtol=1e-6)
    assert len(set(np.round(many.friction, 6))) == 3
    with pytest.raises(ValueError, match="pass world=target"):
        RandomiseConfig(lab=5)
