import json
from dataclasses import replace

import numpy as np
import pytest

from masspush import models as models_module
from masspush.data.dataset import load_dataset
from masspush.evaluate import EvaluateConfig
from masspush.learn import recipe as train_module
from masspush.learn.policy import PolicyConfig
from masspush.learn.predictor import (
    ModelMismatchError,
    PredictorEnsemble,
    load_model,
    recorded_config,
)
from masspush.learn.recipe import FINAL_FINETUNE, FINETUNE, PREDICTOR, Recipe, RecipeConfig
from masspush.models import evaluate_model
from masspush.reports.reproduction import (
    collect_rows,
    recipe_summary,
    ship_recipe,
    table_markdown,
    write_outputs,
)
from masspush.settings import get_setting

SETTING = get_setting("2link-0.1-1")
TINY = RecipeConfig(
    meta_iterations=2,
    first_episodes=1500,
    iteration_episodes=200,
    final_episodes=200,
    policy=PolicyConfig(algo="mlp", n_envs=2, steps=64, n_steps=16),
    predictor=replace(PREDICTOR, steps=1500, batch_size=128, eval_every=500),
    finetune=replace(FINETUNE, steps=100, batch_size=64, eval_every=50, checkpoint_every=50),
    final_finetune=replace(FINETUNE, steps=100, batch_size=64, eval_every=50),
    eval_episodes=200,
)


class Interrupted(Exception):
    pass


@pytest.mark.slow
def test_a_short_recipe_resumes_after_interruption_and_beats_the_floor(tmp_path, monkeypatch):
    run = tmp_path / "runs" / "2link-0.1-1-stiff-train"
    calls: list[str] = []
    real_collect = train_module.collect

    def counting_collect(setting, out, **kwargs):
        calls.append(out.name)
        return real_collect(setting, out, **kwargs)

    monkeypatch.setattr(train_module, "collect", counting_collect)
    real_train_policy = Recipe._train_policy

    def killed_in_policy_2(self, i):
        if i == 2:
            raise Interrupted
        real_train_policy(self, i)

    monkeypatch.setattr(Recipe, "_train_policy", killed_in_policy_2)
    with pytest.raises(Interrupted):
        Recipe(SETTING, "stiff", run, TINY, progress=False).run()
    assert calls == ["data-0", "data-1"]
    monkeypatch.setattr(Recipe, "_train_policy", real_train_policy)
    state = Recipe(SETTING, "stiff", run, TINY, progress=False).run()
    assert calls == ["data-0", "data-1", "data-2", "data-final"]  # nothing done twice
    stages = [h["stage"] for h in state["history"]]
    assert stages == ["predictor-0", "predictor-1", "predictor-2", "predictor-final"]
    first = state["history"][0]
    assert first["percentage_error"] < 0.9 * first["constant_floor"], first
    # A 64-step policy has barely moved from its initial action, and the tiny predictors
    # are fine-tuned on a few dozen episodes, so the later errors are only checked finite.
    assert all(np.isfinite(h["percentage_error"]) for h in state["history"])
    assert {"policy-1", "data-final", "predictor-final"} <= set(state["timings"])

    # TP and TP+ ship as files that load by name and refuse another setting; with no RP
    # shipped for the setting, predictor-0 ships as its random-push RP.
    models = tmp_path / "models"
    monkeypatch.setattr(models_module, "SHIPPED_DIR", models)
    shipped = ship_recipe(Recipe(SETTING, "stiff", run, TINY, progress=False), root=tmp_path)
    assert (tmp_path / "results" / "runs" / f"{SETTING.name}-stiff-train.json").exists()
    assert {p.name for p in shipped} == {
        "rp.pt", "tp.pt", "tp.policy.zip", "tp+.pt", "tp+.policy.zip"
    }  # fmt: skip
    assert load_model(models / SETTING.name / "rp.pt")[1]["policy"] == "random"
    again = ship_recipe(Recipe(SETTING, "stiff", run, TINY, progress=False), root=tmp_path)
    assert "rp.pt" not in {p.name for p in again}  # an RP already there is kept
    _, meta = load_model(models / SETTING.name / "tp+.pt", setting=SETTING.name, pusher="stiff")
    assert meta["policy"] == "learned" and meta["setting"]["name"] == SETTING.name
    result = evaluate_model(EvaluateConfig(SETTING.name, "tp+", episodes=200)).to_dict()
    final = state["history"][-1]
    assert result["policy"].startswith("learned") and result["mae"] == pytest.approx(final["mae"])
    with pytest.raises(ModelMismatchError, match=r"2link-0\.1-1"):
        evaluate_model(
            EvaluateConfig("2link-1-10", str(models / SETTING.name / "tp+.pt"), episodes=5)
        )

    # The table and figures come from the run's files.
    rows = collect_rows([SETTING.name], {SETTING.name: "stiff"}, root=tmp_path)
    assert rows[0]["tp+"] == pytest.approx(final["percentage_error"]) and rows[0]["rp"] is None
    assert "6.07" in table_markdown(rows)  # the paper's TP+ beside ours
    for path in write_outputs([SETTING.name], {SETTING.name: "stiff"}, root=tmp_path):
        assert path.stat().st_size > 0
    times = (tmp_path / "results" / "recipe-times.md").read_text()
    assert f"| {SETTING.name} | 2 x " in times  # one row per finished run

    # A resized final stage redoes only itself: data-final grows, predictor-final retrains.
    bigger = replace(
        TINY, final_episodes=300, final_finetune=replace(TINY.final_finetune, steps=60)
    )
    state = Recipe(SETTING, "stiff", run, bigger, progress=False).run()
    assert calls == ["data-0", "data-1", "data-2", "data-final", "data-final"]
    assert load_dataset(run / "data-final")[0].episodes == 300
    assert [h["stage"] for h in state["history"]] == stages
    assert state["final"] == {
        "episodes": 300, "finetune": recorded_config(bigger.final_finetune), "members": 1
    }  # fmt: skip
    assert json.loads((run / "predictor-final" / "config.json").read_text())["train"]["steps"] == 60
    # Resumed without final sizes, the run keeps the ones it recorded.
    plain = replace(bigger, final_episodes=None, final_finetune=None)
    assert Recipe(SETTING, "stiff", run, plain, progress=False).run()["final"] == state["final"]
    assert calls.count("data-final") == 2

    # TP+ as two predictors averaged: only predictor-final is trained again, twice, from
    # scratch, and ships and evaluates as any model.
    real_ensemble, inits = train_module.train_ensemble, []

    def spy_ensemble(*args, **kwargs):
        inits.append(args[6] if len(args) > 6 else kwargs.get("init"))
        return real_ensemble(*args, **kwargs)

    monkeypatch.setattr(train_module, "train_ensemble", spy_ensemble)
    state = Recipe(SETTING, "stiff", run, replace(plain, final_members=2), progress=False).run()
    assert state["final"]["members"] == 2 and inits == [None]
    assert calls.count("data-final") == 2  # the same episodes: data-final is not redone
    assert load_dataset(run / "data-final")[0].episodes == 300
    assert [h["stage"] for h in state["history"]] == stages
    assert {p.name for p in (run / "predictor-final").glob("member-*")} == {"member-0", "member-1"}
    assert isinstance(load_model(run / "predictor-final" / "predictor.pt")[0], PredictorEnsemble)
    ship_recipe(Recipe(SETTING, "stiff", run, plain, progress=False), root=tmp_path)
    result = evaluate_model(EvaluateConfig(SETTING.name, "tp+", episodes=200)).to_dict()
    assert result["mae"] == pytest.approx(state["history"][-1]["mae"])
    assert "TP+ on 0.3k, 0.06k steps, 2 averaged" in recipe_summary(state, SETTING.name)

    # A wide TP+ alone trains from scratch too: predictor-M's weights cannot seed it.
    real_train, starts = train_module.train_predictor, []

    def spy_train(*args, **kwargs):
        starts.append(kwargs.get("init"))
        return real_train(*args, **kwargs)

    monkeypatch.setattr(train_module, "train_predictor", spy_train)
    wide = replace(plain, final_members=1, final_finetune=replace(bigger.final_finetune, width=16))
    state = Recipe(SETTING, "stiff", run, wide, progress=False).run()
    assert starts == [None] and load_model(run / "predictor-final" / "predictor.pt")[0].width == 16
    assert "TP+ on 0.3k, 0.06k steps, 16 wide" in recipe_summary(state, SETTING.name)


def test_a_runs_final_stage_is_kept_unless_other_sizes_are_given(tmp_path):
    plain = replace(TINY, final_episodes=None, final_finetune=None)
    quiet = {"log": lambda _: None}
    # A new run takes the defaults: 4x data-0's episodes, FINAL_FINETUNE.
    fresh = Recipe(SETTING, "stiff", tmp_path / "new", plain, **quiet)._state()
    assert fresh["final"] == {
        "episodes": 4 * 1500, "finetune": recorded_config(FINAL_FINETUNE), "members": 1
    }  # fmt: skip

    recipe = Recipe(SETTING, "stiff", tmp_path, plain, **quiet)
    old = recipe._identity()
    del old["final_finetune"]  # as runs made before it recorded their config
    done = {"data-final": 30.0, "predictor-final": 5.0, "evaluate-final": 1.0, "policy-2": 9.0}
    history = [{"stage": "predictor-2"}, {"stage": "predictor-final"}]

    logs = []

    def state_of(config):
        recipe.state_path.write_text(
            json.dumps({"config": old, "timings": dict(done), "history": list(history)})
        )
        (tmp_path / "predictor-final").mkdir(exist_ok=True)
        return Recipe(SETTING, "stiff", tmp_path, config, log=logs.append)._state()

    # Made before the record: first_episodes' worth with the `finetune` config. Resumed
    # without final sizes, or with those same sizes, it keeps its final stage.
    made = {"episodes": 1500, "finetune": recorded_config(TINY.finetune), "members": 1}
    for config in (plain, replace(plain, final_episodes=1500, final_finetune=TINY.finetune)):
        kept = state_of(config)
        assert kept["timings"] == done and kept["history"] == history
        assert kept["final"] == made and (tmp_path / "predictor-final").exists()
    # Other sizes redo it, keeping data-final's time to add to.
    redone = state_of(replace(plain, final_episodes=6000))
    assert redone["final"] == {**made, "episodes": 6000}
    assert redone["timings"] == {"policy-2": 9.0} and redone["carried"] == {"data-final": 30.0}
    assert redone["history"] == history[:1] and not (tmp_path / "predictor-final").exists()
    lr = TINY.finetune.lr
    assert logs[-1].endswith(
        f"run with 1500 episodes, {TINY.finetune.steps} steps at lr {lr:g}; "
        f"redoing it with 6000 episodes, {TINY.finetune.steps} steps at lr {lr:g}"
    )
    # A cut keeps the time of the episodes it keeps.
    assert state_of(replace(plain, final_episodes=500))["carried"] == {"data-final": 10.0}
    # More predictors averaged redo the training only: data-final stays done.
    averaged = state_of(replace(plain, final_members=3))
    assert averaged["final"] == {**made, "members": 3}
    assert averaged["timings"] == {"policy-2": 9.0, "data-final": 30.0}
    assert "data-final" not in averaged.get("carried", {})
    assert logs[-1].endswith(f"at lr {lr:g}, 3 predictors averaged")
    # Another loss redoes the training only, and says so.
    l1 = state_of(replace(plain, final_finetune=replace(TINY.finetune, loss="l1")))
    assert l1["final"]["finetune"] == {**made["finetune"], "loss": "l1"}
    assert l1["timings"] == {"policy-2": 9.0, "data-final": 30.0}
    assert logs[-1].endswith(f"at lr {lr:g}, l1 loss")
    # So does another width.
    wide = state_of(replace(plain, final_finetune=replace(TINY.finetune, width=32)))
    assert wide["final"]["finetune"] == {**made["finetune"], "width": 32}
    assert wide["timings"] == {"policy-2": 9.0, "data-final": 30.0}
    assert logs[-1].endswith(f"at lr {lr:g}, 32 wide")
    # A run that recorded its final stage before ensembles trained one predictor.
    recipe.state_path.write_text(json.dumps({
        "config": old, "timings": dict(done), "history": list(history),
        "final": {"episodes": 1500, "finetune": recorded_config(TINY.finetune)},
    }))  # fmt: skip
    kept = Recipe(SETTING, "stiff", tmp_path, plain, log=logs.append)._state()
    assert kept["final"] == made and kept["timings"] == done
    # Anything else that differs is still refused.
    with pytest.raises(ValueError, match=r"\(meta_iterations\)"):
        state_of(replace(plain, meta_iterations=3))


def test_a_run_directory_refuses_another_config(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    other = replace(TINY, meta_iterations=1)
    (run / "state.json").write_text('{"config": {"x": 1}, "timings": {}, "history": []}')
    with pytest.raises(ValueError, match="another setting, pusher or config"):
        Recipe(SETTING, "stiff", run, other, progress=False).run()


def test_a_run_made_before_a_policy_field_resumes_only_with_that_fields_old_value(tmp_path):
    import json

    def recorded(pusher, policy):
        recipe = Recipe(SETTING, pusher, tmp_path / pusher, replace(TINY, policy=policy))
        return recipe, recipe._identity()

    # An arm's run from before the lockstep (processes) recorded no `lockstep_arms`.
    _, old = recorded("kuka", replace(TINY.policy, lockstep_arms=False))
    assert "lockstep_arms" not in old["policy"]
    recipe, new = recorded("kuka", TINY.policy)
    assert new["policy"]["lockstep_arms"] is True
    recipe.dir.mkdir()
    recipe.state_path.write_text(json.dumps({"config": old, "timings": {}, "history": []}))
    with pytest.raises(ValueError, match=r"\(policy.lockstep_arms\); use another --out"):
        recipe._state()
    # The stiff pusher always ran in lockstep: the field never enters its runs' identity.
    assert "lockstep_arms" not in recorded("stiff", TINY.policy)[1]["policy"]


def test_a_run_made_before_the_loss_field_resumes_with_mse_only(tmp_path):
    import json

    recipe = Recipe(SETTING, "stiff", tmp_path, TINY, progress=False)
    old = recipe._identity()
    assert "loss" not in old["predictor"] and "loss" not in old["finetune"]  # as runs said
    recipe.state_path.write_text(json.dumps({"config": old, "timings": {}, "history": []}))
    assert recipe._state()["config"] == old
    l1 = replace(TINY, predictor=replace(TINY.predictor, loss="l1"))
    with pytest.raises(ValueError, match=r"\(predictor.loss\); use another --out"):
        Recipe(SETTING, "stiff", tmp_path, l1, progress=False)._state()


def test_bad_recipe_configs_are_refused():
    with pytest.raises(ValueError, match="meta_iterations"):
        RecipeConfig(meta_iterations=0)
    with pytest.raises(ValueError, match="first_episodes"):
        RecipeConfig(first_episodes=1)
    for members in (0, 17):
        with pytest.raises(ValueError, match=f"final_members must be in 1..16, got {members}"):
            RecipeConfig(final_members=members)
    assert RecipeConfig().episodes(2) == (16_000, 8_000, 64_000)
    assert RecipeConfig().episodes(3) == (32_000, 16_000, 128_000)
    assert np.isclose(TINY.policy.rollout_steps, 16)


@pytest.mark.slow
def test_the_recipe_runs_its_collections_and_evaluations_on_a_pool(tmp_path, serial_pool):
    from masspush.data.dataset import collect
    from masspush.evaluate import evaluate
    from masspush.learn.estimator import PredictorEstimator

    small = replace(
        TINY, meta_iterations=1, first_episodes=300, eval_episodes=60,
        predictor=replace(PREDICTOR, steps=100, batch_size=64, eval_every=50),
    )  # fmt: skip
    pool = serial_pool(size=2)
    run = Recipe(SETTING, "stiff", tmp_path / "run", small, progress=False, workers=pool)
    state = run.run()
    assert pool.tasks > 0
    collect(SETTING, tmp_path / "here", episodes=300, pusher="stiff", base_seed=0,
            progress=False)  # fmt: skip
    for shard in (tmp_path / "here").glob("shard-*.npz"):
        assert (tmp_path / "run" / "data-0" / shard.name).read_bytes() == shard.read_bytes()
    here = evaluate(SETTING, PredictorEstimator.from_file(run.predictor(0), SETTING.name), 60)
    assert state["history"][0]["percentage_error"] == here.percentage_error
