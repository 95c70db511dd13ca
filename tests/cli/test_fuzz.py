"""Bad input to every command ends in one line on stderr and a non-zero exit, before any
work: table-driven, one row per command and kind of bad input (issue 26). A command without
rows fails the suite."""

from __future__ import annotations

import functools
import json
import signal
import tempfile
from pathlib import Path

import pytest

from masspush.cli import COMMANDS, main
from masspush.models import shipped_file

# Placeholders, filled per test: DIR (a directory), MISSING (no such file), GARBAGE (a file
# of random bytes), FOREIGN (a good recording of another setting, 2link-0.1-1),
# FOREIGN_RESULT (an evaluation of another setting), FOREIGN_MODEL (a model of another
# setting), DATASET (a small dataset of the required setting, 2link-1-10).
CASES: dict[str, list[list[str]]] = {
    "demo": [["--seed", "-1"], ["--setting", "nope"], ["--out", "DIR"], ["--model", "MISSING"],
             ["--video", "v.txt"], ["--model", "GARBAGE"]],
    "evaluate": [["--episodes", "0"], ["--episodes", "1000000000000"], ["--seed", "-1"],
                 ["--model", "nope"], ["--paired-with", "DIR"], ["--paired-with", "MISSING"],
                 ["--paired-with", "GARBAGE"], ["--setting", "nope"], ["--workers", "0"],
                 ["--model", "DIR"], ["--model", "GARBAGE"], ["--episodes", "nan"],
                 ["--paired-with", "FOREIGN_RESULT"], ["--model", "FOREIGN_MODEL"],
                 ["--model", "THREE_LINK_MODEL", "--allow-mismatch"], ["--pusher", "nope"],
                 ["--model", "bayes", "--bayes", "likelihood=learned"],
                 ["--model", "bayes", "--bayes", "likelihood=learned", "--bayes",
                  "density=missing.pt"]],
    "run": [["--count", "0"], ["--count", "-1"], ["--pushes", "0"], ["--seed", "-1"],
            ["--robot", "nope"], ["--robot", "replay"], ["--episodes-file", "DIR"],
            ["--masses", "nan,1"], ["--record", "DIR"], ["--lab", "1"], ["--setting", "nope"],
            ["--robot", "target", "--day", "1"], ["--robot", "target", "--lab", "1", "--day", "-1"],
            ["--robot", "replay", "--episodes-file", "FOREIGN"], ["--masses", "50,50"],
            ["--record", "FOREIGN"], ["--model", "FOREIGN_MODEL"], ["--robot", "no_such_lab:x"],
            ["--robot", "os:getcwd"], ["--robot", "a b:c"], ["--governor-fit", "MISSING"],
            ["--governor-fit", "GARBAGE"], ["--governor-fit", "FOREIGN"],
            ["--robot", "ur10-stationary", "--setting", "real-ur10", "--governor-fit", "FOREIGN"]],
    "collect": [["--episodes", "0"], ["--episodes", "-1"], ["--shard-size", "0"],
                ["--policy", "nope"], ["--setting", "nope"], ["--seed", "-1"],
                ["--episodes", "1000000000000"], ["--out", "GARBAGE"], ["--pusher", "nope"]],
    "check-episodes": [["DIR"], ["MISSING"], ["GARBAGE"]],
    "train-predictor": [["--data", "MISSING"], ["--data", "DIR"], ["--batch-size", "0"],
                        ["--steps", "-1"], ["--lr", "nan"], ["--episodes", "1"],
                        ["--data", "DATASET", "--loss", "huber"],
                        ["--data", "DATASET", "--width", "4"],
                        ["--data", "DATASET", "--batch-size", "1000000000000"]],
    "train-density": [["--data", "MISSING"], ["--data", "DIR"], ["--data", "GARBAGE"],
                      ["--data", "DATASET", "--steps", "0"],
                      ["--data", "DATASET", "--held-out", "0.7"],
                      ["--data", "DATASET", "--lr", "nan"], ["--data", "DATASET", "--out", "DIR"],
                      ["--data", "DATASET", "--batch-size", "1000000000000"]],
    "baselines": [["--setting", "nope"], ["--table", "--pusher", "nope"],
                  ["--eval-episodes", "0"], ["--episodes", "1", "5"]],
    "train": [["--setting", "nope"], ["--meta-iterations", "0"], ["--ppo-steps", "0"],
              ["--envs", "0"], ["--algo", "nope"], ["--pusher", "nope"],
              ["--final-loss", "huber"], ["--final-width", "0"]],
    "reproduce": [["--settings", "nope"], ["--meta-iterations", "0"], ["--eval-episodes", "0"],
                  ["--pusher", "nope"]],
    "calibrate": [["--setting", "nope"], ["--model", "MISSING"], ["--episodes", "0"],
                  ["--out", "DIR"], ["--model", "GARBAGE"]],
    "finetune": [["--episodes", "MISSING"], ["--episodes", "DIR"], ["--episodes", "GARBAGE"],
                 ["--folds", "0"], ["--out", "DIR"], ["--episodes", "FOREIGN"]],
    "classify": [["--classifier", "MISSING"], ["--classifier", "GARBAGE"], ["--episodes", "DIR"],
                 ["--density", "MISSING"], ["--density", "GARBAGE"], ["--pushes", "0"],
                 ["--pushes", "2"]],
    "tune-density": [["--episodes", "MISSING"], ["--episodes", "DIR"], ["--episodes", "GARBAGE"],
                     ["--episodes", "FOREIGN"], ["--density", "MISSING"],
                     ["--density", "GARBAGE"], ["--folds", "1"], ["--steps", "0"],
                     ["--lr", "nan"], ["--anchor", "-1"], ["--frictions", "0"],
                     ["--sort-range", "1.2,0.3"], ["--sort-range", "0,1"],
                     ["--sort-frictions", "0"],
                     ["--out", "DIR"], ["--setting", "nope"]],
    "sim2real": [["--episodes-per-class", "0"], ["--severity", "2"], ["--world", "moon"],
                 ["--lab", "-1"], ["--segments", "0"], ["--setting", "nope"], ["--day", "2"],
                 ["--lab", "5", "--day", "-1"],
                 ["--start-range", "2"], ["--start-yaw", "400"],
                 ["--setting", "2link-1-10", "--start-yaw", "0"], ["--check-reach"],
                 ["--density", "MISSING"],
                 ["--learned-model", "bayes", "--density", "MISSING"],
                 ["--learned-model", "bayes", "--density", "DIR"],
                 ["--learned-model", "bayes", "--density", "GARBAGE"],
                 ["--tuned-density", "MISSING"], ["--tuned-density", "GARBAGE"]],
    "randomise": [["--episodes", "0"], ["--steps", "0"], ["--world", "moon"], ["--envs", "0"],
                  ["--workers", "0"], ["--lab", "5"], ["--world", "target", "--lab", "x"],
                  ["--world", "target", "--lab", "-1"]],
    "bayes-table": [["--settings", "nope"], ["--episodes", "0"], ["--models", "nope"]],
    "render": [["--out", "x.txt"], ["--out", "DIR"], ["--width", "1"], ["--seed", "-1"],
               ["--pusher", "nope"]],
    "bench sim": [["--links", "1"], ["--chains", "0"], ["--mass-range", "1", "0"],
                  ["--seed", "-1"]],
    "bench pushers": [["--pushers", "nope"], ["--pushes", "0"], ["--links", "1"]],
    "bench arm": [["--links", "1"], ["--arm", "stiff"], ["--arm", "nope"], ["--episodes", "0"],
                  ["--check-pushes", "0"], ["--links", "65"], ["--seed", "-1"]],
    "bench data": [["--episodes", "-1"], ["--pusher", "nope"], ["--workers", "0"]],
    "bench ray": [["--episodes", "0"], ["--pusher", "nope"], ["--cpus", "0"], ["--cpus", ""],
                  ["--setting", "nope"], ["--shard-size", "0"]],
    "bench train": [["--episodes", "0"], ["--steps", "0"]],
    "bench ppo": [["--steps", "0"], ["--envs", "0"], ["--pusher", "nope"]],
    "bench motion": [["--data", "MISSING"], ["--episodes", "0"]],
    "bench physics": [["--links", "1"], ["--pushes", "0"], ["--mass-range", "nan", "1"]],
}  # fmt: skip

# What each command needs besides the bad value, so that only that value is wrong.
REQUIRED: dict[str, list[str]] = {
    "evaluate": ["--setting", "2link-1-10", "--model", "rp"],
    "run": ["--robot", "stiff", "--setting", "2link-1-10"],
    "collect": ["--setting", "2link-1-10", "--episodes", "5", "--out", "TMP/ds"],
    "train-predictor": ["--setting", "2link-1-10", "--data", "MISSING"],
    "train-density": ["--data", "MISSING", "--out", "TMP/density.pt"],
    "baselines": ["--setting", "2link-1-10"],
    "train": ["--setting", "2link-1-10", "--out", "TMP/run"],
    "reproduce": ["--settings", "2link-1-10"],
    "calibrate": ["--setting", "2link-1-10"],
    "finetune": ["--setting", "2link-1-10", "--episodes", "MISSING"],
    "classify": ["--classifier", "MISSING", "--episodes", "MISSING"],
    "tune-density": ["--setting", "real-ur10", "--episodes", "MISSING"],
    "sim2real": ["--out", "TMP/s2r"],
    "randomise": ["--out", "TMP/dr"],
    "bench motion": ["--data", "MISSING"],
}


class StartedWork(BaseException):
    """Raised by the alarm: not an Exception, so that no error handler can swallow it."""


def test_every_command_has_cases():
    assert set(CASES) == {c.name for c in COMMANDS}


def _foreign_recording(tmp_path) -> str:
    from masspush.data.recording import Recording, write_recording

    episode = {"id": "a", "lengths": [0.1, 0.12], "actions": [[0.5, -0.5], [1.0, 0.5]],
               "observations": [[0.0, 0.0, 0.1, 0.2]] * 3, "label": "x"}  # fmt: skip
    recording = Recording(2, setting="2link-0.1-1", episodes=[episode, {**episode, "id": "b"}])
    return str(write_recording(tmp_path / "foreign.jsonl", recording))


def _foreign_result(tmp_path) -> str:
    result = {"setting": "2link-0.1-1", "model": "rp", "seed": 0, "per_episode": {}}
    (tmp_path / "foreign.json").write_text(json.dumps(result))
    return str(tmp_path / "foreign.json")


@functools.cache
def _dataset() -> str:
    """A dataset of 4 episodes of 2link-1-10, made once for the whole suite."""
    from masspush.data.dataset import collect
    from masspush.settings import get_setting

    out = Path(tempfile.mkdtemp()) / "ds"
    collect(get_setting("2link-1-10"), out, 4, "stiff", progress=False)
    return str(out)


def _argv(name: str, case: list[str], tmp_path) -> list[str]:
    (tmp_path / "dir").mkdir(exist_ok=True)
    (tmp_path / "garbage").write_bytes(bytes(range(256)) * 4)
    where = {"DIR": str(tmp_path / "dir"), "MISSING": str(tmp_path / "missing.file"),
             "GARBAGE": str(tmp_path / "garbage"), "FOREIGN": _foreign_recording(tmp_path),
             "FOREIGN_RESULT": _foreign_result(tmp_path), "DATASET": _dataset(),
             "FOREIGN_MODEL": str(shipped_file("2link-0.1-1", "rp")),
             "THREE_LINK_MODEL": str(shipped_file("3link-1-10", "rp"))}  # fmt: skip

    def fill(word: str) -> str:
        word = word.replace("TMP", str(tmp_path))
        return where.get(word, word)

    base = [fill(w) for w in REQUIRED.get(name, [])]
    bad = [fill(w) for w in case]
    # A bad value replaces the required one of the same option.
    for i in range(0, len(bad) - 1):
        if bad[i].startswith("--") and bad[i] in base:
            j = base.index(bad[i])
            del base[j : j + 2]
    return [*name.split(), *base, *bad]


@pytest.mark.parametrize(
    ("name", "case"),
    [(name, case) for name, cases in CASES.items() for case in cases],
    ids=lambda v: v if isinstance(v, str) else " ".join(v) or "(nothing)",
)
def test_bad_input_is_one_line_and_a_non_zero_exit(name, case, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    argv = _argv(name, case, tmp_path)

    def started_work(*_):
        raise StartedWork(f"masspush {' '.join(argv)} started work instead of refusing")

    # Bad input is refused before any work: anything still running after 20 s started it.
    before = set(tmp_path.rglob("*"))
    signal.signal(signal.SIGALRM, started_work)
    signal.alarm(20)
    try:
        code = main(argv)
    except SystemExit as stop:  # argparse's usage error
        code = stop.code
    finally:
        signal.alarm(0)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code not in (0, None), f"accepted: masspush {' '.join(argv)}"
    assert len(lines) == 1, f"masspush {' '.join(argv)}:\n{err}"
    assert lines[0].startswith(f"masspush {name}: error: ") or lines[0].startswith(
        "masspush: error: "
    ), lines[0]
    assert "Traceback" not in err
    # Nor may it leave anything behind: a progress bar's carriage returns hide on one line
    # with the error, an output directory made before the refusal does not.
    assert set(tmp_path.rglob("*")) == before, f"masspush {' '.join(argv)} wrote files"
