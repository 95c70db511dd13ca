from dataclasses import replace

import pytest

from masspush.reports.bench import (
    DataBench,
    PPOBench,
    TrainBench,
    bench_data,
    bench_ppo,
    bench_train,
)


@pytest.mark.slow
def test_collection_and_training_benchmarks_report_rates():
    data = bench_data(DataBench("2link-0.1-1", "stiff", episodes=20))
    assert data["episodes_per_s"] > 0 and data["pushes_per_s"] == 2 * data["episodes_per_s"]
    rows = bench_train(TrainBench(episodes=60, steps=20))
    assert [r["batch_size"] for r in rows] == [16, 256]
    assert all(r["samples_per_s"] > 0 for r in rows)


@pytest.mark.slow
def test_ppo_benchmark_reports_a_rate_per_learner():
    rows = bench_ppo(PPOBench("2link-0.1-1", "stiff", ("mlp",), steps=16, envs=(4,), n_steps=8))
    assert len(rows) == 1 and rows[0]["pushes_per_s"] > 0
    assert rows[0]["pushes"] == 32  # PPO completes its rollout of 4 x 8


@pytest.mark.slow
def test_ppo_benchmark_runs_an_arm_in_lockstep_by_default_or_in_processes():
    from masspush.sim.pushers import compiled

    if compiled.library() is None:
        pytest.skip("the arms' lockstep runs the compiled law")
    bench = PPOBench("2link-0.1-1", "kuka", ("mlp",), steps=16, envs=(4,), n_steps=8)
    rows = bench_ppo(bench)
    assert rows[0]["lockstep_arms"] is True and rows[0]["pushes"] == 32
    # Then worker processes, in the same process as MuJoCo's batch threads: workers forked
    # from such a process once hung; they now start from a fork server.
    rows = bench_ppo(replace(bench, lockstep_arms=False))
    assert rows[0]["lockstep_arms"] is False and rows[0]["pushes"] == 32


@pytest.mark.slow
def test_bench_arm_reports_both_throughputs_and_checks_the_compiled_law():
    from masspush.reports.bench import ArmBench, bench_arm

    result = bench_arm(ArmBench(episodes=4, check_pushes=2, workers=1))
    assert result["arm_pushes_per_s"] > 0 and result["stiff_pushes_per_s"] > 0
    assert result["ratio"] == pytest.approx(
        result["arm_pushes_per_s"] / result["stiff_pushes_per_s"]
    )
    assert result["goal"] == 0.6 and result["meets_goal"] == (result["ratio"] >= 0.6)
    assert result["identical"] and result["largest_difference"] <= 1e-9
    assert result["arm_steps_per_push"] > 0 and result["stiff_steps_per_push"] > 0
    assert result["arm_engine"] == ("lockstep" if result["compiled"] else "processes")
