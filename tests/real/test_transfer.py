import json
import math
from dataclasses import asdict

import numpy as np
import pytest
import torch

from masspush.data.recording import read_recording
from masspush.real.classifier import PAPER_CLASSES, ClassifierConfig
from masspush.real.transfer import (
    CLASS_SEEDS,
    RUN_SEEDS,
    Sim2RealConfig,
    class_robot,
    paired_answers,
    paired_test,
    plot_accuracy_by_pushes,
    reach_note,
    read_summary,
    run_counts,
    run_sim2real,
    sign_test,
    summary_markdown,
)

# The shipped 2link-1-10 models (stiff pusher, fast) stand in for real-ur10's here.
CONFIG = Sim2RealConfig(
    setting="2link-1-10", episodes_per_class=2, classifier=ClassifierConfig(folds=2, epochs=50)
)

# Toy densities read toy tables, at an end of the sorting grid: a warning that is right there.
TOY_TABLES = pytest.mark.filterwarnings("ignore::masspush.real.table_friction.FrictionDriftWarning")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim2real")
    return out, run_sim2real(CONFIG, out, progress=False)


@pytest.mark.slow
def test_each_policy_records_the_paper_classes_with_their_masses(run):
    out, _ = run
    for arm in ("random", "learned"):
        recording = read_recording(out / f"{arm}.jsonl")
        assert recording.setting == "2link-1-10"
        assert sorted(recording.labels) == sorted(list(PAPER_CLASSES) * 2)
        for episode in recording.episodes:
            np.testing.assert_allclose(episode["masses"], PAPER_CLASSES[episode["label"]])


@pytest.mark.slow
def test_both_policies_see_the_same_chains(run):
    # Paired comparison: the same seeds, so the same starting poses up to the noise.
    out, _ = run
    random, learned = (read_recording(out / f"{arm}.jsonl") for arm in ("random", "learned"))
    for a, b in zip(random.episodes, learned.episodes, strict=True):
        np.testing.assert_allclose(a["observations"][0], b["observations"][0], atol=1e-6)


@pytest.mark.slow
def test_the_summary_scores_both_feature_kinds_beside_the_paper(run):
    out, _ = run
    saved = json.loads((out / "summary.json").read_text())
    assert saved["arms"].keys() == {"random", "learned"}
    for arm in saved["arms"].values():
        for kind in ("estimate", "lstm"):
            assert 0 <= arm[kind]["accuracy"] <= 1
            assert np.sum(arm[kind]["confusion"]) == 10
    table = (out / "summary.md").read_text()
    assert "| learned | tp+ |" in table and "81.4 %" in table


@pytest.mark.slow
def test_a_rerun_reuses_the_recordings(run):
    out, results = run
    before = (out / "learned.jsonl").read_bytes()
    again = run_sim2real(CONFIG, out, progress=False)
    assert again["arms"]["learned"]["reused"] is True
    assert (out / "learned.jsonl").read_bytes() == before
    assert again["arms"]["learned"]["estimate"] == results["arms"]["learned"]["estimate"]


@pytest.mark.slow
def test_a_run_directory_reads_back_as_the_summary_it_wrote(run):
    out, _ = run
    summary = read_summary(out)
    assert summary["config"] == json.loads(json.dumps(asdict(CONFIG)))
    assert summary["arms"].keys() == {"random", "learned"}


def test_a_directory_without_a_summary_is_a_one_line_error(tmp_path):
    with pytest.raises(ValueError, match=r"no summary\.json"):
        read_summary(tmp_path)
    (tmp_path / "summary.json").write_text("{")
    with pytest.raises(ValueError, match="cannot be read as JSON"):
        read_summary(tmp_path)
    (tmp_path / "summary.json").write_text('{"config": {}}')
    with pytest.raises(ValueError, match="no config and arms"):
        read_summary(tmp_path)


def test_the_summary_says_which_filter_arm_weighed_the_reach():
    arms = {
        "random": {"model": "rp"},
        "learned": {"filter": {"reach_weight": 1.0, "reach_from": 2}},
    }
    assert reach_note(arms) == (
        " The learned arm's filter also valued leaving the chain room in the reach from push 3"
        " on (reach_weight 1)."
    )
    assert reach_note({"learned": {"filter": {"particles": 512}}}) == ""
    assert reach_note(arms, stationary=False) == ""  # no governor: the weight is unused


def test_too_few_episodes_for_the_folds_are_refused():
    with pytest.raises(ValueError, match="folds"):
        Sim2RealConfig(episodes_per_class=3)


def test_a_negative_seed_is_refused_before_any_work():
    # it used to fail inside the first episode with a message that named no argument
    with pytest.raises(ValueError, match="seed must be an integer >= 0"):
        Sim2RealConfig(seed=-1)
    with pytest.raises(ValueError, match="seed must be an integer <= 4294967295"):
        Sim2RealConfig(seed=2**32)  # its chains' seeds would overflow the policies' 64 bits


def test_a_missing_recording_for_the_governor_is_refused_before_any_work(tmp_path):
    with pytest.raises(ValueError, match="governor_fit: no such recording"):
        Sim2RealConfig(governor_fit=str(tmp_path / "none.jsonl"))


@pytest.mark.slow
def test_the_control_runs_in_the_training_world(tmp_path):
    from dataclasses import replace

    run_sim2real(replace(CONFIG, world="training"), tmp_path, progress=False)
    assert read_recording(tmp_path / "learned.jsonl").robot == "masspush training world"
    # Runs of the policy push on past the training environment's last push.
    run_sim2real(replace(CONFIG, world="training", segments=2), tmp_path / "runs", progress=False)
    runs = read_recording(tmp_path / "runs" / "learned.jsonl").episodes
    assert max(len(e["actions"]) for e in runs) == 4
    with pytest.raises(ValueError, match="world must be one of"):
        Sim2RealConfig(world="moon")


@pytest.mark.slow
def test_another_model_for_an_arm_records_anew_and_is_named(run, tmp_path):
    import shutil
    from dataclasses import replace

    done, _ = run
    out = tmp_path
    for name in ("random.jsonl", "random.failures.json", "learned.jsonl", "learned.failures.json"):
        shutil.copy(done / name, out / name)
    other = replace(CONFIG, models={"random": "rp", "learned": "tp"})
    again = run_sim2real(other, out, progress=False)
    assert again["arms"]["learned"]["reused"] is False
    assert again["arms"]["learned"]["model"] == "tp"
    assert again["arms"]["random"]["reused"] is True
    assert read_recording(out / "learned.jsonl").robot == "masspush target world, tp"
    with pytest.raises(ValueError, match="one model for each"):
        replace(CONFIG, models={"learned": "tp+"})


@pytest.mark.slow
def test_the_target_worlds_differences_can_be_scaled(run, tmp_path):
    from dataclasses import replace

    done, _ = run
    run_sim2real(replace(CONFIG, severity=0.0), tmp_path, progress=False)
    scaled = read_recording(tmp_path / "learned.jsonl")
    assert scaled.robot == "masspush target world (differences x0)"
    full = read_recording(done / "learned.jsonl")
    # The same chains, seen through another world's tracker.
    assert [e["masses"].tolist() for e in scaled.episodes] == [
        e["masses"].tolist() for e in full.episodes
    ]
    assert not np.array_equal(scaled.episodes[0]["observations"], full.episodes[0]["observations"])
    # A world given outright is what the robot runs in.
    from masspush.models import model_and_policy
    from masspush.real.target_world import scaled_world
    from masspush.real.transfer import record_classes

    predictor, _, policy = model_and_policy("tp+", CONFIG.setting)
    given, _, _ = record_classes(CONFIG, predictor, policy, "given", progress=False,
                              target=scaled_world(0))  # fmt: skip
    np.testing.assert_allclose(
        np.asarray(given.episodes[0]["observations"], float),
        np.asarray(scaled.episodes[0]["observations"], float), atol=1e-6,
    )  # fmt: skip
    with pytest.raises(ValueError, match="needs world 'target'"):
        Sim2RealConfig(world="training", severity=0.5)
    with pytest.raises(ValueError, match="needs world 'target'"):
        Sim2RealConfig(world="training", lab=0)
    with pytest.raises(ValueError, match="day is a day in one lab"):
        Sim2RealConfig(day=1)
    with pytest.raises(ValueError, match="severity"):
        Sim2RealConfig(severity=-0.1)


@pytest.mark.slow
def test_one_lab_with_runs_of_the_policy(tmp_path):
    from dataclasses import replace

    results = run_sim2real(replace(CONFIG, lab=3, segments=2), tmp_path, progress=False)
    recording = read_recording(tmp_path / "learned.jsonl")
    assert recording.robot == "masspush target world, lab 3, 2 runs of the policy per episode"
    # One chain design in one lab: every episode is told the same link lengths.
    assert len({tuple(e["lengths"]) for e in recording.episodes}) == 1
    # Two runs of the setting's 2 pushes, unless a push failed.
    assert max(len(e["actions"]) for e in recording.episodes) == 4
    learned = results["arms"]["learned"]
    assert 0 <= learned["estimate"]["accuracy"] <= 1
    # The same episodes scored as if they had stopped after 1 run, then all of them.
    assert [(s["runs"], s["pushes"]) for s in learned["by_runs"]] == [(1, 2), (2, 4)]
    for kind in ("estimate", "lstm"):
        assert learned["by_runs"][-1][kind] == learned[kind]["accuracy"]
    summary = (tmp_path / "summary.md").read_text()
    assert "| 2 (1 run) |" in summary and "log-probabilities added up" in summary
    assert (tmp_path / "accuracy-by-pushes.png").stat().st_size > 0
    with pytest.raises(ValueError, match="segments"):
        Sim2RealConfig(segments=0)
    # Several labs in one figure; results of unlike lengths are refused.
    plot_accuracy_by_pushes({"lab 3": results, "again": results}, tmp_path / "labs.png")
    assert (tmp_path / "labs.png").stat().st_size > 0
    shorter = json.loads(json.dumps(results))
    for arm in shorter["arms"].values():
        arm["by_runs"] = arm["by_runs"][:1]
    with pytest.raises(ValueError, match="same segments"):
        plot_accuracy_by_pushes({"a": results, "b": shorter}, tmp_path / "bad.png")


@pytest.mark.slow
def test_the_arms_are_compared_on_the_same_chains(run):
    out, results = run
    learned, random = results["arms"]["learned"], results["arms"]["random"]
    assert learned["ids"] == random["ids"]
    truth = np.array(learned["labels"])
    for kind in ("estimate", "lstm"):
        right = {arm: np.array(r[kind]["predicted"]) == truth for arm, r in
                 results["arms"].items()}  # fmt: skip
        paired = results["paired"][kind]
        assert paired["only_learned"] == np.sum(right["learned"] & ~right["random"])
        assert paired["only_random"] == np.sum(~right["learned"] & right["random"])
    assert "McNemar" in (out / "summary.md").read_text()


def test_paired_test_is_the_exact_mcnemar_test():
    truth = np.zeros(10, np.int64)
    wrong_twice = np.array([1] * 8 + [0] * 2)
    p = paired_test(truth, truth, wrong_twice)
    assert (p["only_learned"], p["only_random"]) == (8, 0)
    assert p["p_value"] == pytest.approx(2 / 2**8)
    assert paired_test(truth, wrong_twice, truth)["p_value"] == p["p_value"]
    assert paired_test(truth, truth, truth) == {"only_learned": 0, "only_random": 0, "p_value": 1.0}
    # 3 against 1: two-sided tail 2 * (1 + 4) / 16.
    mixed = paired_test(truth[:4], np.array([0, 0, 0, 1]), np.array([1, 1, 1, 0]))
    assert mixed["p_value"] == pytest.approx(10 / 16)
    # The sign test under it, on counts of wins and losses.
    assert sign_test(3, 1) == pytest.approx(10 / 16) == sign_test(1, 3)
    assert sign_test(8, 0) == pytest.approx(2 / 2**8)
    assert sign_test(0, 0) == 1.0 and sign_test(5, 5) == 1.0


def test_paired_answers_pair_by_episode_id_on_the_episodes_both_kept():
    first = {"ids": ["a", "b", "c"], "labels": [0, 1, 2], "estimate": {"predicted": [0, 1, 1]}}
    # Another order, "a" lost, "d" only here.
    second = {"ids": ["d", "c", "b"], "labels": [3, 2, 1], "estimate": {"predicted": [3, 2, 0]}}
    truth, a, b = paired_answers(first, second)
    assert truth.tolist() == [1, 2]  # ids b, c
    assert a.tolist() == [1, 1] and b.tolist() == [0, 2]


@pytest.mark.slow
def test_a_single_run_has_no_curve_over_runs(run):
    out, results = run
    assert "by_runs" not in results["arms"]["learned"]
    assert not (out / "accuracy-by-pushes.png").exists()


def test_run_counts_double_up_to_all_runs():
    assert run_counts(1) == [1]
    assert run_counts(8) == [1, 2, 4, 8]
    assert run_counts(6) == [1, 2, 4, 6]


class _LosingRobot:
    """A robot that loses the chain on the first push of every third episode and on the
    second push of every third after it: the protocol's bookkeeping, without physics."""

    n_links = 2

    def __init__(self, setting, seed=0, masses=(0.16, 0.16), **_):
        self.seed, self.episode = seed, -1
        self.truth = {"masses": np.array(masses)}
        self.rng = np.random.default_rng(seed)

    def start(self):
        from masspush.real.robot import RestPose

        self.episode, self.k = self.episode + 1, 0
        return RestPose(self.rng.normal(0, 0.05, 4).astype(np.float32), np.array([0.12, 0.12]))

    def push(self, action):
        from masspush.real.robot import PushReport

        self.k += 1
        if (self.episode % 3 == 0 and self.k == 1) or (self.episode % 3 == 1 and self.k == 2):
            return PushReport(None, "left_workspace", speed=0.8)
        return PushReport(self.rng.normal(0, 0.05, 4).astype(np.float32), speed=1.5)

    def close(self):
        pass


def test_failed_episodes_are_counted_never_replaced(monkeypatch):
    import masspush.real.backends as backends
    from masspush.models import model_and_policy
    from masspush.real.transfer import record_classes

    monkeypatch.setattr(backends, "SimRobot", _LosingRobot)
    config = Sim2RealConfig(setting="2link-1-10", world="training", episodes_per_class=6)
    predictor, _, policy = model_and_policy("rp", "2link-1-10")
    recording, failures, classes = record_classes(config, predictor, policy, "t", progress=False)
    # Per class, 6 attempted: 2 lost on the first push (nothing to classify), 2 lost on the
    # second (kept with their one good push), 2 whole.
    for tally in classes.values():
        assert tally == {"attempted": 6, "kept": 4, "lost": 4, "failed": 0, "good_pushes": 6}
    assert failures == {"left_workspace": 4 * len(PAPER_CLASSES)}
    kept = [e for e in recording.episodes if e["label"] == "0.160-0.160"]
    # No episode took a lost one's place: the ids are the attempts that had a good push.
    assert [e["id"] for e in kept] == [f"0.160-0.160-00{i}" for i in (2, 3, 5, 6)]
    assert [len(e["actions"]) for e in kept] == [1, 2, 1, 2]
    assert [e.get("failure") for e in kept] == ["left_workspace", None, "left_workspace", None]
    assert all(e["speeds"] == [1.5] * len(e["actions"]) for e in kept)


def test_the_lab_s_placement_puts_every_chain_where_it_says():
    from dataclasses import asdict

    from masspush.models import model_and_policy
    from masspush.real.transfer import record_classes

    predictor, _, policy = model_and_policy("rp", "2link-1-10")
    starts = {}
    for placed in (None, 0.0):
        config = Sim2RealConfig(
            setting="2link-1-10", world="training", episodes_per_class=2, start_range=placed,
            classifier=ClassifierConfig(folds=2),
        )  # fmt: skip
        recording, _, _ = record_classes(config, predictor, policy, "t", progress=False)
        starts[placed] = np.array([e["observations"][0][:2] for e in recording.episodes])
    # Placed on the origin, the first link's centre is seen there up to the tracker's noise;
    # left to the setting (0.1 m here), the same seeds spread the chains over the table.
    assert np.abs(starts[0.0]).max() < 0.03
    assert np.abs(starts[None]).max() > 0.05
    for placed, said in ((0.02, True), (None, False)):
        config = asdict(Sim2RealConfig(start_range=placed))
        text = summary_markdown({"config": config, "arms": {}})
        assert ("Chains placed within 0.02 m of the origin" in text) is said
    with pytest.raises(ValueError, match="start_range must be in"):
        Sim2RealConfig(start_range=-0.1)


def test_the_lab_s_heading_lays_every_chain_the_way_it_says():
    from dataclasses import asdict

    from masspush.models import model_and_policy
    from masspush.real.transfer import HAND_YAW_SCATTER, record_classes
    from masspush.sim.chain import wrap_angle

    predictor, _, policy = model_and_policy("rp", "real-ur10")
    facing = math.pi / 2  # real-ur10's UR10 stands at -y, facing +y
    for asked in (0.0, 90.0):
        config = Sim2RealConfig(
            world="training", episodes_per_class=2, start_range=0.02, start_yaw=asked,
            classifier=ClassifierConfig(folds=2),
        )  # fmt: skip
        recording, _, _ = record_classes(config, predictor, policy, "t", progress=False)
        yaws = np.array([e["observations"][0][2] for e in recording.episodes])
        # within the hand's scatter of the heading asked, up to the tracker's noise
        off = np.degrees(np.abs(wrap_angle(yaws - facing - math.radians(asked))))
        assert off.max() < HAND_YAW_SCATTER + 3, (asked, off)
    text = summary_markdown({"config": asdict(config), "arms": {}})
    assert "first link at 90 degrees to the direction the robot faces" in text
    with pytest.raises(ValueError, match="start_yaw must be in"):
        Sim2RealConfig(start_yaw=270)
    with pytest.raises(ValueError, match="start_yaw is relative to a stationary robot"):
        Sim2RealConfig(setting="2link-1-10", start_yaw=0)


@pytest.mark.slow
def test_the_summary_reports_losses_and_the_start_pose_control(run):
    out, results = run
    for arm in results["arms"].values():
        assert set(arm["by_class"]) == set(PAPER_CLASSES)
        assert all(c["attempted"] == 2 for c in arm["by_class"].values())
        assert 0 <= arm["start_pose_control"]["accuracy"] <= 1
        for kind in ("estimate", "lstm"):
            assert arm[kind]["accuracy_attempted"] <= arm[kind]["accuracy"]
    table = (out / "summary.md").read_text()
    assert "start-pose control" in table and "lost the chain" in table
    assert "at the speed the robot reported (--read-speeds)" in table


@pytest.mark.slow
def test_the_pushes_read_as_commanded_rescore_the_same_recordings(run, tmp_path):
    import shutil
    from dataclasses import replace

    out, results = run
    for arm in ("random", "learned"):
        for suffix in (".jsonl", ".failures.json"):
            shutil.copy(out / f"{arm}{suffix}", tmp_path / f"{arm}{suffix}")
    again = run_sim2real(replace(CONFIG, read_speeds=False), tmp_path, progress=False)
    assert all(again["arms"][arm]["reused"] for arm in ("random", "learned"))
    assert "read each push as commanded (--no-read-speeds)" in (tmp_path / "summary.md").read_text()
    # The predictor read other actions: its features, so its error, differ.
    learned = results["arms"]["learned"]["percentage_error"]
    assert again["arms"]["learned"]["percentage_error"] != learned


@pytest.mark.slow
def test_the_classes_recorded_on_a_pool_are_the_classes_recorded_here(serial_pool):
    from masspush.models import model_and_policy
    from masspush.real.transfer import record_classes

    predictor, _, policy = model_and_policy("tp+", "2link-1-10")
    here = record_classes(CONFIG, predictor, policy, "t", progress=False)
    pooled = record_classes(CONFIG, predictor, policy, "t", workers=serial_pool(size=5))
    assert pooled[1:] == here[1:]  # failures and each class's tally
    assert json.dumps(pooled[0].episodes, default=str) == json.dumps(here[0].episodes, default=str)


def test_each_class_s_robot_pushes_that_class_s_chains_in_the_world_asked():
    from masspush.real.backends import SimRobot
    from masspush.real.target_world import TargetWorld, TargetWorldRobot
    from masspush.settings import get_setting

    setting = get_setting("2link-1-10")
    training = class_robot(setting, 3, seed=5, pushes=4)
    lab = class_robot(setting, 3, seed=5, world=TargetWorld(), lab=2)
    try:
        assert isinstance(training, SimRobot) and isinstance(lab, TargetWorldRobot)
        assert training.seed == lab.seed == 5 * RUN_SEEDS + 3 * CLASS_SEEDS  # sim2real --seed 5
        for robot in (training, lab):
            robot.start()
            np.testing.assert_allclose(robot.truth["masses"], list(PAPER_CLASSES.values())[3])
        again = class_robot(setting, 3, seed=5, pushes=4)
        np.testing.assert_allclose(again.start().config, class_robot(setting, 3, 5).start().config)
        again.close()
        assert class_robot(setting, 3, 5, TargetWorld(), lab=2, day=4).lab.day == 4
    finally:
        training.close()
        lab.close()


def test_runs_with_other_seeds_never_share_a_chain():
    # Seed S + 1's chains were once seed S's shifted by one: a calibration run and its
    # "held-out" test runs then pushed the same chains.
    from masspush.real.transfer import class_episodes
    from masspush.settings import get_setting

    setting = get_setting("2link-1-10")
    runs = [
        [e.pose.config for e in class_episodes(setting, 3, seed=s, pushes=4) if e.c == 0]
        for s in (0, 1, 2)
    ]
    starts = [tuple(np.round(config, 6)) for run in runs for config in run]
    assert len(set(starts)) == len(starts) == 9


def test_class_episodes_start_the_chains_of_a_run_in_its_order_and_close_each_robot(
    monkeypatch,
):
    from masspush.real.backends import SimRobot
    from masspush.real.transfer import class_episodes, episode_id
    from masspush.settings import get_setting

    closed = []
    close = SimRobot.close
    monkeypatch.setattr(SimRobot, "close", lambda self: (closed.append(self), close(self)))
    setting = get_setting("2link-1-10")
    seen = list(class_episodes(setting, 2, seed=5, pushes=4))
    assert [(e.c, e.i) for e in seen] == [(c, i) for c in range(len(PAPER_CLASSES)) for i in (0, 1)]
    assert seen[2].id == episode_id(1, 0) == f"{list(PAPER_CLASSES)[1]}-001"
    assert closed == [e.robot for e in seen[::2]]  # each class's robot, once, after its last
    robot = class_robot(setting, 3, seed=5, pushes=4)
    try:
        for e in seen[6:8]:
            np.testing.assert_allclose(e.pose.config, robot.start().config)
    finally:
        robot.close()


@TOY_TABLES
def test_the_particle_filter_is_an_arm_scored_on_the_estimates_it_recorded(density_file, tmp_path):
    from dataclasses import replace

    from masspush.learn.push_density import load_push_density
    from masspush.real.classifier_jobs import TuneDensityJob, tune
    from masspush.real.density_tuning import CalibrationWarning, TuneConfig

    config = replace(CONFIG, world="training", segments=2, density=str(density_file),
                     models={"random": "rp", "learned": "bayes"},
                     bayes={"particles": 512})  # fmt: skip
    results = run_sim2real(config, tmp_path, progress=False)
    recording = read_recording(tmp_path / "learned.jsonl")
    assert recording.robot == (
        "masspush training world, 2 runs of the policy per episode, bayes weighing pushes "
        "with density.pt (particles=512), speeds read"
    )
    assert all(len(e["estimates"]) == len(e["actions"]) for e in recording.episodes)
    learned = results["arms"]["learned"]
    assert learned["kinds"] == ["estimate"] and "lstm" not in learned
    # Read from the recorded estimates: the posterior after all pushes, and after the first 2.
    assert [s["pushes"] for s in learned["by_runs"]] == [2, 4]
    assert learned["by_runs"][-1]["estimate"] == learned["estimate"]["accuracy"]
    assert set(results["paired"]) == {"estimate"}
    summary = (tmp_path / "summary.md").read_text()
    assert "| learned | bayes |" in summary and "learned, LSTM" not in summary
    assert (tmp_path / "accuracy-by-pushes.png").stat().st_size > 0
    assert "posterior" not in learned  # no tuned density given
    # A density tuned to these episodes (`masspush tune-density`) also sorts every arm's
    # episodes by class posterior; the recordings are reused (the filter pushes as before).
    tuned = tmp_path / "tuned.pt"
    job = TuneDensityJob(config.setting, str(tmp_path / "learned.jsonl"), str(tuned),
                         str(density_file))  # fmt: skip
    tune(job, TuneConfig(steps=3, folds=0), progress=False)
    before = (tmp_path / "learned.jsonl").read_text()
    rescored = run_sim2real(replace(config, tuned_density=str(tuned)), tmp_path, progress=False)
    assert (tmp_path / "learned.jsonl").read_text() == before
    for arm in ("random", "learned"):
        posterior = rescored["arms"][arm]["posterior"]
        assert 0 <= posterior["accuracy"] <= 1
        assert np.sum(posterior["confusion"]) == len(recording.episodes)
        by_runs = rescored["arms"][arm]["by_runs"]
        assert by_runs[-1]["posterior"] == posterior["accuracy"] and "posterior" in by_runs[0]
    # Its reading of the table's friction, against the calibration's (the learned episodes).
    read = {arm: rescored["arms"][arm]["table_friction"] for arm in ("random", "learned")}
    assert read["learned"]["change"] == pytest.approx(0, abs=1e-9)
    assert read["random"]["low"] <= read["random"]["value"] <= read["random"]["high"]
    summary = (tmp_path / "summary.md").read_text()
    assert "Sorted by the class posterior of the push density tuned" in summary
    assert f"learned {read['learned']['value']:.3f}" in summary and "+0 % from the" in summary
    # The filter's settings as run, defaults included, are kept beside its recording: one
    # made under other defaults (here another reach weight) is recorded anew, not reused.
    assert rescored["arms"]["learned"]["filter"]["particles"] == 512
    assert "filter" not in rescored["arms"]["random"]
    counts = tmp_path / "learned.failures.json"
    kept = json.loads(counts.read_text())
    kept["filter"]["reach_weight"] = 1.0
    counts.write_text(json.dumps(kept))
    anew = run_sim2real(config, tmp_path, progress=False)
    assert anew["arms"]["learned"]["reused"] is False and anew["arms"]["random"]["reused"]
    assert "reach_weight" not in json.loads(counts.read_text())["filter"]
    assert "learned, class posterior of the tuned density" in summary
    # Refused before any episode: a density not tuned, or tuned for other classes.
    with pytest.raises(ValueError, match="is not tuned"):
        replace(config, tuned_density=str(density_file))
    other = load_push_density(tuned)
    other.meta["tuned"]["classes"] = {"a": [1.0, 2.0], "b": [2.0, 1.0]}
    other.save(tmp_path / "other.pt")
    with pytest.raises(ValueError, match="tuned for the classes"):
        replace(config, tuned_density=str(tmp_path / "other.pt"))
    # Tuned on episodes much shorter than these runs: a warning, before any episode.
    assert load_push_density(tuned).meta["tuned"]["pushes_per_episode"] == pytest.approx(
        np.mean([len(e["actions"]) for e in recording.episodes])
    )
    short = load_push_density(tuned)
    short.meta["tuned"]["pushes_per_episode"] = 1.0
    short.save(tmp_path / "short.pt")
    with pytest.warns(CalibrationWarning, match="tune it on runs as long as those it sorts"):
        replace(config, tuned_density=str(tmp_path / "short.pt"))
    # A recording without its estimates cannot be scored as the filter's.
    lines = (tmp_path / "learned.jsonl").read_text().splitlines()
    bare = [lines[0]] + [
        json.dumps({k: v for k, v in json.loads(line).items() if k != "estimates"})
        for line in lines[1:]
    ]
    (tmp_path / "learned.jsonl").write_text("\n".join(bare) + "\n")
    with pytest.raises(ValueError, match="has no estimates"):
        run_sim2real(config, tmp_path, progress=False)


@pytest.mark.slow
def test_a_filter_arm_that_checks_reach_asks_before_every_push(monkeypatch, tmp_path):
    from dataclasses import replace

    from masspush.sim.arm_reach import ReachCheck

    asked, threads = [], []
    check = ReachCheck.__call__

    def asking(self, *a):
        asked.append(a)
        threads.append(torch.get_num_threads())
        return check(self, *a)

    monkeypatch.setattr(ReachCheck, "__call__", asking)
    before = torch.get_num_threads()
    config = replace(CONFIG, setting="real-ur10", world="training", check_reach=True,
                     models={"random": "rp", "learned": "bayes"},
                     bayes={"particles": 64, "lookahead_particles": 8})  # fmt: skip
    run_sim2real(config, tmp_path, progress=False)
    recording = read_recording(tmp_path / "learned.jsonl")
    assert "pushes checked for reach" in recording.robot
    pushes = sum(len(e["actions"]) for e in recording.episodes)
    assert len(asked) >= pushes  # every push asked about (more where the best was refused)
    # each asked with the pose the push starts from, as the robot saw it
    first = recording.episodes[0]
    np.testing.assert_allclose(asked[0][1], first["observations"][0], atol=1e-6)
    assert "(--check-reach)" in (tmp_path / "summary.md").read_text()
    # the filter pushes on one torch thread (small calls; a pool only waits), then restores
    assert set(threads) == {1} and torch.get_num_threads() == before
    with pytest.raises(ValueError, match="check_reach is the particle filter's"):
        Sim2RealConfig(check_reach=True)
    with pytest.raises(ValueError, match="check_reach is for a stationary robot"):
        Sim2RealConfig(setting="2link-1-10", check_reach=True,
                       models={"random": "rp", "learned": "bayes"})  # fmt: skip


def test_a_density_is_checked_before_any_episode(density_file, tmp_path):
    with pytest.raises(ValueError, match="no arm's model is bayes"):
        Sim2RealConfig(setting="2link-1-10", density=str(density_file))
    bayes = {"random": "rp", "learned": "bayes"}
    with pytest.raises(ValueError, match=r"density: push density .* n_links 2, not 3"):
        Sim2RealConfig(setting="3link-1-10", density=str(density_file), models=bayes)
    with pytest.raises(ValueError, match=r"density: .*no such file"):
        Sim2RealConfig(setting="2link-1-10", density=str(tmp_path / "x.pt"), models=bayes)
    # ... and so are the filter's own options
    with pytest.raises(ValueError, match="no arm's model is bayes"):
        Sim2RealConfig(setting="2link-1-10", bayes={"particles": 64})
    with pytest.raises(ValueError, match=r"bayes: likelihood_power must be in \(0, 1\]"):
        Sim2RealConfig(setting="2link-1-10", bayes={"likelihood_power": 2.0}, models=bayes)
    with pytest.raises(ValueError, match="as density"):
        Sim2RealConfig(setting="2link-1-10", bayes={"density": "x.pt"}, models=bayes)
