import json
import subprocess
import sys
from dataclasses import replace

import pytest

from masspush.cli import build_parser, main


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "masspush.cli", *args], capture_output=True, text=True, timeout=300
    )


@pytest.mark.slow
def test_demo_prints_each_push_and_the_estimate_and_draws_them(tmp_path):
    picture = tmp_path / "demo.png"
    result = run_cli("demo", "--model", "rp+", "--seed", "4", "--out", str(picture))
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "mass distribution" in out and "random policy" in out
    assert out.count("estimate ") == 2 and "q2 =" in out  # two pushes, two estimates
    assert picture.stat().st_size > 10_000


def test_bad_cli_input_is_a_clear_error(capsys):
    assert main(["demo", "--setting", "4link"]) == 2
    assert "unknown setting" in capsys.readouterr().err
    assert main(["demo", "--setting", "3link-1-10", "--model", "nothing.pt"]) == 2
    assert "no model file" in capsys.readouterr().err


@pytest.mark.slow
def test_bench_sim_reports_all_paths():
    result = run_cli("bench", "sim", "--chains", "32", "--env-pushes", "10", "--json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    for key in ("env_pushes_per_s", "batch_pushes_per_s", "ceiling_pushes_per_s"):
        assert report[key] > 0
    assert 0 <= report["failure_rate"] < 0.2


@pytest.mark.slow
def test_demo_is_reproducible_from_its_seed(tmp_path):
    def demo(seed: str) -> str:
        return run_cli("demo", "--model", "rp+", "--seed", seed, "--out", str(tmp_path / "d.png"))

    first, second = demo("5"), demo("5")
    assert first.returncode == 0 and first.stdout == second.stdout
    assert demo("6").stdout != first.stdout


@pytest.mark.slow
def test_reproduce_table_only_writes_the_table_beside_the_papers(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["reproduce", "--settings", "2link-0.1-1,3link-1-10", "--table-only"]) == 0
    table = (tmp_path / "results" / "table1.md").read_text()
    assert "| 3link-1-10 | stiff |" in table and "15.99" in table  # the paper's TP+
    assert table.count("not yet") == 8  # nothing run here yet
    assert (tmp_path / "results" / "meta-iterations.png").stat().st_size > 0
    assert main(["train", "--setting", "4link"]) == 2
    assert "unknown setting" in capsys.readouterr().err


@pytest.mark.slow
def test_randomise_collects_fine_tunes_and_names_the_result(tmp_path, capsys):
    out = tmp_path / "dr"
    args = ["randomise", "--setting", "2link-1-10", "--episodes", "3", "--steps", "2"]
    assert main([*args, "--workers", "1", "--out", str(out)]) == 0
    assert f"randomised predictor: {out / 'predictor' / 'predictor.pt'}" in capsys.readouterr().out
    assert len(list(out.glob("shard-*.npz"))) == 1


def test_randomise_passes_the_policy_training_on(tmp_path, monkeypatch, capsys):
    import masspush.real.randomisation

    seen = {}

    def fake(config, out, workers, ship):
        seen.update(config=config, out=out)
        return tmp_path / "p.pt"

    monkeypatch.setattr(masspush.real.randomisation, "randomise", fake)
    main(["randomise", "--setting", "2link-1-10", "--policy-steps", "500", "--envs", "3"])
    assert (seen["config"].policy_steps, seen["config"].policy_envs) == (500, 3)
    assert seen["config"].shipped_name == "tp+drp"
    assert seen["out"] == "runs/randomise-2link-1-10-policy"
    main(["randomise", "--setting", "2link-1-10", "--world", "target"])
    assert seen["config"].world == "target"
    assert seen["out"] == "runs/randomise-2link-1-10-target"
    main(["randomise", "--setting", "2link-1-10", "--world", "target", "--lab", "5"])
    assert seen["config"].lab == 5
    assert seen["out"] == "runs/randomise-2link-1-10-target-lab5"


def test_a_warning_is_one_line_said_once(monkeypatch, capsys):
    import warnings

    import masspush.real.randomisation

    def fake(config, out, workers, ship):
        for line in (1, 2):  # two places in masspush say the same
            warnings.warn_explicit("density trained on executed pushes\nsecond line", UserWarning,
                                   "f.py", line, module="masspush.learn.push_density")  # fmt: skip
        return "p.pt"

    monkeypatch.setattr(masspush.real.randomisation, "randomise", fake)
    main(["randomise", "--setting", "2link-1-10"])
    err = capsys.readouterr().err
    assert err == "masspush randomise: warning: density trained on executed pushes second line\n"


@pytest.mark.slow
def test_run_on_one_lab_of_the_target_world_records_it(tmp_path, capsys):
    out = tmp_path / "lab.jsonl"
    args = ["run", "--robot", "target", "--setting", "2link-1-10", "--model", "tp+",
            "--count", "2", "--lab", "1", "--record", str(out)]  # fmt: skip
    assert main(args) == 0
    assert capsys.readouterr().out.count("estimate ") >= 2
    from masspush.data.recording import read_recording

    episodes = read_recording(out).episodes
    assert len(episodes) == 2 and episodes[0]["lengths"].tolist() == episodes[1]["lengths"].tolist()
    assert main(["run", "--robot", "stiff", "--setting", "2link-1-10", "--lab", "1"]) == 2
    assert "lab" in capsys.readouterr().err


@pytest.mark.parametrize(
    "command",
    [
        ["collect", "--setting", "2link-1-10", "--episodes", "5", "--out", "unused"],
        ["evaluate", "--setting", "2link-1-10", "--model", "rp"],
        ["baselines", "--setting", "2link-1-10"],
        ["train", "--setting", "2link-1-10"],
        ["bayes-table"],
        ["sim2real"],
    ],
)
def test_every_command_that_scales_out_takes_ray_and_checks_its_address(command, capsys):
    assert main([*command, "--ray", "nowhere"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0
    assert f"masspush {command[0]}: error: ray must be auto, local, ray://HOST:PORT" in err


def test_train_builds_tp_plus_fine_tuning_from_the_final_options(capsys):
    from masspush.cli.train import _recipe
    from masspush.learn.recipe import FINAL_FINETUNE

    def recipe(*options):
        return _recipe(build_parser().parse_args(["train", "--setting", "2link-1-10", *options]))

    # Without them the run's recorded fine-tuning stands (None until the run is read).
    assert recipe().final_finetune is None
    assert recipe("--final-steps", "5000").final_finetune == replace(FINAL_FINETUNE, steps=5000)
    tuned = recipe("--final-lr", "0.001", "--final-steps", "40000").final_finetune
    assert (tuned.lr, tuned.steps, tuned.optimizer) == (1e-3, 40000, FINAL_FINETUNE.optimizer)
    # Bad values name the option the user typed, before any work.
    assert main(["train", "--setting", "2link-1-10", "--final-steps", "0"]) == 2
    assert "--final-steps must be >= 1" in capsys.readouterr().err
    assert main(["train", "--setting", "2link-1-10", "--final-lr", "20"]) == 2
    assert "--final-lr must be in (0, 10)" in capsys.readouterr().err
    # TP+ as several predictors averaged: none given, the run's own; a bad count, refused.
    assert recipe().final_members is None
    assert recipe("--final-members", "3").final_members == 3
    assert main(["train", "--setting", "2link-1-10", "--final-members", "0"]) == 2
    assert "final_members must be in 1..16, got 0" in capsys.readouterr().err


def test_sim2real_runs_the_particle_filter_arm_with_a_density(density_file, tmp_path, capsys):
    out = tmp_path / "s2r"
    args = ["sim2real", "--setting", "2link-1-10", "--world", "training", "--learned-model",
            "bayes", "--density", str(density_file), "--episodes-per-class", "2",
            "--folds", "2", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    assert "| learned | bayes |" in capsys.readouterr().out
    assert "weighing pushes with density.pt" in (out / "learned.jsonl").read_text()
