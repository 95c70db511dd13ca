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
mapping to a contact point, direction and speed). `label`, `masses`, `notes`, `failure` (why
the episode ended early), `speeds` (each push's speed as executed) and `estimates` (the
estimator's mass distribution after each push, as it ran) are optional.

`check_recording` reports every problem with its line and field; `read_recording` refuses
a file with any problem and returns it as `Episodes` (the predictor's input).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from masspush.config import MAX_PUSHES, ChainGeometry
from masspush.data.rollout import Episodes, empty_episodes

SpeedReader = Callable[[np.ndarray, Any, np.ndarray, "float | None"], np.ndarray]
"""(rest pose before the push, link lengths, the action, the speed the robot reported or None)
-> the action the models read (`masspush.sim.SpeedEquivalent.action`)."""

FORMAT, VERSION = "masspush-episodes", 1
UNITS = {"length": "m", "angle": "rad", "mass": "kg"}
HEADER_FIELDS = {
    "format", "version", "n_links", "units", "robot", "setting", "created", "notes", "geometry",
}  # fmt: skip
GEOMETRY_FIELDS = ("link_width", "link_height", "joint_gap", "tool_radius")
"""The header's optional `geometry`: the lab's chain and tool, m (`config.ChainGeometry`)."""
EPISODE_FIELDS = {
    "id", "lengths", "observations", "actions", "label", "masses", "notes", "failure", "speeds",
    "estimates",
}  # fmt: skip


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
        total = problem_count(problems)
        shown = "\n".join(f"  {p}" for p in problems[:20])
        more = f"\n  ... and {total - 20} more" if total > 20 else ""
        super().__init__(f"{path}: {total} problem(s)\n{shown}{more}")


@dataclass
class Recording:
    """A recording's header and episodes: each a dict of the file's fields, its numbers as
    NumPy arrays where read from a file (observations and actions float32, lengths and
    masses float64); lists or arrays where written."""

    n_links: int
    robot: str = ""
    setting: str | None = None
    notes: str = ""
    episodes: list[dict[str, Any]] = field(default_factory=list)
    geometry: ChainGeometry | None = None
    """The chain and tool the episodes were recorded with, where the lab measured them."""

    @property
    def labels(self) -> list[str | None]:
        return [e.get("label") for e in self.episodes]

    def to_episodes(self, read_speed: SpeedReader | None = None) -> Episodes:
        """The episodes as the predictor's input, padded to the longest with NaN (an episode
        recorded with fewer pushes is scored after its last one). With `read_speed`, each
        push whose speed the recording keeps is read as the action that speed stands for
        (`masspush.real.robot.speed_reader`)."""
        k = max(len(e["actions"]) for e in self.episodes)
        n, d = self.n_links, 3 + self.n_links - 1
        out = empty_episodes(len(self.episodes), k, n)
        out.index[:] = np.arange(len(self.episodes))
        for i, e in enumerate(self.episodes):
            obs = np.asarray(e["observations"], np.float32).reshape(-1, d)
            # a copy: reading speeds must not rewrite the recording's own actions
            acts = np.array(e["actions"], np.float32).reshape(-1, 2)
            if read_speed is not None and e.get("speeds") is not None:
                for j, speed in enumerate(e["speeds"]):
                    acts[j] = read_speed(obs[j], e["lengths"], acts[j], float(speed))
            out.observations[i, : len(obs)] = out.configs[i, : len(obs)] = obs
            out.actions[i, : len(acts)] = out.executed[i, : len(acts)] = acts
            out.failure[i, : len(acts)] = 0
            out.lengths[i] = e["lengths"]
            if e.get("masses") is not None:
                out.masses[i] = e["masses"]
        return out


def write_recording(path: str | os.PathLike, recording: Recording) -> Path:
    """Write a recording (checked first: a file we write always reads back), whole or not
    at all."""
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
    if recording.geometry is not None:
        header["geometry"] = asdict(recording.geometry)
    lines = [json.dumps(header)]
    for e in recording.episodes:
        lines.append(json.dumps({k: _plain(v) for k, v in e.items() if v is not None}))
    checker = _Checker()
    for number, line in enumerate(lines, 1):
        checker.feed(number, line)
    problems = checker.finish()
    if problems:
        raise RecordingError(path, problems)
    path.parent.mkdir(parents=True, exist_ok=True)
    # Written beside and moved over: a write cut short (a session stopped, a full disk)
    # leaves the file as it was, never half of it.
    partial = path.with_name(f".{path.name}.partial")
    try:
        partial.write_text("\n".join(lines) + "\n")
        os.replace(partial, path)
    except OSError as err:
        with contextlib.suppress(OSError):
            partial.unlink(missing_ok=True)
        raise OSError(f"{path}: cannot write the recording: {err.strerror or err}") from None
    return path


def check_recording(path: str | os.PathLike) -> list[Problem]:
    """Every problem in a recording file (an empty list: the file is good; at most
    `MAX_PROBLEMS` are listed, `problem_count` counts them all).

    The file is read line by line: memory does not grow with its size."""
    return _checked(path).finish()


def _checked(path: str | os.PathLike) -> _Checker:
    checker = _Checker()
    for number, line in _lines(path, checker):
        checker.feed(number, line)
    return checker


def read_recording(path: str | os.PathLike) -> Recording:
    """A checked recording; RecordingError lists every problem otherwise.

    One pass, line by line; each episode's numbers are kept as NumPy arrays (observations
    and actions in float32, the precision the predictor reads), a few bytes a number."""
    checker = _Checker()
    episodes: list[dict[str, Any]] = []
    for number, line in _lines(path, checker):
        value = checker.feed(number, line)
        if value is not None and not checker.problems and number > checker.header_line:
            episodes.append(_compact(value))
    problems = checker.finish()
    if problems:
        raise RecordingError(path, problems)
    return _recording(checker.header, episodes)


def iter_recording(path: str | os.PathLike, chunk: int = 4096) -> Iterator[Recording]:
    """A large recording in pieces of at most `chunk` episodes (each a `Recording` with the
    file's header), after checking the whole file: memory grows with `chunk`, not with the
    file. RecordingError, before the first piece, where the file has a problem."""
    checker = _checked(path)
    if checker.finish():
        raise RecordingError(path, checker.problems)
    episodes: list[dict[str, Any]] = []
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, 1):
            if number > checker.header_line and line.strip():
                episodes.append(_compact(json.loads(line)))
                if len(episodes) == chunk:
                    yield _recording(checker.header, episodes)
                    episodes = []
    if episodes:
        yield _recording(checker.header, episodes)


def _recording(header: dict[str, Any], episodes: list[dict[str, Any]]) -> Recording:
    """A checked file's header and (some of) its episodes as a `Recording`."""
    return Recording(
        n_links=header["n_links"],
        robot=header.get("robot", ""),
        setting=header.get("setting"),
        notes=header.get("notes", ""),
        episodes=episodes,
        geometry=ChainGeometry(**header["geometry"]) if "geometry" in header else None,
    )


def problem_count(problems: list[Problem]) -> int:
    """How many problems a `check_recording` list stands for (it keeps the first
    MAX_PROBLEMS)."""
    return len(problems) + getattr(problems, "more", 0)


MAX_LINE_BYTES = 8 << 20
"""The longest line read, in characters: 1000 pushes of a 64-link chain fit in a few MB."""
MAX_PROBLEMS = 1000
"""Problems listed at most; the rest are counted."""
MAX_LABELS = 100
"""Distinct labels `check-episodes` lists at most."""


class _Problems(list):
    """A list of problems that keeps the first MAX_PROBLEMS and counts the rest."""

    more = 0

    def append(self, problem: Problem) -> None:
        if len(self) < MAX_PROBLEMS:
            super().append(problem)
        else:
            self.more += 1


def _lines(path: str | os.PathLike, checker: _Checker) -> Iterator[tuple[int, str]]:
    """The file's lines with their numbers; an unreadable file, a line too long or text
    that is not UTF-8 becomes a problem of `checker` instead."""
    number = 0
    try:
        with open(path, encoding="utf-8") as f:
            while line := f.readline(MAX_LINE_BYTES + 1):
                number += 1
                if len(line) > MAX_LINE_BYTES:
                    while (rest := f.readline(1 << 20)) and not rest.endswith("\n"):
                        pass  # skip the rest of the line without holding it
                    checker.problems.append(Problem(number, "", (
                        f"longer than {MAX_LINE_BYTES >> 20} MiB; an episode holds at most "
                        f"{MAX_PUSHES} pushes")))  # fmt: skip
                    checker.seen(number)
                    continue
                yield number, line
    except FileNotFoundError:
        checker.problems.append(Problem(0, "", f"no file at {path}"))
    except IsADirectoryError:
        checker.problems.append(Problem(0, "", f"{path} is a directory, not a recording"))
    except UnicodeDecodeError as err:
        checker.problems.append(Problem(number + 1, "", f"not UTF-8 text: {err.reason}"))


class _Checker:
    """Checks a recording one line at a time, keeping only the header and the ids seen."""

    def __init__(self) -> None:
        self.problems: list[Problem] = _Problems()
        self.header: dict[str, Any] = {}
        self.header_line = 0  # 0: no line seen yet
        self.n_links: int | None = None
        self.ids: dict[str, int] = {}
        self.episodes = 0
        self.readable_header = False
        self.labels: set[str] = set()  # the first MAX_LABELS distinct ones

    def seen(self, number: int) -> None:
        """A non-blank line that could not be read (the header, if it was the first)."""
        if not self.header_line:
            self.header_line = number

    def feed(self, number: int, line: str) -> dict[str, Any] | None:
        """Check one line; the parsed object where it is a good one."""
        if not line.strip():
            return None
        first = not self.header_line
        self.seen(number)
        value = self._parse(number, line)
        if first:
            if value is not None:
                self.readable_header = True
                self.header = value
                self.n_links = _check_header(number, value, self.problems)
            return value
        if value is None or not self.readable_header:
            return None  # no readable header: an episode cannot be judged
        before = problem_count(self.problems)
        self.episodes += 1
        _check_episode(number, value, self.n_links, self.problems)
        key = value.get("id")
        if isinstance(key, str):
            if key in self.ids:
                self.problems.append(
                    Problem(number, "id", f"{_text(key)} repeats line {self.ids[key]}'s id")
                )
            self.ids.setdefault(key, number)
        label = value.get("label")
        if isinstance(label, str) and len(self.labels) < MAX_LABELS:
            self.labels.add(label)
        return value if problem_count(self.problems) == before else None

    def _parse(self, number: int, line: str) -> dict[str, Any] | None:
        try:
            value = json.loads(line)
        except json.JSONDecodeError as err:
            message = f"not valid JSON ({err.msg} at column {err.colno})"
            self.problems.append(Problem(number, "", message))
            return None
        except RecursionError:
            self.problems.append(Problem(number, "", "nested too deeply to be a recording's line"))
            return None
        if not isinstance(value, dict):
            self.problems.append(Problem(number, "", "must be a JSON object {...}"))
            return None
        return value

    def finish(self) -> list[Problem]:
        if not self.header_line and not self.problems:
            self.problems.append(Problem(1, "", "the file is empty; line 1 must be the header"))
        elif self.readable_header and not self.episodes and not self.problems:
            self.problems.append(
                Problem(self.header_line, "", "the header is followed by no episode")
            )
        return self.problems


def _compact(episode: dict[str, Any]) -> dict[str, Any]:
    """A checked episode with its numbers as arrays (a tenth of the memory of lists)."""
    out = dict(episode)
    for key, dtype in (("observations", np.float32), ("actions", np.float32),
                       ("lengths", np.float64), ("masses", np.float64),
                       ("speeds", np.float32), ("estimates", np.float32)):  # fmt: skip
        if key in out:
            out[key] = np.asarray(out[key], dtype)
    return out


def _text(value: str) -> str:
    """A string from a file as it may be shown: escaped, and cut short."""
    shown = ascii(value)
    return shown if len(shown) <= 60 else shown[:57] + "..."


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
    if "geometry" in header:
        _check_geometry(line, header["geometry"], problems)
    return n_links


def _check_geometry(line: int, value: Any, problems: list[Problem]) -> None:
    want = "{" + ", ".join(f'"{k}": m' for k in GEOMETRY_FIELDS) + "}"
    if not isinstance(value, dict) or set(value) != set(GEOMETRY_FIELDS):
        problems.append(Problem(line, "geometry", f"must be an object {want}"))
        return
    numbers = _numbers([value[k] for k in GEOMETRY_FIELDS], "geometry", line, problems, (4,))
    if numbers is None:
        return
    try:
        ChainGeometry(*(float(v) for v in numbers))
    except ValueError as err:
        problems.append(Problem(line, "geometry", str(err)))


def _check_episode(line: int, e: dict, n_links: int | None, problems: list[Problem]) -> None:
    def bad(name: str, message: str) -> None:
        problems.append(Problem(line, name, message))

    for key in sorted(set(e) - EPISODE_FIELDS):
        bad(key, f"unknown episode field; known: {sorted(EPISODE_FIELDS)}")
    for key in ("id", "lengths", "observations", "actions"):
        if key not in e:
            bad(key, "missing (required)")
    if "id" in e and not (isinstance(e["id"], str) and e["id"] and e["id"].isprintable()):
        bad("id", "must be a non-empty string of printable characters")
    for key in ("lengths", "observations", "actions"):
        if key in e and e[key] is None:
            bad(key, "must be an array of numbers, not null")
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
        if len(acts) > MAX_PUSHES:
            bad("actions", f"{len(acts)} pushes; an episode holds at most {MAX_PUSHES}")
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
    if "failure" in e and not (
        isinstance(e["failure"], str) and e["failure"] and e["failure"].isprintable()
    ):
        bad("failure", "must be a non-empty string of printable characters (why it ended)")
    if "speeds" in e:
        if e["speeds"] is None:
            bad("speeds", "must be an array of numbers; leave the field out where unknown")
        pushes = None if acts is None else len(acts)
        speeds = _numbers(e["speeds"], "speeds", line, problems, shape=(pushes,))
        if speeds is not None and np.any(speeds < 0):
            bad("speeds", "speeds reached must be >= 0 (m/s)")
    if "estimates" in e:
        if e["estimates"] is None:
            bad("estimates", "must be an array of numbers; leave the field out where unknown")
        pushes = None if acts is None else len(acts)
        shares = _numbers(e["estimates"], "estimates", line, problems, shape=(pushes, n_links))
        if shares is not None and (
            np.any(shares < 0) or np.any(np.abs(shares.sum(axis=1) - 1) > 1e-3)
        ):
            bad("estimates", "each push's estimate is a mass distribution: shares >= 0 "
                "that add up to 1")  # fmt: skip


def _numbers(
    value: Any, name: str, line: int, problems: list[Problem], shape: tuple[int | None, ...]
) -> np.ndarray | None:
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
    checker = _checked(path)
    problems = checker.finish()
    if problems:
        more = problem_count(problems) - len(problems)
        return False, [f"{path}: {problem}" for problem in problems] + (
            [f"{path}: ... and {more} more problem(s)"] if more else []
        )
    labels = sorted(checker.labels)
    return True, [
        f"{path}: good: {checker.episodes} episode(s) of a {checker.n_links}-link "
        f"chain" + (f", labels {labels}" if labels else "")
    ]
