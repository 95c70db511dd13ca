import warnings
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from masspush.cli import main
from masspush.data.recording import Recording, write_recording
from masspush.learn.push_density import PushDensity, load_push_density
from masspush.models import shipped_file
from masspush.real.classifier_jobs import ClassifyJob, classify_by_posterior
from masspush.real.density_tuning import (
    TuneConfig,
    labelled_pushes,
    record_tuning,
    sort_over,
    sorting_grid,
)
from masspush.real.table_friction import (
    DRIFT_LIMIT,
    FrictionDriftWarning,
    FrictionReading,
    check_drift,
    friction_lines,
    peak,
    read_friction,
)

SETTING = "real-ur10"
MASSES = {"light-heavy": (0.064, 0.256), "heavy-light": (0.256, 0.064)}


def slippery_density() -> PushDensity:
    """A small density with the shipped real-ur10 density's metadata whose outcome hangs on
    the table's friction (its standardised log-friction input spread by 0.05)."""
    meta = load_push_density(shipped_file(SETTING, "push-density")).meta
    torch.manual_seed(3)
    net = PushDensity(12, 4, components=2, width=16, depth=1, meta=dict(meta))
    with torch.no_grad():
        net.x_mean[3:6] = torch.tensor([np.log(0.13), np.log(0.13), np.log(0.7)])
        net.x_std[3:6] = 0.05
        net.y_std[:] = 0.01  # small outcomes: no wrapped angle
    return net.eval()


def pushed_at(density: PushDensity, friction: float, per_class: int, seed: int) -> Recording:
    """Labelled episodes of 6 pushes whose outcomes `density` draws at this table friction."""
    rng = np.random.default_rng(seed)
    episodes = []
    for label, masses in MASSES.items():
        for i in range(per_class):
            observations, actions = [np.array([0.0, 0.0, rng.uniform(-3, 3), 0.3])], []
            for _ in range(6):
                actions.append(rng.uniform(-1, 1, 2))
                observations.append(density.sample(observations[-1], actions[-1], np.array(
                    [masses]), np.array([friction]), [0.12, 0.12], rng)[0])  # fmt: skip
            episodes.append({"id": f"{label}-{i}", "label": label, "masses": list(masses),
                             "lengths": [0.12, 0.12], "observations": np.array(observations),
                             "actions": np.array(actions)})  # fmt: skip
    return Recording(2, robot="sim", setting=SETTING, episodes=episodes)


@pytest.fixture(scope="module")
def tuned():
    """The slippery density recorded as tuned (its classes, the default friction grid)."""
    density = slippery_density()
    calibration = pushed_at(density, 0.7, 4, seed=0)
    record_tuning(density, list(MASSES), np.array(list(MASSES.values())), TuneConfig(),
                  labelled_pushes(calibration))  # fmt: skip
    return density


def test_peak_finds_a_parabolas_vertex_between_grid_points_and_stops_at_the_ends():
    grid = np.linspace(0.3, 1.2, 10)
    assert peak(-((grid - 0.637) ** 2), grid) == pytest.approx(0.637)
    assert peak(-grid, grid) == grid[0] and peak(grid, grid) == grid[-1]


def test_the_reading_follows_the_table_friction_the_pushes_were_made_on(tuned):
    readings = {mu: read_friction(tuned, pushed_at(tuned, mu, 6, seed=1), "lab")
                for mu in (0.5, 0.7, 0.95)}  # fmt: skip
    for mu, reading in readings.items():
        assert reading.value == pytest.approx(mu, rel=0.08)
        assert reading.low <= reading.value <= reading.high and reading.edge is None
        assert reading.episodes == 12
    # Fewer episodes, a wider interval.
    few = read_friction(tuned, pushed_at(tuned, 0.7, 1, seed=2), "lab")
    assert few.high - few.low > readings[0.7].high - readings[0.7].low
    # Read from fewer pushes per episode where told.
    assert read_friction(tuned, pushed_at(tuned, 0.7, 6, seed=1), "lab", pushes=1).value != (
        readings[0.7].value
    )


def test_a_table_beyond_the_grid_reads_at_its_end(tuned):
    reading = read_friction(tuned, pushed_at(tuned, 0.2, 3, seed=4), "lab")
    assert reading.edge == "low" and reading.value == pytest.approx(sorting_grid(tuned)[0])
    with pytest.warns(FrictionDriftWarning, match="at the low end"):
        check_drift(reading, tuned, "lab")


def test_a_drift_beyond_the_limit_warns_and_one_within_it_does_not(tuned):
    meta = {**tuned.meta}  # checked on a copy of the metadata
    calibration = {"value": 0.7, "low": 0.68, "high": 0.72, "episodes": 8, "edge": None}
    density = SimpleNamespace(meta={**meta, "tuned": {**meta["tuned"],
                                                      "table_friction": calibration}})  # fmt: skip

    def at(value):
        return FrictionReading(value, value - 0.01, value + 0.01, 8, None)

    with warnings.catch_warnings():
        warnings.simplefilter("error", FrictionDriftWarning)
        check_drift(at(0.7 * (1 - 0.9 * DRIFT_LIMIT)), density, "day.jsonl")
        check_drift(at(0.3), SimpleNamespace(meta=meta), "day.jsonl")  # none kept
    with pytest.warns(FrictionDriftWarning, match=r"^day.jsonl: the table reads -20 %"):
        check_drift(at(0.56), density, "day.jsonl")
    with pytest.warns(FrictionDriftWarning, match=r"\+20 %"):
        check_drift(at(0.84), density, "day.jsonl")
    lines = friction_lines(at(0.56), calibration)
    assert "0.560 (90 % interval 0.550-0.570, 8 episodes)" in lines[0]
    assert "change -20 %, beyond the 15 %" in lines[1]
    assert len(friction_lines(at(0.56), None)) == 1


def test_tune_density_keeps_the_calibrations_reading_and_classify_compares_a_later_day(tmp_path):
    density = slippery_density()
    start = tmp_path / "start.pt"
    density.save(start)
    calibration = tmp_path / "calibration.jsonl"
    write_recording(calibration, pushed_at(density, 0.7, 4, seed=5))
    out = tmp_path / "tuned.pt"
    assert main(["tune-density", "--setting", SETTING, "--episodes", str(calibration),
                 "--density", str(start), "--steps", "1", "--folds", "0",
                 "--out", str(out)]) == 0  # fmt: skip
    kept = load_push_density(out).meta["tuned"]
    assert list(kept["config"]["sort_range"]) == [0.3, 1.2]
    assert kept["table_friction"]["value"] == pytest.approx(0.7, rel=0.08)
    same, slippery = tmp_path / "same.jsonl", tmp_path / "slippery.jsonl"
    write_recording(same, pushed_at(density, 0.7, 4, seed=6))
    write_recording(slippery, pushed_at(density, 0.5, 4, seed=6))
    with warnings.catch_warnings():
        warnings.simplefilter("error", FrictionDriftWarning)
        lines = classify_by_posterior(ClassifyJob(str(same), density=str(out)))
    assert lines[-2].startswith("table friction as the tuned density reads it")
    assert "within the 15 %" in lines[-1]
    with pytest.warns(FrictionDriftWarning, match="repeat the governor fit"):
        lines = classify_by_posterior(ClassifyJob(str(slippery), density=str(out)))
    assert "beyond the 15 %" in lines[-1]


def test_sorting_reads_the_sort_range_and_a_density_tuned_before_it_its_tuning_grid(tuned):
    assert sorting_grid(tuned) == pytest.approx(np.arange(0.35, 1.16, 0.05))
    kept = tuned.meta["tuned"]["config"]
    before = {k: v for k, v in kept.items() if k not in ("sort_range", "sort_frictions")}
    old = {**tuned.meta["tuned"], "config": before}
    older = SimpleNamespace(meta={**tuned.meta, "tuned": old})
    grid = sorting_grid(older)
    assert len(grid) == 8 and 0.5 < grid[0] < grid[-1] < 1.0
    sort_over(
        older, TuneConfig(sort_range=(0.2, 0.8), sort_frictions=5)
    )  # the weights as they were
    assert sorting_grid(older) == pytest.approx([0.3, 0.4, 0.5, 0.6, 0.7])


@pytest.mark.parametrize("bad", [(0.5, 0.3), (0.0, 1.0), (0.3, float("nan"))])
def test_a_bad_sort_range_is_refused(bad):
    with pytest.raises(ValueError, match="sort_range"):
        TuneConfig(sort_range=bad)
