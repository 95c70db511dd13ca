"""Recorded episodes from a robot: a versioned, human-readable file format, and its validator.

A recording is a JSON Lines file (UTF-8, one JSON object per line). Line 1 is the header,
every further line one episode. docs/real-robot.md specifies every field; in short:

    {"format": "masspush-episodes", "version": 1, "n_links": 2,
     "units": {"length": "m", "angle": "rad", "mass": "kg"}, "robot": "ur10", ...}
    {"id": "a-01", "lengths": [0.1, 0.1], "observations": [[x, y, yaw, q1], ...],
     "actions": [[a1, a2], ...], "label": "even", "masses": [0.16, 0.16]}

Observations are the chain's rest configurations q_0..q_k in the table frame (x, y in m;
yaw and joint angles in rad), one more than the actions; actions are the pushes as the
policy chose them, in masspush's action box [-1, 1]^2 (docs/real-robot.md gives the
mapping to a contact point, direction and speed). `label` and `masses` are optional.

`check_recording` reports every problem with its line and field; `read_recording` refuses
a file with any problem and returns it as `Episodes` (the predictor's input).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from masspush.data.rollout import Episodes, empty_episodes

FORMAT, VERSION = "masspush-episodes", 1
UNITS = {"length": "m", "angle": "rad", "mass": "kg"}
HEADER_FIELDS = {"format", "version", "n_links", "units", "robot", "setting", "created", "notes"}
EPISODE_FIELDS = {"id", "lengths", "observations", "actions", "label", "masses", "notes"}


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a recording, where it is."""

    line: int
    field: str
    message: str

    def __str__(self) -> str:
        where = f"line {self.line}" + (f", field {self.field!r}" if self.field else "")
        return f"{where}: {self.message}"


class RecordingError(ValueError):
    """A recording that cannot be used; `problems` lists every reason."""

    def __init__(self, path: str | os.PathLike, problems: list[Problem]):
        self.problems = problems
        shown = "\n".join(f"  {p}" for p in problems[:20])
        more = f"\n  ... and {len(problems) - 20} more" if len(problems) > 20 else ""
        super().__init__(f"{path}: {len(problems)} problem(s)\n{shown}{more}")


@dataclass
class Recording:
    """A recording's header and episodes (lists as in the file)."""

    n_links: int
    robot: str = ""
    setting: str | None = None
    notes: str = ""
    episodes: list[dict[str, Any]] = field(default_factory=list)

    @property
    def labels(self) -> list[str | None]:
        return [e.get("label") for e in self.episodes]

    def to_episodes(self) -> Episodes:
        """The episodes as the predictor's input, padded to the longest with NaN (an episode
        recorded with fewer pushes is scored after its last one)."""
        k = max(len(e["actions"]) for e in self.episodes)
        n, d = self.n_links, 3 + self.n_links - 1
        out = empty_episodes(len(self.episodes), k, n)
        out.index[:] = np.arange(len(self.episodes))
        for i, e in enumerate(self.episodes):
            obs = np.asarray(e["observations"], np.float32).reshape(-1, d)
            acts = np.asarray(e["actions"], np.float32).reshape(-1, 2)
            out.observations[i, : len(obs)] = out.configs[i, : len(obs)] = obs
            out.actions[i, : len(acts)] = out.executed[i, : len(acts)] = acts
            out.failure[i, : len(acts)] = 0
            out.lengths[i] = e["lengths"]
            if e.get("masses") is not None:
                out.masses[i] = e["masses"]
        return out


def write_recording(path: str | os.PathLike, recording: Recording) -> Path:
    """Write a recording (checked first: a file we write always reads back)."""
    path = Path(path)
    header = {
        "format": FORMAT,
        "version": VERSION,
        "n_links": recording.n_links,
        "units": UNITS,
        "robot": recording.robot,
    }
    if recording.setting:
        header["setting"] = recording.setting
    if recording.notes:
        header["notes"] = recording.notes
    lines = [json.dumps(header)]
    for e in recording.episodes:
        lines.append(json.dumps({k: _plain(v) for k, v in e.items() if v is not None}))
    text = "\n".join(lines) + "\n"
    problems = _check_lines(text.splitlines())
    if problems:
        raise RecordingError(path, problems)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def check_recording(path: str | os.PathLike) -> list[Problem]:
    """Every problem in a recording file (an empty list: the file is good)."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        return [Problem(0, "", f"no file at {path}")]
    except UnicodeDecodeError as err:
        return [Problem(0, "", f"not UTF-8 text: {err}")]
    return _check_lines(text.splitlines())


def read_recording(path: str | os.PathLike) -> Recording:
    """A checked recording; RecordingError lists every problem otherwise."""
    problems = check_recording(path)
    if problems:
        raise RecordingError(path, problems)
    lines = [line for line in Path(path).read_text(encoding="utf-8").splitlines() if line.strip()]
    header = json.loads(lines[0])
    return Recording(
        n_links=header["n_links"],
        robot=header.get("robot", ""),
        setting=header.get("setting"),
        notes=header.get("notes", ""),
        episodes=[json.loads(line) for line in lines[1:]],
    )


# --- the checks -----------------------------------------------------------------------------
def _check_lines(lines: list[str]) -> list[Problem]:
    numbered = [(i + 1, line) for i, line in enumerate(lines) if line.strip()]
    if not numbered:
        return [Problem(1, "", "the file is empty; line 1 must be the header")]
    problems: list[Problem] = []
    objects = []
    for number, line in numbered:
        try:
            value = json.loads(line)
        except json.JSONDecodeError as err:
            problems.append(
                Problem(number, "", f"not valid JSON ({err.msg} at column {err.colno})")
            )
            continue
        except RecursionError:
            problems.append(Problem(number, "", "nested too deeply to be a recording's line"))
            continue
        if not isinstance(value, dict):
            problems.append(Problem(number, "", "must be a JSON object {...}"))
            continue
        objects.append((number, value))
    if not objects or objects[0][0] != numbered[0][0]:
        return problems  # no readable header: nothing else can be judged
    header_line, header = objects[0]
    n_links = _check_header(header_line, header, problems)
    if len(objects) == 1 and not problems:
        problems.append(Problem(header_line, "", "the header is followed by no episode"))
    ids: dict[str, int] = {}
    for number, episode in objects[1:]:
        _check_episode(number, episode, n_links, problems)
        key = episode.get("id")
        if isinstance(key, str):
            if key in ids:
                problems.append(Problem(number, "id", f"{key!r} repeats line {ids[key]}'s id"))
            ids.setdefault(key, number)
    return problems


def _check_header(line: int, header: dict, problems: list[Problem]) -> int | None:
    if header.get("format") != FORMAT:
        problems.append(
            Problem(line, "format", f"must be {FORMAT!r} (is this a masspush recording?)")
        )
    version = header.get("version")
    if not (type(version) is int and version == VERSION):  # not True, not 1.0
        problems.append(
            Problem(line, "version", f"this masspush reads version {VERSION}, "
                    f"got {header.get('version')!r}")
        )  # fmt: skip
    for key in sorted(set(header) - HEADER_FIELDS):
        problems.append(Problem(line, key, f"unknown header field; known: {sorted(HEADER_FIELDS)}"))
    if header.get("units") != UNITS:
        problems.append(Problem(line, "units", f"must be {json.dumps(UNITS)}"))
    n_links = header.get("n_links")
    if not (isinstance(n_links, int) and not isinstance(n_links, bool) and n_links >= 2):
        problems.append(Problem(line, "n_links", f"must be an integer >= 2, got {n_links!r}"))
        return None
    for key in ("robot", "setting", "created", "notes"):
        if key in header and not isinstance(header[key], str):
            problems.append(Problem(line, key, "must be a string"))
    return n_links


def _check_episode(line: int, e: dict, n_links: int | None, problems: list[Problem]) -> None:
    def bad(name: str, message: str) -> None:
        problems.append(Problem(line, name, message))

    for key in sorted(set(e) - EPISODE_FIELDS):
        bad(key, f"unknown episode field; known: {sorted(EPISODE_FIELDS)}")
    for key in ("id", "lengths", "observations", "actions"):
        if key not in e:
            bad(key, "missing (required)")
    if "id" in e and not (isinstance(e["id"], str) and e["id"]):
        bad("id", "must be a non-empty string")
    if n_links is None:
        return
    d = 3 + n_links - 1
    lengths = _numbers(e.get("lengths"), "lengths", line, problems, shape=(n_links,))
    if lengths is not None and np.any(lengths <= 0):
        bad("lengths", "link lengths must be > 0 (metres)")
    obs = _numbers(e.get("observations"), "observations", line, problems, shape=(None, d))
    acts = _numbers(e.get("actions"), "actions", line, problems, shape=(None, 2))
    if acts is not None:
        if len(acts) == 0:
            bad("actions", "an episode needs at least one push")
        outside = np.argwhere(np.abs(acts) > 1.0)
        if len(outside):
            k, j = outside[0]
            bad(f"actions[{k}][{j}]", f"{acts[k, j]} is outside the action box [-1, 1]")
    if obs is not None and acts is not None and len(obs) != len(acts) + 1:
        bad(
            "observations",
            f"needs one rest pose more than there are actions (q_0 before the first push): "
            f"{len(obs)} observations, {len(acts)} actions",
        )
    if "label" in e and not (isinstance(e["label"], str) and e["label"].isprintable()):
        bad("label", "must be a string of printable characters (the class name)")
    if "masses" in e:
        if e["masses"] is None:
            bad("masses", "must be an array of numbers; leave the field out where unknown")
        masses = _numbers(e["masses"], "masses", line, problems, shape=(n_links,))
        if masses is not None and np.any(masses <= 0):
            bad("masses", "link masses must be > 0 (kg)")
    if "notes" in e and not isinstance(e["notes"], str):
        bad("notes", "must be a string")


def _numbers(value, name, line, problems, shape) -> np.ndarray | None:
    """`value` as a float array of `shape` (None: any length), or None with a problem."""
    if value is None:
        return None
    want = " x ".join("k" if s is None else str(s) for s in shape)
    leaf = _first_non_number(value)
    if leaf is not None:
        problems.append(
            Problem(line, name, f"must be a {want} array of numbers, holds {leaf!r}"[:200])
        )
        return None
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        problems.append(Problem(line, name, f"must be a {want} array of numbers"))
        return None
    if array.ndim != len(shape) or any(
        s is not None and a != s for a, s in zip(array.shape, shape, strict=True)
    ):
        problems.append(
            Problem(line, name, f"must be a {want} array of numbers, got shape {array.shape}")
        )
        return None
    # The predictor reads float32: a value beyond its range would become infinite there.
    bad = np.argwhere(~np.isfinite(array) | (np.abs(array) > FLOAT32_MAX))
    if len(bad):
        index = "".join(f"[{i}]" for i in bad[0])
        problems.append(Problem(line, f"{name}{index}", "must be a finite number (in float32)"))
        return None
    return array


FLOAT32_MAX = float(np.finfo(np.float32).max)


def _first_non_number(value: Any) -> Any:
    """The first leaf of nested lists that is not a JSON number (a boolean is not one, nor
    a string), or None where all are."""
    stack = [value]
    while stack:
        item = stack.pop()
        if isinstance(item, list):
            stack.extend(reversed(item))
        elif isinstance(item, bool) or not isinstance(item, (int, float)):
            return item
    return None


def _plain(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value.tolist()] if value.ndim else _plain(value.item())
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (np.floating, float)):
        return round(float(value), 6) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def check_report(path: str | os.PathLike) -> tuple[bool, list[str]]:
    """`masspush check-episodes`: whether a recording is good, and what to say of it (every
    problem with its line and field, or what it holds)."""
    problems = check_recording(path)
    if problems:
        return False, [f"{path}: {problem}" for problem in problems]
    recording = read_recording(path)
    labels = sorted({label for label in recording.labels if label is not None})
    return True, [
        f"{path}: good: {len(recording.episodes)} episode(s) of a {recording.n_links}-link "
        f"chain" + (f", labels {labels}" if labels else "")
    ]
