"""Malformed recordings from a generator (issue 26): every field given every kind of wrong
value, every structural break, every truncation and random byte damage. A bad file is
reported as problems, never a crash; what the checker passes, the reader reads."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from masspush.cli import main
from masspush.data.recording import (
    MAX_PUSHES,
    RecordingError,
    check_recording,
    read_recording,
)

# The generator starts from the documented example (docs/examples/recording.jsonl, itself
# checked by test_recording.py), its first episode given a label, a failure and speeds so that
# every field occurs.
_EXAMPLE = Path(__file__).parents[2] / "docs" / "examples" / "recording.jsonl"
HEADER, _FIRST = (json.loads(line) for line in _EXAMPLE.read_text().splitlines()[:2])
EPISODE = {**_FIRST, "label": "even", "failure": "left_workspace", "speeds": [1.2, 0.8]}

# Values of the wrong kind for any field: no field of a recording accepts all of these.
WRONG_KINDS = [None, True, "1", 1e39, -1, [], {}, [[[]]], "\x1b[2J", math.nan]
# What each field may hold, so that only the values it may not are counted as bad.
ACCEPTS = {
    "robot": lambda v: isinstance(v, str),
    "setting": lambda v: isinstance(v, str),
    "label": lambda v: isinstance(v, str) and v.isprintable(),
    "failure": lambda v: isinstance(v, str) and v.isprintable() and v,
    "id": lambda v: isinstance(v, str) and v.isprintable() and v,
}


def _lines(header: dict, *episodes: dict) -> str:
    return "\n".join(json.dumps(o) for o in (header, *episodes)) + "\n"


def _bad_files() -> list[tuple[str, str]]:
    """(what, text) of files that are not valid recordings."""
    out = []
    for key in HEADER:
        for value in WRONG_KINDS:
            if not ACCEPTS.get(key, lambda _: False)(value):
                out.append((f"header {key}={value!r}", _lines({**HEADER, key: value}, EPISODE)))
        if key in ("format", "version", "n_links", "units"):  # the required ones
            out.append((f"header without {key}", _lines(
                {k: v for k, v in HEADER.items() if k != key}, EPISODE)))  # fmt: skip
    for key in EPISODE:
        for value in WRONG_KINDS:
            if not ACCEPTS.get(key, lambda _: False)(value):
                bad = {**EPISODE, key: value}
                out.append((f"episode {key}={value!r}", _lines(HEADER, bad)))
        if key in ("id", "lengths", "observations", "actions"):
            out.append((f"episode without {key}", _lines(
                HEADER, {k: v for k, v in EPISODE.items() if k != key})))  # fmt: skip
        if key in ("lengths", "observations", "actions", "masses", "speeds"):  # one bad number
            array = np.asarray(EPISODE[key], dtype=object)
            for value in (True, "0.1", None, math.inf, 1e39, [0.1]):
                damaged = array.copy()
                damaged.flat[-1] = value
                out.append((f"episode {key}[-1]={value!r}", _lines(
                    HEADER, {**EPISODE, key: damaged.tolist()})))  # fmt: skip
    too_long = {
        **EPISODE,
        "actions": [[0.1, 0.1]] * (MAX_PUSHES + 1),
        "observations": [[0.0, 0.0, 0.0, 0.0]] * (MAX_PUSHES + 2),
    }
    good = _lines(HEADER, EPISODE)
    marked = _lines(HEADER, {**EPISODE, "lengths": [12345.5, *EPISODE["lengths"][1:]]})
    out += [
        ("empty", ""),
        ("blank lines", "\n \n\n"),
        ("header only", _lines(HEADER)),
        ("episode first", _lines(EPISODE, HEADER)),
        ("two headers", _lines(HEADER, HEADER)),
        ("a list", "[1, 2]\n"),
        ("repeated id", _lines(HEADER, EPISODE, EPISODE)),
        ("unknown field", _lines(HEADER, {**EPISODE, "x": 1})),
        ("NaN token", marked.replace("12345.5", "NaN")),
        ("Infinity token", marked.replace("12345.5", "-Infinity")),
        ("too many pushes", _lines(HEADER, too_long)),
        ("deep nesting", _lines(HEADER) + "[" * 50_000 + "]" * 50_000 + "\n"),
    ]
    # Every cut in the middle of a line.
    breaks = {i for i, c in enumerate(good) if c == "\n"}
    for cut in range(1, len(good) - 1, 7):
        if cut not in breaks and cut - 1 not in breaks:
            out.append((f"cut at {cut}", good[:cut]))
    return out


BAD = _bad_files()


@pytest.mark.parametrize(("what", "text"), BAD, ids=[w for w, _ in BAD])
def test_a_malformed_recording_is_problems_not_a_crash(what, text, tmp_path):
    path = tmp_path / "bad.jsonl"
    path.write_text(text)
    problems = check_recording(path)
    assert problems, f"accepted: {what}"
    assert all(p.line >= 0 and str(p).isprintable() for p in problems)
    with pytest.raises(RecordingError):
        read_recording(path)


def test_bytes_that_are_not_text_and_lines_too_long_are_problems(tmp_path, capsys):
    for name, data in (
        ("latin1", json.dumps(HEADER).encode() + b"\n\xff\xfe\n"),
        ("garbage", bytes(range(256)) * 8),
        ("long", json.dumps(HEADER).encode() + b"\n" + b" " * (9 << 20) + b"x\n"),
    ):
        path = tmp_path / f"{name}.jsonl"
        path.write_bytes(data)
        assert check_recording(path), name
        assert main(["check-episodes", str(path)]) == 1
        assert "Traceback" not in capsys.readouterr().err


def test_random_damage_is_problems_or_a_good_recording(tmp_path):
    """Random byte changes: whatever the checker passes, the reader reads and the predictor
    input is finite; whatever it refuses, the reader refuses too."""
    good = _lines(HEADER, EPISODE, {**EPISODE, "id": "b"}).encode()
    rng = np.random.default_rng(0)
    path = tmp_path / "damaged.jsonl"
    refused = 0
    for _ in range(300):
        data = bytearray(good)
        for i in rng.integers(0, len(data), size=rng.integers(1, 4)):
            data[i] = rng.integers(0, 256)
        path.write_bytes(bytes(data))
        if check_recording(path):
            refused += 1
            with pytest.raises(RecordingError):
                read_recording(path)
        else:
            episodes = read_recording(path).to_episodes()
            assert np.isfinite(episodes.observations).all()
            assert np.abs(episodes.actions).max() <= 1
    assert refused > 200  # most damage is caught; the rest changed a digit or a letter
