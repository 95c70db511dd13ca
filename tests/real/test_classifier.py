import numpy as np
import pytest

from masspush.cli import main
from masspush.data.recording import Recording, read_recording, write_recording
from masspush.data.rollout import RandomPolicy
from masspush.learn.predictor import load_model
from masspush.models import resolve_model
from masspush.real.backends import SimRobot
from masspush.real.classifier import (
    ClassifierConfig,
    classifier_inputs,
    cross_validate,
    episode_log_probs,
    first_pushes,
    labelled,
    load_classifier,
    out_of_fold_log_probs,
    predictor_features,
    stratified_folds,
)
from masspush.real.robot import run_estimation

SETTING = "2link-1-10"
CLASSES = {"light-heavy": (2.0, 8.0), "even": (5.0, 5.0), "heavy-light": (8.0, 2.0)}


@pytest.fixture(scope="module")
def labelled_recording(tmp_path_factory):
    """12 simulated episodes per class, each class on its own chains (as in a lab, where
    the chain is placed anew for every episode)."""
    predictor = load_model(resolve_model("rp+", SETTING), SETTING)[0]
    episodes = []
    for c, (label, masses) in enumerate(CLASSES.items()):
        robot = SimRobot(SETTING, seed=1000 * (c + 1), masses=masses)
        for i in range(12):
            run = run_estimation(robot, predictor, RandomPolicy(), 2, seed=i)
            if run.failure is not None:
                continue
            episodes.append(run.recorded(id=f"{label}-{i}", label=label, masses=list(masses)))
    path = tmp_path_factory.mktemp("rec") / "labelled.jsonl"
    return write_recording(path, Recording(2, robot="sim", setting=SETTING, episodes=episodes))


@pytest.mark.slow
def test_a_classifier_on_predictor_features_beats_chance(labelled_recording):
    recording = read_recording(labelled_recording)
    predictor = load_model(resolve_model("rp+", SETTING), SETTING)[0]
    labels, classes = labelled(recording)
    assert predictor_features(predictor, recording.to_episodes(), "lstm").shape == (
        len(labels),
        64,
    )
    features = predictor_features(predictor, recording.to_episodes())
    assert features.shape == (len(labels), 2)
    scores = cross_validate(features, labels, len(classes), ClassifierConfig(folds=4))
    assert scores["chance"] == pytest.approx(1 / 3, abs=0.05)
    assert scores["accuracy"] > 0.7  # chance is a third
    assert np.sum(scores["confusion"]) == len(labels)
    # Each episode's out-of-fold guess, consistent with the confusion matrix.
    again = np.zeros_like(scores["confusion"])
    np.add.at(again, (labels, scores["predicted"]), 1)
    np.testing.assert_array_equal(again, scores["confusion"])


@pytest.mark.slow
def test_finetune_and_classify_commands(labelled_recording, tmp_path, capsys):
    out = tmp_path / "clf.pt"
    args = ["--setting", SETTING, "--model", "rp+", "--episodes", str(labelled_recording)]
    assert main(["finetune", *args, "--out", str(out), "--folds", "3"]) == 0
    printed = capsys.readouterr().out
    assert "cross-validated accuracy" in printed and "start-pose control" in printed
    assert "pushes each, ended early: none" in printed
    assert main(["classify", "--classifier", str(out), "--episodes", str(labelled_recording)]) == 0
    assert "accuracy on the" in capsys.readouterr().out
    # The pushes were read at their recorded speeds, and the classifier file says so.
    assert all("speeds" in e for e in read_recording(labelled_recording).episodes)
    assert load_classifier(out)[2]["read_speeds"] is True
    as_commanded = tmp_path / "commanded.pt"
    assert main(["finetune", *args, "--out", str(as_commanded), "--folds", "3",
                 "--no-read-speeds"]) == 0  # fmt: skip
    assert load_classifier(as_commanded)[2]["read_speeds"] is False
    with pytest.raises(ValueError, match=r"not '2link-0\.1-1'"):
        load_classifier(out, "2link-0.1-1")
    # A predictor of another setting is refused, with a clear message on the command line.
    assert main(["finetune", *args[:2], "--model", str(resolve_model("rp+", "3link-1-10")),
                 "--episodes", str(labelled_recording)]) == 2  # fmt: skip
    assert "trained for setting '3link-1-10'" in capsys.readouterr().err


def test_folds_are_stratified_and_too_few_episodes_are_refused():
    labels = np.array([0] * 6 + [1] * 9)
    folds = stratified_folds(labels, 3, seed=0)
    assert sorted(np.concatenate(folds).tolist()) == list(range(15))
    assert all(np.sum(labels[f] == 0) == 2 and np.sum(labels[f] == 1) == 3 for f in folds)
    with pytest.raises(ValueError, match="at least 5 episodes"):
        cross_validate(np.zeros((6, 4)), np.array([0, 0, 0, 1, 1, 1]), 2, ClassifierConfig())
    with pytest.raises(ValueError, match="folds"):
        ClassifierConfig(folds=1)


def test_out_of_fold_log_probs_are_cross_validates_guesses():
    """Separable classes: every episode's log-probabilities come from a classifier that
    never saw it, sum to one, and give cross_validate's predictions; an episode's rows
    (owner) are scored together."""
    rng = np.random.default_rng(0)
    labels = np.repeat([0, 1, 2], 10)
    features = (labels[:, None] * 3.0 + rng.normal(0, 0.3, (30, 2))).astype(np.float32)
    config = ClassifierConfig(folds=5, epochs=200)
    log_probs = out_of_fold_log_probs(features, labels, 3, config)
    assert log_probs.shape == (30, 3)
    np.testing.assert_allclose(np.exp(log_probs).sum(1), 1.0, rtol=1e-5)
    predicted = cross_validate(features, labels, 3, config)["predicted"]
    np.testing.assert_array_equal(log_probs.argmax(1), predicted)
    assert np.mean(log_probs.argmax(1) == labels) > 0.9
    # Two rows per episode: the episode's log-probabilities are its rows' together.
    rows, owner = np.repeat(features, 2, axis=0), np.repeat(np.arange(30), 2)
    paired = out_of_fold_log_probs(rows, labels, 3, config, owner)
    assert paired.shape == (30, 3) and np.mean(paired.argmax(1) == labels) > 0.9
    with pytest.raises(ValueError, match="rows of features but"):
        out_of_fold_log_probs(rows, labels, 3, config, owner[:-1])


def segmented_recording(path, segments: int = 3, episodes: int = 4):
    """Episodes of `segments` runs of the random policy (2 pushes each) in which no push
    failed, with what each run estimated as it went."""
    from masspush.real.robot import run_segments
    from masspush.real.target_world import TargetWorldRobot

    predictor = load_model(resolve_model("rp+", SETTING), SETTING)[0]
    # The target world, unlike the training world's environment, has no last push.
    robot = TargetWorldRobot(SETTING, seed=77, masses=(2.0, 8.0))
    runs = []
    while len(runs) < episodes:
        run = run_segments(robot, predictor, RandomPolicy(), 2, segments, seed=robot.seed)
        if len(run.estimates) == 2 * segments:
            runs.append(run)
    recorded = [r.recorded(id=f"e{i}", label="light-heavy" if i % 2 else "even")
                for i, r in enumerate(runs)]  # fmt: skip
    write_recording(path, Recording(2, robot="sim", setting=SETTING, episodes=recorded))
    return predictor, runs


@pytest.mark.slow
def test_an_ensembles_features_are_its_members_side_by_side(labelled_recording, perturbed_pair):
    predictor = load_model(resolve_model("rp+", SETTING), SETTING)[0]
    ensemble = perturbed_pair(predictor)
    other = ensemble.members[1]
    episodes = read_recording(labelled_recording).to_episodes()
    lstm = predictor_features(ensemble, episodes, "lstm")
    np.testing.assert_array_equal(lstm[:, :64], predictor_features(predictor, episodes, "lstm"))
    np.testing.assert_array_equal(lstm[:, 64:], predictor_features(other, episodes, "lstm"))
    estimate = predictor_features(ensemble, episodes, "estimate")
    means = (np.exp(predictor_features(predictor, episodes, "estimate"))
             + np.exp(predictor_features(other, episodes, "estimate"))) / 2  # fmt: skip
    np.testing.assert_allclose(estimate, np.log(means), atol=1e-5)


@pytest.mark.slow
def test_segment_features_average_what_each_run_estimated(tmp_path):
    predictor, runs = segmented_recording(tmp_path / "runs.jsonl")
    episodes = read_recording(tmp_path / "runs.jsonl").to_episodes()
    assert all(len(r.run_estimates) == 3 and len(r.actions) == 6 for r in runs)
    features = predictor_features(predictor, episodes, "estimate", segment=2)
    expected = np.log([np.mean(r.run_estimates, axis=0) for r in runs])
    np.testing.assert_allclose(features, expected, atol=1e-5)
    # Read whole, the 6 pushes make one estimate of their own.
    whole = predictor_features(predictor, episodes, "estimate")
    assert not np.allclose(whole, features, atol=1e-3)
    lstm = predictor_features(predictor, episodes, "lstm", segment=2)
    assert lstm.shape == (4, 64)


@pytest.mark.slow
def test_an_episode_cut_after_its_first_runs_averages_only_those(tmp_path):
    predictor, runs = segmented_recording(tmp_path / "runs.jsonl")
    episodes = read_recording(tmp_path / "runs.jsonl").to_episodes()
    cut = first_pushes(episodes, 4)
    assert cut.actions.shape[1] == 4 and cut.observations.shape[1] == 5
    np.testing.assert_array_equal(cut.observations, episodes.observations[:, :5])
    features = predictor_features(predictor, cut, "estimate", segment=2)
    expected = np.log([np.mean(r.run_estimates[:2], axis=0) for r in runs])
    np.testing.assert_allclose(features, expected, atol=1e-5)
    with pytest.raises(ValueError, match="at least one push"):
        first_pushes(episodes, 0)


@pytest.mark.slow
def test_an_unfinished_run_counts_with_the_pushes_it_saw(tmp_path):
    predictor, _ = segmented_recording(tmp_path / "runs.jsonl", episodes=2)
    recording = read_recording(tmp_path / "runs.jsonl")
    short = recording.episodes[0]
    short["actions"], short["observations"] = short["actions"][:3], short["observations"][:4]
    episodes = recording.to_episodes()
    features = predictor_features(predictor, episodes, "estimate", segment=2)
    first_run = predictor_features(predictor, episodes.select(np.array([True, False])),
                                   "estimate")  # fmt: skip
    from masspush.real.classifier import segments_of

    parts, owner = segments_of(episodes, 2)
    assert len(parts) == 5 and parts.actions.shape[1] == 2
    assert owner.tolist() == [0, 1, 0, 1, 1]  # runs 1-2 of episode 0, runs 1-3 of episode 1
    assert not np.allclose(features[0], first_run[0])
    with pytest.raises(ValueError, match="segment"):
        ClassifierConfig(segment=-1)


@pytest.mark.slow
def test_finetune_and_classify_read_runs_as_recorded(tmp_path, capsys):
    segmented_recording(tmp_path / "runs.jsonl", episodes=6)
    out = tmp_path / "clf.pt"
    args = ["--setting", SETTING, "--model", "rp+", "--episodes", str(tmp_path / "runs.jsonl")]
    for runs in ("each", "average"):
        assert main(["finetune", *args, "--out", str(out), "--folds", "3", "--segment", "2",
                     "--runs", runs]) == 0  # fmt: skip
        meta = load_classifier(out)[2]
        assert (meta["segment"], meta["runs"]) == (2, runs)
        capsys.readouterr()
        assert main(["classify", "--classifier", str(out), "--episodes", args[-1]]) == 0
        assert "accuracy on the 6 labelled" in capsys.readouterr().out


@pytest.mark.slow
def test_runs_read_one_by_one_are_classified_by_their_summed_log_probabilities(tmp_path):
    import torch

    from masspush.real.classifier import MassClassifier

    predictor, runs = segmented_recording(tmp_path / "runs.jsonl")
    episodes = read_recording(tmp_path / "runs.jsonl").to_episodes()
    each = ClassifierConfig(segment=2, runs="each")
    features, owner = classifier_inputs(predictor, episodes, each)
    assert owner.tolist() == [0, 1, 2, 3] * 3  # 3 runs of 2 pushes per episode
    np.testing.assert_allclose(np.exp(features[owner == 1]), runs[1].run_estimates, atol=1e-5)
    averaged, one_each = classifier_inputs(predictor, episodes, ClassifierConfig(segment=2,
                                           runs="average"))  # fmt: skip
    assert averaged.shape == (4, 2) and one_each.tolist() == [0, 1, 2, 3]
    torch.manual_seed(0)
    model = MassClassifier(2, 3)
    log_probs = episode_log_probs(model, features, owner, 4)
    with torch.no_grad():
        rows = torch.log_softmax(model(torch.as_tensor(features)), -1).numpy()
    summed = np.stack([rows[owner == e].sum(0) for e in range(4)])
    np.testing.assert_allclose(log_probs, summed - np.log(np.exp(summed).sum(1, keepdims=True)),
                               atol=1e-5)  # fmt: skip
    np.testing.assert_allclose(np.exp(log_probs).sum(1), 1, atol=1e-6)
    with pytest.raises(ValueError, match="runs"):
        ClassifierConfig(runs="median")


@pytest.mark.slow
def test_reading_runs_one_by_one_keeps_what_averaging_loses(monkeypatch):
    """Two classes whose episodes have the same mean: one's runs land at +1 or -1, half of
    each, the other's near 0. Averaged the classes overlap; read run by run they do not.
    An episode's runs are never split between training and test."""
    import masspush.real.classifier as finetune

    rng = np.random.default_rng(0)
    episodes, runs = 40, 8
    labels = np.repeat([0, 1], episodes // 2)
    owner = np.repeat(np.arange(episodes), runs)
    halves = np.concatenate([rng.permutation([-1.0, 1.0] * (runs // 2)) for _ in labels])
    spread = np.where(labels[owner] == 0, halves, 0.0)
    features = (spread + rng.normal(0, 0.1, owner.size)).astype(np.float32)[:, None]
    whose = dict(zip(features[:, 0].tolist(), owner.tolist(), strict=True))  # values unique
    fitted = finetune.fit_classifier
    trained_on: list[np.ndarray] = []

    def spy(x, *args):
        trained_on.append(np.array([whose[v] for v in x[:, 0].tolist()]))
        return fitted(x, *args)

    monkeypatch.setattr(finetune, "fit_classifier", spy)
    config = ClassifierConfig(folds=4, segment=1)
    each = cross_validate(features, labels, 2, config, owner)
    for test, seen in zip(stratified_folds(labels, 4, config.seed), trained_on, strict=True):
        assert not np.isin(seen, test).any()
    assert len(trained_on) == 4 and all(len(seen) == 30 * runs for seen in trained_on)
    monkeypatch.setattr(finetune, "fit_classifier", fitted)
    mean = np.stack([features[owner == e, 0].mean() for e in range(episodes)])[:, None]
    averaged = cross_validate(mean, labels, 2, config)
    assert each["accuracy"] >= 0.95
    assert averaged["accuracy"] < 0.75  # chance is a half
    with pytest.raises(ValueError, match="owners"):
        cross_validate(features, labels, 2, config, owner[:-1])


def test_the_classifier_trains_on_one_thread_and_gives_the_rest_back():
    import torch

    from masspush.real.classifier import one_thread

    before = torch.get_num_threads()
    with one_thread():
        assert torch.get_num_threads() == 1
    assert torch.get_num_threads() == before


def test_the_start_pose_control_sees_the_start_pose_alone():
    from masspush.data.rollout import Episodes
    from masspush.real.classifier import start_pose_features

    obs = np.zeros((2, 3, 4), np.float32)
    obs[:, 0] = [[0.1, 0.2, 0.0, 0.3], [0.0, -0.1, np.pi / 2, -0.2]]
    obs[:, 1:] = 9.0  # what the pushes did: never seen
    episodes = Episodes.history(obs, np.zeros((2, 2, 2), np.float32), np.full((2, 2), 0.12))
    got = start_pose_features(episodes)
    np.testing.assert_allclose(
        got,
        [[0.1, 0.2, 1.0, 0.0, 0.3, 0.12, 0.12], [0.0, -0.1, 0.0, 1.0, -0.2, 0.12, 0.12]],
        atol=1e-6,
    )
