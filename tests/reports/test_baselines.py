import json

import pytest

import masspush.models as models_module
import masspush.reports.baselines as baselines
from masspush.evaluate import EvaluateConfig
from masspush.learn.predictor import TrainConfig
from masspush.models import evaluate_model


@pytest.mark.slow
def test_baselines_recipe_end_to_end_and_shipping(tmp_path, monkeypatch):
    tiny = TrainConfig(
        optimizer="adam", steps=200, batch_size=32, lr=3e-3, eval_every=100, features="relative"
    )
    results = baselines.run_baselines(
        "2link-0.1-1", "stiff", tiny, eval_episodes=40, root=tmp_path, episodes=(60, 120)
    )
    written = json.loads((tmp_path / "results" / "2link-0.1-1-stiff-baselines.json").read_text())
    assert written == json.loads(json.dumps(results))
    for name, n in (("rp", 60), ("rp+", 120)):
        model = results["models"][name]
        assert model["train_episodes"] == n >= model["usable_episodes"]
        assert {"percentage_error", "constant_floor", "failures"} <= set(model)
    assert set(results["timings"]) >= {"collect_s", "train_rp_s", "train_rp+_s"}
    # Shipping puts the models where `--model rp` finds them.
    monkeypatch.setattr(models_module, "SHIPPED_DIR", tmp_path / "models")
    baselines.ship_baselines("2link-0.1-1", "stiff", root=tmp_path)
    shipped = evaluate_model(EvaluateConfig("2link-0.1-1", "rp", episodes=40)).to_dict()
    assert shipped["mae"] == results["models"]["rp"]["mae"]  # same model, same episodes
    table = baselines.baselines_table("stiff", root=tmp_path)
    row = next(line for line in table.splitlines() if line.startswith("| 2link-0.1-1 "))
    assert f"**{results['models']['rp']['percentage_error']:.2f}**" in row and "15.26" in row
    assert table.count("not yet") == 10  # the five settings without results, RP and RP+
