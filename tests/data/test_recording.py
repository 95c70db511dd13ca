import json

import numpy as np
import pytest

from masspush.data.recording import (
    Recording,
    RecordingError,
    check_recording,
    read_recording,
    write_recording,
)

HEADER = {
    "format": "masspush-episodes",
    "version": 1,
    "n_links": 2,
    "units": {"length": "m", "angle": "rad", "mass": "kg"},
    "robot": "ur10",
}
EPISODE = {
    "id": "a-01",
    "lengths": [0.1, 0.12],
    "observations": [[0.0, 0.0, 0.1, 0.2], [0.05, 0.01, 0.3, -0.1], [0.07, 0.02, 0.2, 0.0]],
    "actions": [[0.5, -0.5], [1.0, 0.5]],
    "label": "even",
    "masses": [0.16, 0.16],
    "speeds": [2.5, 4.2],
    "estimates": [[0.6, 0.4], [0.55, 0.45]],
    "failure": "left_workspace",
}


NUMBERS = ("lengths", "observations", "actions", "masses", "speeds", "estimates")


def write_lines(tmp_path, *objects) -> str:
    path = tmp_path / "rec.jsonl"
    path.write_text("\n".join(o if isinstance(o, str) else json.dumps(o) for o in objects) + "\n")
    return str(path)


def test_a_recording_carries_the_labs_geometry(tmp_path):
    from masspush.config import ChainGeometry

    lab = ChainGeometry(link_width=0.05, link_height=0.03, joint_gap=0.02, tool_radius=0.006)
    recording = Recording(n_links=2, episodes=[EPISODE], geometry=lab)
    assert read_recording(write_recording(tmp_path / "g.jsonl", recording)).geometry == lab
    assert (
        read_recording(
            write_recording(tmp_path / "n.jsonl", Recording(2, episodes=[EPISODE]))
        ).geometry
        is None
    )


@pytest.mark.parametrize(
    "geometry",
    [
        {"link_width": 0.05},
        {"link_width": 0.05, "link_height": 0.03, "joint_gap": 0.02, "tool_radius": "6 mm"},
        {"link_width": 0.05, "link_height": 0.03, "joint_gap": -0.02, "tool_radius": 0.006},
        {"link_width": 50, "link_height": 30, "joint_gap": 20, "tool_radius": 6},
        [0.05, 0.03, 0.02, 0.006],
    ],
)
def test_a_bad_geometry_is_a_header_problem(tmp_path, geometry):
    problems = check_recording(write_lines(tmp_path, {**HEADER, "geometry": geometry}, EPISODE))
    assert [(p.line, p.field) for p in problems] == [(1, "geometry")]


def test_a_recording_round_trips_and_becomes_predictor_input(tmp_path):
    short = {**EPISODE, "id": "b", "observations": EPISODE["observations"][:2]}
    short["actions"] = EPISODE["actions"][:1]
    del short["label"], short["masses"], short["speeds"], short["failure"], short["estimates"]
    recording = Recording(n_links=2, robot="ur10", setting="2link-0.1-1", episodes=[EPISODE, short])
    path = write_recording(tmp_path / "r.jsonl", recording)
    back = read_recording(path)
    assert back.setting == "2link-0.1-1" and len(back.episodes) == 2
    for got, wrote in zip(back.episodes, recording.episodes, strict=True):
        assert set(got) == set(wrote)
        for key, value in wrote.items():
            if key in NUMBERS:
                np.testing.assert_allclose(got[key], value, rtol=1e-6)
            else:
                assert got[key] == value
    assert back.labels == ["even", None]
    episodes = back.to_episodes()
    assert episodes.observations.shape == (2, 3, 4)
    np.testing.assert_allclose(episodes.observations[0], EPISODE["observations"])
    assert np.isnan(episodes.observations[1, 2]).all()  # the shorter episode is padded
    np.testing.assert_allclose(episodes.masses[0], [0.16, 0.16])


def test_a_write_cut_short_leaves_the_recording_as_it_was(tmp_path, monkeypatch):
    path = write_recording(tmp_path / "r.jsonl", Recording(2, episodes=[EPISODE]))
    before = path.read_text()

    def full_disk(*_):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("masspush.data.recording.os.replace", full_disk)
    longer = Recording(2, episodes=[EPISODE, {**EPISODE, "id": "a-02"}])
    with pytest.raises(OSError, match=r"r\.jsonl: cannot write the recording: No space left"):
        write_recording(path, longer)
    assert path.read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.jsonl"]  # no partial file left


def test_a_recording_read_at_its_speeds_passes_each_push_through_the_reader():
    seen = []

    def reader(config, lengths, action, speed):
        seen.append((np.asarray(config).copy(), list(lengths), speed))
        return np.array([speed, action[1]], np.float32)

    no_speeds = {k: v for k, v in EPISODE.items() if k != "speeds"}
    recording = Recording(n_links=2, setting="2link-0.1-1", episodes=[EPISODE, no_speeds])
    episodes = recording.to_episodes(reader)
    np.testing.assert_allclose(episodes.actions[0, :, 0], EPISODE["speeds"])
    np.testing.assert_allclose(episodes.actions[0, :, 1], np.asarray(EPISODE["actions"])[:, 1])
    # Without speeds the actions are the recorded ones, as without a reader.
    np.testing.assert_allclose(episodes.actions[1], EPISODE["actions"])
    np.testing.assert_allclose(recording.to_episodes().actions[0], EPISODE["actions"])
    # Each push is read from the rest pose it was made from.
    assert len(seen) == len(EPISODE["speeds"])
    for k, (config, lengths, speed) in enumerate(seen):
        np.testing.assert_allclose(config, EPISODE["observations"][k], rtol=1e-6)
        assert lengths == list(EPISODE["lengths"]) and speed == EPISODE["speeds"][k]


def test_reading_a_files_speeds_leaves_its_recorded_actions_as_they_were(tmp_path):
    write_recording(tmp_path / "r.jsonl", Recording(2, setting="2link-0.1-1", episodes=[EPISODE]))
    recording = read_recording(tmp_path / "r.jsonl")  # float32 arrays, as a file gives them
    recorded = np.array(recording.episodes[0]["actions"])
    episodes = recording.to_episodes(lambda config, lengths, action, speed: np.array([0.9, 0.0]))
    np.testing.assert_allclose(episodes.actions[0, :, 0], 0.9)
    np.testing.assert_array_equal(recording.episodes[0]["actions"], recorded)


@pytest.mark.parametrize(
    ("change", "line", "field", "message"),
    [
        ({"format": "csv"}, 1, "format", "must be 'masspush-episodes'"),
        ({"version": 2}, 1, "version", "reads version 1"),
        ({"units": {"length": "mm"}}, 1, "units", "must be"),
        ({"n_links": 1}, 1, "n_links", "integer >= 2"),
        ({"colour": "red"}, 1, "colour", "unknown header field"),
        ({"version": True}, 1, "version", "reads version 1"),
        ({"version": 1.0}, 1, "version", "reads version 1"),
    ],
)
def test_header_problems_name_line_and_field(tmp_path, change, line, field, message):
    problems = check_recording(write_lines(tmp_path, {**HEADER, **change}, EPISODE))
    assert any(p.line == line and p.field == field and message in p.message for p in problems)


@pytest.mark.parametrize(
    ("change", "field", "message"),
    [
        ({"id": ""}, "id", "non-empty string"),
        ({"lengths": [0.1]}, "lengths", "must be a 2 array"),
        ({"lengths": [0.1, -0.1]}, "lengths", "must be > 0"),
        ({"observations": [[0, 0, 0]] * 3}, "observations", "k x 4"),
        ({"observations": EPISODE["observations"][:2]}, "observations", "one rest pose more"),
        ({"actions": [[0.5, -0.5], [1.5, 0.5]]}, "actions[1][0]", "outside the action box"),
        ({"actions": [[0.5, "x"], [1.0, 0.5]]}, "actions", "array of numbers"),
        ({"masses": [0.1, 0.0]}, "masses", "> 0 (kg)"),
        ({"label": 3}, "label", "must be a string"),
        ({"speed": 3}, "speed", "unknown episode field"),
        ({"actions": [[True, 0.5], [1.0, 0.5]]}, "actions", "holds True"),
        ({"lengths": ["0.1", 0.12]}, "lengths", "holds '0.1'"),
        ({"observations": [[0.0, 0.0, 0.1, 1e300]] * 3}, "observations[0][3]", "in float32"),
        ({"masses": None}, "masses", "leave the field out"),
        ({"label": "even\x1b[2J"}, "label", "printable"),
        ({"speeds": [1.0]}, "speeds", "must be a 2 array"),
        ({"speeds": [1.0, -0.5]}, "speeds", ">= 0 (m/s)"),
        ({"speeds": None}, "speeds", "leave the field out"),
        ({"estimates": [[0.5, 0.5]]}, "estimates", "must be a 2 x 2 array"),
        ({"estimates": [[0.5, 0.6], [0.5, 0.5]]}, "estimates", "add up to 1"),
        ({"estimates": [[1.5, -0.5], [0.5, 0.5]]}, "estimates", "add up to 1"),
        ({"estimates": None}, "estimates", "leave the field out"),
        ({"failure": ""}, "failure", "non-empty string"),
        ({"failure": 3}, "failure", "non-empty string"),
    ],
)
def test_episode_problems_name_line_and_field(tmp_path, change, field, message):
    path = write_lines(tmp_path, HEADER, EPISODE, {**EPISODE, "id": "x", **change})
    problems = check_recording(path)
    assert [(p.line, p.field) for p in problems if message in p.message] == [(3, field)]


def test_a_line_nested_too_deeply_is_a_problem_not_a_crash(tmp_path):
    problems = check_recording(write_lines(tmp_path, HEADER, "[" * 100_000 + "]" * 100_000))
    assert any(p.line == 2 and "nested too deeply" in p.message for p in problems)


def test_structural_problems_are_reported_with_their_lines(tmp_path):
    assert "empty" in str(check_recording(write_lines(tmp_path, ""))[0])
    problems = check_recording(write_lines(tmp_path, HEADER, EPISODE, "{not json", EPISODE))
    text = [str(p) for p in problems]
    assert any(t.startswith("line 3: not valid JSON") for t in text)
    assert any(t.startswith("line 4, field 'id'") and "repeats line 2" in t for t in text)
    missing = {k: v for k, v in EPISODE.items() if k != "actions"}
    problems = check_recording(write_lines(tmp_path, HEADER, missing))
    assert [str(p) for p in problems] == ["line 2, field 'actions': missing (required)"]
    with pytest.raises(RecordingError, match="1 problem"):
        read_recording(write_lines(tmp_path, HEADER, missing))
    assert "no file" in str(check_recording(tmp_path / "nothing.jsonl")[0])


def test_writing_refuses_what_could_not_be_read_back(tmp_path):
    bad = {**EPISODE, "actions": [[2.0, 0.0], [0.0, 0.0]]}
    with pytest.raises(RecordingError, match="outside the action box"):
        write_recording(tmp_path / "r.jsonl", Recording(n_links=2, episodes=[bad]))
    assert not (tmp_path / "r.jsonl").exists()


def test_the_example_recording_is_valid():
    from pathlib import Path

    example = Path(__file__).parents[2] / "docs" / "examples" / "recording.jsonl"
    assert check_recording(example) == []


def test_a_recording_read_in_pieces_is_the_whole_and_checked_first(tmp_path):
    from masspush.data.recording import iter_recording

    episodes = [{**EPISODE, "id": f"e{i}"} for i in range(7)]
    path = write_recording(tmp_path / "r.jsonl", Recording(2, setting="s", episodes=episodes))
    pieces = list(iter_recording(path, chunk=3))
    assert [len(p.episodes) for p in pieces] == [3, 3, 1] and pieces[0].setting == "s"
    whole = read_recording(path).to_episodes()
    joined = [e["id"] for p in pieces for e in p.episodes]
    assert joined == [f"e{i}" for i in range(7)]
    np.testing.assert_array_equal(pieces[1].to_episodes().observations, whole.observations[3:6])
    with open(path, "a") as f:
        f.write("{broken\n")
    with pytest.raises(RecordingError, match="line 9"):
        next(iter_recording(path))  # refused before the first piece
