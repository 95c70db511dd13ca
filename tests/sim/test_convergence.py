import pytest

from masspush.sim.convergence import format_table, validate_physics


@pytest.mark.slow
def test_validation_reports_every_comparison_and_slow_pushes_are_not_chaotic():
    rows = validate_physics(n_links=2, pushes=8, timesteps=(0.002, 0.001), seed=3, progress=False)
    labels = {r.label for r in rows}
    assert labels == {"dt 2 ms", "dt 1 ms", "1e-6 rad perturbation"}
    assert all(r.pushes > 0 for r in rows)
    slow = [r for r in rows if r.label.startswith("1e-6") and r.speed_bin[1] <= 0.25]
    for r in slow:  # under 1.25 m/s a 1e-6 rad nudge must not change the outcome visibly
        assert r.angle_p90_rad < 0.02 and r.position_p90_mm < 1.0
    table = format_table(rows)
    assert table.count("\n") == len(rows) + 1 and "dt 1 ms" in table
