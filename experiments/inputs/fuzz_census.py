"""How does a masspush checkout answer bad input? The fuzz suites' own cases (tests/cli,
tests/data/test_recording_fuzz.py, tests/test_env.py), counted by outcome, for this checkout
or another one's `src` (issue 26's before/after; docs/notebook/2026-12-01-bad-input.md).

    .venv/bin/python experiments/inputs/fuzz_census.py                  # this checkout
    .venv/bin/python experiments/inputs/fuzz_census.py --source /tmp/old/src

The CLI cases run each in a fresh process (20 s limit: a case still running then has started
work instead of refusing); outcomes: one-line error, several lines, traceback, exit 0
(accepted), started work. Recordings and environment arguments run in one process against
the checkout's reader and environment: refused (a clear error or problems), accepted,
crashed (any other exception).
"""

from __future__ import annotations

import argparse
import collections
import importlib
import importlib.util
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).parents[2]
RUN_MAIN = "import sys; from masspush.cli import main; sys.exit(main(sys.argv[1:]))"


def _module(path: Path):
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def cli_cases(workdir: Path) -> list[tuple[str, list[str], Path]]:
    """(label, argv, directory to run in) of every CLI case, its files made here."""
    fuzz = _module(ROOT / "tests" / "cli" / "test_fuzz.py")
    out = []
    for name, cases in fuzz.CASES.items():
        for case in cases:
            where = Path(tempfile.mkdtemp(dir=workdir))
            out.append((f"masspush {name} {' '.join(case)}", fuzz._argv(name, case, where), where))
    return out


def cli_census(cases, source: str | None) -> collections.Counter:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    if source:
        env["PYTHONPATH"] = source
    counts: collections.Counter = collections.Counter()
    for label, argv, where in cases:
        try:
            done = subprocess.run([sys.executable, "-c", RUN_MAIN, *argv], cwd=where, env=env,
                                  capture_output=True, text=True, timeout=20)  # fmt: skip
        except subprocess.TimeoutExpired:
            outcome = "started work"
        else:
            lines = [x for x in done.stderr.splitlines() if x.strip()]
            if "Traceback" in done.stderr:
                outcome = "traceback"
            elif done.returncode == 0:
                outcome = "exit 0 (accepted)"
            elif len(lines) == 1:
                outcome = "one-line error"
            else:
                outcome = "several lines"
        counts[outcome] += 1
        print(f"{outcome:18s} {label}", flush=True)
    return counts


def recording_census(bad, check) -> collections.Counter:
    counts: collections.Counter = collections.Counter()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bad.jsonl"
        for what, text in bad:
            path.write_text(text)
            try:
                counts["refused" if check(path) else "accepted"] += 1
            except ValueError:
                counts["refused"] += 1
            except Exception as err:
                counts[f"crashed ({type(err).__name__})"] += 1
                print("recording crashed:", what, type(err).__name__)
    return counts


def env_census(cases, chain_env) -> collections.Counter:
    counts: collections.Counter = collections.Counter()
    for kind, key, value in cases:
        try:
            if kind == "new":
                chain_env(**{key: value}).reset(seed=0)
            else:
                chain_env().reset(seed=0, options={key: value})
            counts["accepted"] += 1
        except ValueError:
            counts["refused"] += 1
        except Exception as err:
            counts[f"crashed ({type(err).__name__})"] += 1
            print("environment crashed:", kind, key, repr(value), type(err).__name__)
    return counts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", help="another checkout's src directory")
    parser.add_argument("--skip-cli", action="store_true")
    args = parser.parse_args()
    # Every case is made with this checkout's code, then put to the checkout under test.
    workdir = Path(tempfile.mkdtemp())
    cases = [] if args.skip_cli else cli_cases(workdir)
    bad = _module(ROOT / "tests" / "data" / "test_recording_fuzz.py").BAD
    tests = _module(ROOT / "tests" / "test_env.py")
    env_cases = [("new", k, v) for k, v in tests._wrong_constructor_args()]
    env_cases += [("reset", k, v) for k, v in tests._wrong_options()]
    if args.source:
        for name in [m for m in sys.modules if m == "masspush" or m.startswith("masspush.")]:
            del sys.modules[name]
        sys.path.insert(0, args.source)
    try:
        check = importlib.import_module("masspush.data.recording").check_recording
    except ImportError:  # the flat layout before issue 25
        check = importlib.import_module("masspush.recording").check_recording
    chain_env = importlib.import_module("masspush.env").ChainEnv
    result = {}
    if cases:
        result["cli"] = cli_census(cases, args.source)
    result["recordings"] = recording_census(bad, check)
    result["environment"] = env_census(env_cases, chain_env)
    print(json.dumps({k: dict(v) for k, v in result.items()}))


if __name__ == "__main__":
    main()
