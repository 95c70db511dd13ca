import copy
import re
import warnings

import numpy as np
import pytest
import torch

from masspush.cli import main
from masspush.data.recording import Recording, read_recording, write_recording
from masspush.learn.push_density import PushDensity, load_push_density
from masspush.models import shipped_file
from masspush.real.classifier_jobs import ClassifyJob, classify_by_posterior
from masspush.real.density_tuning import (
    CalibrationWarning,
    TuneConfig,
    check_calibration_length,
    class_log_likelihoods,
    cross_validate_tuning,
    evidence_per_push,
    first_pushes,
    friction_grid,
    labelled_pushes,
    posterior_accuracy,
    posterior_classes,
    push_ladder,
    record_tuning,
    true_class_evidence,
    tune_density,
    tuned_classes,
)

# Toy densities read toy tables, at an end of the sorting grid: a warning that is right there.
TOY_TABLES = pytest.mark.filterwarnings("ignore::masspush.real.table_friction.FrictionDriftWarning")

SETTING = "real-ur10"
CLASSES = {"light-heavy": (0.064, 0.256), "heavy-light": (0.256, 0.064)}
LENGTHS = [0.12, 0.12]


def tiny_density(seed: int, mass_scale: float = 0.05) -> PushDensity:
    """A small density with the shipped real-ur10 density's metadata (so the commands take
    it for that setting's), whose outcome hangs strongly on the masses: their standardised
    inputs are spread by `mass_scale`; its outcomes stay small, so no angle wraps."""
    meta = load_push_density(shipped_file(SETTING, "push-density")).meta
    torch.manual_seed(seed)
    net = PushDensity(12, 4, components=2, width=16, depth=1, meta=dict(meta))
    with torch.no_grad():
        net.x_mean[3:5] = float(np.log(0.13))
        net.x_std[3:5] = mass_scale
        net.y_std[:] = 0.01  # outcomes of cm and hundredths of a radian: no wrapped angle
    return net.eval()


def lab_episodes(teacher: PushDensity, per_class: int, pushes: int, seed: int) -> list[dict]:
    """Episodes of each class whose outcomes the `teacher` density draws (the 'lab')."""
    rng = np.random.default_rng(seed)
    episodes = []
    for label, masses in CLASSES.items():
        for i in range(per_class):
            pose = np.array([*rng.uniform(-0.05, 0.05, 2), rng.uniform(-3, 3), rng.uniform(-1, 1)])
            observations, actions = [pose], []
            for _ in range(pushes):
                action = rng.uniform(-1, 1, 2)
                after = teacher.sample(observations[-1], action, np.array([masses]),
                                       np.array([0.7]), LENGTHS, rng)[0]  # fmt: skip
                observations.append(after)
                actions.append(action)
            episodes.append({"id": f"{label}-{i}", "label": label, "masses": list(masses),
                             "lengths": LENGTHS, "observations": np.array(observations),
                             "actions": np.array(actions)})  # fmt: skip
    return episodes


def record(path, episodes) -> Recording:
    write_recording(path, Recording(2, robot="sim", setting=SETTING, episodes=episodes))
    return read_recording(path)


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """A 'lab' density, a 'simulation' density that differs from it, and a labelled
    recording drawn in the lab (6 episodes of 8 pushes per class)."""
    teacher = tiny_density(1)
    student = tiny_density(1)
    with torch.no_grad():  # the simulation's outcomes are off by a systematic shift
        student.mean.bias.add_(0.8)
    folder = tmp_path_factory.mktemp("lab")
    recording = record(folder / "lab.jsonl", lab_episodes(teacher, 6, 8, seed=0))
    student_file = folder / "student.pt"
    student.save(student_file)
    return teacher, student, recording, folder / "lab.jsonl", student_file


def mean_log_lik(density, recording, labels_masses) -> float:
    pushes = labelled_pushes(recording)
    grid = friction_grid(density, 4)
    log_lik = class_log_likelihoods(density, pushes, labels_masses, grid)
    labels = [list(CLASSES).index(e["label"]) for e in recording.episodes]
    return float(np.mean(log_lik[np.arange(len(labels)), labels]))


def test_tuning_raises_the_likelihood_of_the_labs_unseen_pushes_and_the_anchor_holds_it(
    lab, tmp_path
):
    teacher, student, recording, _, _ = lab
    masses = np.array(list(CLASSES.values()))
    labels = np.array([list(CLASSES).index(e["label"]) for e in recording.episodes])
    before = [p.detach().clone() for p in student.parameters()]
    tuned = tune_density(student, labelled_pushes(recording), masses[labels],
                         TuneConfig(steps=40, lr=3e-3, anchor=0.0), progress=False)  # fmt: skip
    # the original is left as it was
    assert all(torch.equal(a, b) for a, b in zip(before, student.parameters(), strict=True))
    unseen = record(tmp_path / "unseen.jsonl", lab_episodes(teacher, 4, 4, seed=5))
    assert mean_log_lik(tuned, unseen, masses) > mean_log_lik(student, unseen, masses) + 1.0
    held = tune_density(student, labelled_pushes(recording), masses[labels],
                        TuneConfig(steps=40, lr=3e-3, anchor=1e3), progress=False)  # fmt: skip

    def moved(net):  # the penalised quantity: the squared change of the weights
        pairs = zip(net.parameters(), student.parameters(), strict=True)
        return sum(float(((a - b).detach() ** 2).sum()) for a, b in pairs)

    assert moved(held) < 0.1 * moved(tuned)


def test_episodes_are_sorted_by_their_class_posterior_with_the_right_density(lab):
    teacher, _, recording, _, _ = lab
    masses = np.array(list(CLASSES.values()))
    log_lik = class_log_likelihoods(teacher, labelled_pushes(recording), masses,
                                    friction_grid(teacher, 4))  # fmt: skip
    labels = np.array([list(CLASSES).index(e["label"]) for e in recording.episodes])
    assert log_lik.shape == (len(labels), 2) and np.isfinite(log_lik).all()
    assert np.mean(log_lik.argmax(1) == labels) >= 0.9


def test_first_pushes_keeps_each_episodes_first_ones(lab):
    pushes = labelled_pushes(lab[2])
    first, every = first_pushes(pushes, 1), first_pushes(pushes, None)
    for f, e, p in zip(first, every, pushes, strict=True):
        assert len(f.actions) == len(f.starts) == len(f.outputs) == min(1, len(p.actions))
        assert np.array_equal(f.actions, p.actions[:1])
        assert len(e.actions) == len(p.actions)


def test_the_density_that_made_the_pushes_explains_them_best(lab):
    teacher, student, recording, _, _ = lab
    masses = np.array(list(CLASSES.values()))
    labels = np.array([list(CLASSES).index(e["label"]) for e in recording.episodes])
    pushes, grid = labelled_pushes(recording), friction_grid(teacher, 4)
    own = evidence_per_push(teacher, pushes, labels, masses, grid)
    assert own > evidence_per_push(student, pushes, labels, masses, grid) + 1
    # the true classes' mean log-likelihood per push (episodes of equal length)
    assert own == pytest.approx(mean_log_lik(teacher, recording, masses) / 8)
    read = class_log_likelihoods(teacher, pushes, masses, grid)
    assert true_class_evidence(read, pushes, labels) == pytest.approx(own)
    with pytest.raises(ValueError, match="no labelled push"):
        evidence_per_push(teacher, first_pushes(pushes, 0), labels, masses, grid)


def test_push_ladder_doubles_below_the_longest_episode():
    assert push_ladder(0) == push_ladder(2) == []
    assert push_ladder(3) == [2]
    assert push_ladder(32) == [2, 4, 8, 16]
    assert push_ladder(33) == [2, 4, 8, 16, 32]


def test_cross_validation_tunes_without_the_held_out_fold_and_counts_every_episode(lab):
    _, student, recording, _, _ = lab
    masses = np.array(list(CLASSES.values()))
    labels = np.array([list(CLASSES).index(e["label"]) for e in recording.episodes])
    config = TuneConfig(steps=5, lr=3e-3, folds=3)
    scores = cross_validate_tuning(student, labelled_pushes(recording), labels, masses, config,
                                   progress=False)  # fmt: skip
    assert np.sum(scores["confusion"]) == len(labels) == len(scores["predicted"])
    assert 0 <= scores["accuracy"] <= 1 and scores["chance"] == pytest.approx(0.5)
    log_lik = np.array(scores["log_likelihoods"])
    assert log_lik.shape == (len(labels), 2)
    assert (log_lik.argmax(1) == scores["predicted"]).all()
    # held-out episodes read from their first push: the same folds' densities, less evidence
    first = cross_validate_tuning(student, labelled_pushes(recording), labels, masses, config,
                                  progress=False, count=1)  # fmt: skip
    one = class_log_likelihoods(student, first_pushes(labelled_pushes(recording), 1), masses,
                                friction_grid(student, config.sort_frictions,
                                              config.sort_range))  # fmt: skip
    assert np.mean(one.argmax(1) == labels) == pytest.approx(first["untuned_accuracy"])
    assert not np.allclose(first["log_likelihoods"], log_lik)
    assert first["by_pushes"] == []  # nothing shorter than one push to read
    # the caller's own untuned reading is used, not read again
    given = cross_validate_tuning(student, labelled_pushes(recording), labels, masses, config,
                                  progress=False, count=1, untuned=-one)  # fmt: skip
    assert given["untuned_accuracy"] == pytest.approx(np.mean((-one).argmax(1) == labels))
    assert given["log_likelihoods"] == first["log_likelihoods"]
    with pytest.raises(ValueError, match="untuned"):
        cross_validate_tuning(student, labelled_pushes(recording), labels, masses, config,
                              progress=False, untuned=one[:, :1])  # fmt: skip
    # the early readings are what the same folds give with the episodes cut short
    assert [s["pushes"] for s in scores["by_pushes"]] == [2, 4]  # episodes of 8 pushes
    two = cross_validate_tuning(student, labelled_pushes(recording), labels, masses, config,
                                progress=False, count=2)  # fmt: skip
    assert scores["by_pushes"][0]["accuracy"] == pytest.approx(two["accuracy"])
    with pytest.raises(ValueError, match="at least 7 episodes"):
        cross_validate_tuning(student, labelled_pushes(recording), labels, masses,
                              TuneConfig(folds=7), progress=False)  # fmt: skip


def test_tune_density_and_classify_commands(lab, tmp_path, capsys):
    _, _, _, recording_file, student_file = lab
    out = tmp_path / "tuned.pt"
    args = ["tune-density", "--setting", SETTING, "--episodes", str(recording_file),
            "--density", str(student_file), "--steps", "5", "--lr", "0.003"]  # fmt: skip
    assert main([*args, "--folds", "3", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "3-fold cross-validated" in printed and "untuned density" in printed
    assert re.search(r"explains these pushes at -?\d+\.\d{3} nats per push", printed)
    assert "read from their first pushes only" in printed and "2: " in printed
    tuned = load_push_density(out).meta["tuned"]
    assert tuned["classes"] == {k: list(v) for k, v in sorted(CLASSES.items())}
    assert tuned["cross_validation"]["confusion"] is not None
    # Several recordings are tuned on together.
    both = tmp_path / "both.pt"
    assert main([*args, "--folds", "0", "--out", str(both), "--episodes",
                 f"{recording_file},{recording_file}"]) == 0  # fmt: skip
    assert "24 episodes, 2 classes, 192 pushes" in capsys.readouterr().out
    assert load_push_density(both).meta["tuned"]["episodes"] == [str(recording_file)] * 2
    assert load_push_density(both).meta["tuned"]["from"] == str(student_file)
    assert main(["classify", "--density", str(out), "--episodes", str(recording_file)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 15 and lines[12].startswith("accuracy on the 12 labelled")
    assert lines[13].startswith("table friction") and lines[14].startswith("calibration's")
    # Bad inputs: one line each, before any work.
    assert main(["classify", "--density", str(student_file), "--episodes",
                 str(recording_file)]) == 2  # fmt: skip
    assert "not a tuned density" in capsys.readouterr().err
    assert main(["classify", "--episodes", str(recording_file)]) == 2
    assert "either --classifier or --density" in capsys.readouterr().err
    assert main([*args, "--folds", "7", "--out", str(tmp_path / "x.pt")]) == 2
    assert "at least 7 episodes" in capsys.readouterr().err
    assert not (tmp_path / "x.pt").exists()
    assert main([*args, "--frictions", "100000000", "--out", str(tmp_path / "z.pt")]) == 2
    assert "frictions: batch_size" in capsys.readouterr().err
    assert not (tmp_path / "z.pt").exists()
    assert main([*args, "--sort-frictions", "100000000", "--out", str(tmp_path / "z.pt")]) == 2
    assert "sort_frictions: batch_size" in capsys.readouterr().err
    assert not (tmp_path / "z.pt").exists()
    assert main([*args, "--anchor", "-1"]) == 2
    assert "anchor" in capsys.readouterr().err
    unlabelled = read_recording(recording_file)
    for e in unlabelled.episodes:
        e.pop("masses")
    write_recording(tmp_path / "nomass.jsonl", unlabelled)
    assert main([*args[:4], str(tmp_path / "nomass.jsonl"), *args[5:], "--out",
                 str(tmp_path / "y.pt")]) == 2  # fmt: skip
    assert "the same masses" in capsys.readouterr().err


@TOY_TABLES
def test_a_density_tuned_on_short_episodes_warns_where_it_sorts_longer_ones(lab, tmp_path):
    teacher, _, _, recording_file, student_file = lab
    out = tmp_path / "tuned.pt"
    assert main(["tune-density", "--setting", SETTING, "--episodes", str(recording_file),
                 "--density", str(student_file), "--steps", "1", "--folds", "0",
                 "--out", str(out)]) == 0  # fmt: skip
    density = load_push_density(out)
    assert density.meta["tuned"]["pushes_per_episode"] == 8.0
    longer = tmp_path / "longer.jsonl"
    record(longer, lab_episodes(teacher, 2, 16, seed=3))
    with pytest.warns(CalibrationWarning, match="8.0 pushes on average and sorts episodes of 16.0"):
        classify_by_posterior(ClassifyJob(str(longer), density=str(out)))
    with warnings.catch_warnings():  # as long as the calibration's, or a little longer: none
        warnings.simplefilter("error", CalibrationWarning)
        classify_by_posterior(ClassifyJob(str(recording_file), density=str(out)))
        check_calibration_length(density, 10.0, "here")
        del density.meta["tuned"]["pushes_per_episode"]  # tuned before it was kept
        check_calibration_length(density, 100.0, "here")
    density.meta["tuned"]["pushes_per_episode"] = 8.0
    with pytest.warns(CalibrationWarning, match="^here was tuned"):
        check_calibration_length(density, 10.1, "here")


def test_a_density_tuned_outside_the_command_is_recorded_so_sorting_and_the_length_check_read_it(
    lab,
):
    teacher, student, recording, _, _ = lab
    teacher = copy.deepcopy(teacher)  # the fixture's is shared
    masses = np.array(list(CLASSES.values()))
    pushes = first_pushes(labelled_pushes(recording), 2)
    with pytest.raises(ValueError, match="not a tuned density"):
        tuned_classes(student, "student.pt")
    config = TuneConfig(frictions=4)
    record_tuning(teacher, list(CLASSES), masses, config, pushes, {"from": "teacher"})
    names, read = tuned_classes(teacher, "teacher.pt")
    assert names == list(CLASSES) and np.allclose(read, masses)
    assert teacher.meta["tuned"]["pushes_per_episode"] == 2.0
    assert teacher.meta["tuned"]["config"]["frictions"] == 4
    assert teacher.meta["tuned"]["from"] == "teacher"
    assert posterior_accuracy(teacher, recording, "lab.jsonl")["accuracy"] >= 0.9
    with pytest.warns(CalibrationWarning, match="2.0 pushes on average and sorts episodes of 8.0"):
        check_calibration_length(teacher, 8.0, "teacher.pt")


@TOY_TABLES
def test_classify_reads_each_episode_from_its_first_pushes_where_told(tmp_path):
    teacher = tiny_density(1, mass_scale=5.0)  # classes a push or two cannot tell apart
    recording_file = tmp_path / "close.jsonl"
    recording = record(recording_file, lab_episodes(teacher, 6, 8, seed=0))
    record_tuning(
        teacher, list(CLASSES), np.array(list(CLASSES.values())), TuneConfig(frictions=4),
        first_pushes(labelled_pushes(recording), 1),
    )  # fmt: skip
    density = tmp_path / "lab.pt"
    teacher.save(density)
    sureness = {}
    for pushes in (1, None):
        _, log_post = posterior_classes(teacher, recording, "lab.jsonl", pushes)
        job = ClassifyJob(str(recording_file), density=str(density), pushes=pushes)
        if pushes is None:  # all 8 pushes against a calibration of 1: the length warning
            with pytest.warns(CalibrationWarning, match="1.0 pushes on average"):
                lines = classify_by_posterior(job)
        else:
            lines = classify_by_posterior(job)
        printed = [float(re.search(r"p=([0-9.]+)", line)[1]) for line in lines if "p=" in line]
        assert printed == pytest.approx(np.exp(log_post.max(1)), abs=0.006)
        sureness[pushes] = np.mean(printed)
    assert sureness[None] > sureness[1] + 0.01  # more pushes, surer: the cut was made
    with pytest.raises(ValueError, match="--pushes is for --density"):
        ClassifyJob(str(recording_file), classifier=str(density), pushes=2)
