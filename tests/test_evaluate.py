import dataclasses
import json
import subprocess
import sys

import pytest

from masspush.evaluate import EvaluateConfig, evaluate
from masspush.models import evaluate_model
from masspush.settings import get_setting

KEYS = {"percentage_error", "relative_error", "mae", "constant_floor", "episodes", "failures"}


@pytest.mark.slow
def test_evaluate_json_has_the_documented_keys(model_file):
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "masspush.cli",
            "evaluate",
            "--setting",
            "2link-0.1-1",
            "--model",
            str(model_file),
            "--episodes",
            "30",
            "--seed",
            "4",
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)
    assert KEYS <= set(result)
    assert result["episodes"] + result["failures"] == 30
    assert result["pusher"] == "stiff" and result["policy"] == "random"
    assert len(result["percentage_error_after_each_push"]) == 2


def test_evaluation_is_deterministic_and_seeded(model_file):
    a = evaluate_model(
        EvaluateConfig("2link-0.1-1", str(model_file), episodes=20, seed=1)
    ).to_dict()
    b = evaluate_model(
        EvaluateConfig("2link-0.1-1", str(model_file), episodes=20, seed=1)
    ).to_dict()
    c = evaluate_model(
        EvaluateConfig("2link-0.1-1", str(model_file), episodes=20, seed=2)
    ).to_dict()
    assert a == b and a["mae"] != c["mae"]


@pytest.mark.slow
def test_per_episode_records_pair_a_learned_model_with_the_filter(model_file):
    from masspush.bayes.estimator import BayesEstimator
    from masspush.bayes.filter import BayesConfig
    from masspush.metrics import paired_percentage_errors

    learned = evaluate_model(
        EvaluateConfig("2link-0.1-1", str(model_file), episodes=4, per_episode=True)
    ).to_dict()
    assert (
        "per_episode"
        not in evaluate_model(EvaluateConfig("2link-0.1-1", str(model_file), episodes=2)).to_dict()
    )
    small = BayesConfig(particles=16, lookahead_particles=4)
    setting = get_setting("2link-0.1-1")
    estimator = BayesEstimator(setting, "bayes-random", "stiff", config=small, progress=False)
    filt = evaluate(setting, estimator, episodes=3, per_episode=True).to_dict()
    record = learned["per_episode"]
    assert len(record["index"]) == learned["episodes"] == len(record["estimate"])
    # The same evaluation stream: the episodes both scored have the same chains (the
    # truths must agree, or the pairing raises).
    bayes_err, learned_err, n = paired_percentage_errors(filt["per_episode"], record)
    assert n == len(set(filt["per_episode"]["index"]) & set(record["index"])) >= 2
    assert bayes_err > 0 and learned_err > 0


def test_the_cli_pairs_an_evaluation_with_an_earlier_one(model_file, tmp_path, capsys):
    from masspush.cli import main

    args = ["evaluate", "--setting", "2link-0.1-1", "--model", str(model_file), "--episodes", "3"]
    assert main([*args, "--per-episode", "--json"]) == 0
    first = tmp_path / "first.json"
    first.write_text(capsys.readouterr().out)
    assert main([*args, "--paired-with", str(first), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    # The same model on the same episodes: the pairing finds them all and both agree.
    paired = result["paired"]
    assert paired["episodes"] == result["episodes"]
    assert paired["percentage_error"] == pytest.approx(paired["their_percentage_error"])
    assert paired["difference_95_interval"] == pytest.approx([0.0, 0.0], abs=1e-9)
    # The record keeps 6 decimals of each share, so the paired figure agrees to rounding.
    assert paired["percentage_error"] == pytest.approx(result["percentage_error"], rel=1e-4)
    bare = tmp_path / "bare.json"
    bare.write_text(json.dumps({"model": "x"}))
    assert main([*args, "--paired-with", str(bare)]) == 2
    assert "no per-episode record" in capsys.readouterr().err


@pytest.mark.slow
def test_an_evaluation_on_a_ray_cluster_gives_the_same_numbers(model_file, ray_cluster):
    config = EvaluateConfig("2link-0.1-1", str(model_file), episodes=30, seed=3,
                            per_episode=True)  # fmt: skip
    here = evaluate_model(config).to_dict()
    on_ray = evaluate_model(dataclasses.replace(config, ray=ray_cluster)).to_dict()
    assert on_ray == here
