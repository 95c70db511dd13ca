"""The `masspush` command line: a thin layer over the package.

Each command's options come from config dataclasses (`masspush.cli.options`); a command
parses, calls one function and prints. Commands live in one module per group (estimate,
data, train, real robot, report). Bad input ends in one line on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from collections.abc import Callable, Sequence
from typing import NoReturn, TextIO

from masspush.cli import data, estimate, real, reports, train
from masspush.cli.command import Command

COMMANDS: list[Command] = [
    *estimate.COMMANDS, *data.COMMANDS, *train.COMMANDS, *real.COMMANDS, *reports.COMMANDS
]  # fmt: skip


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line usage error: `masspush COMMAND: error: ...`, exit 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _grouped_listing() -> str:
    lines, group = [], None
    width = max(len(c.name) for c in COMMANDS) + 2
    for command in COMMANDS:
        if command.group != group:
            group = command.group
            lines.append(f"\n{group}:")
        lines.append(f"  {command.name:<{width}}{command.help}")
    return "commands (`masspush COMMAND --help` for each one's options):" + "\n".join(lines)


def _chosen(argv: Sequence[str]) -> str | None:
    """The command `argv` runs ("bench sim" for a bench), so that only its options are built."""
    words = [a for a in argv if not a.startswith("-")]
    if not words:
        return None
    if words[0] == "bench" and len(words) > 1:
        return f"bench {words[1]}"
    return words[0]


def build_parser(only: str | None = None, everything: bool = True) -> argparse.ArgumentParser:
    """The parser; the options of the command `only` (of every command with `everything`
    and no `only`) built from their config dataclasses."""
    parser = _Parser(
        prog="masspush",
        description="Estimate the mass distribution of articulated objects by pushing them.",
        epilog=_grouped_listing(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--debug", action="store_true", help="show the traceback behind an error message"
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    bench = sub.add_parser("bench", description="benchmarks")
    bench_sub = bench.add_subparsers(dest="what", metavar="BENCH", required=True)
    for command in COMMANDS:
        target, name = sub, command.name
        if name.startswith("bench "):
            target, name = bench_sub, name.split(" ", 1)[1]
        # The top level lists its commands by group in the epilog, not in argparse's list.
        shown = {"help": command.help} if target is bench_sub else {}
        p = target.add_parser(name, description=command.help, **shown)
        if command.name == only or (only is None and everything):
            command.options(p)
        p.set_defaults(func=command.run)
    return parser


DEBUG_ENV = "MASSPUSH_DEBUG"
"""Set (to anything but 0) to see the traceback behind an error message, as `--debug` does."""


def _one_line(err: BaseException) -> str:
    """The error as one line naming the file or argument: a recording's first problem of
    several, an operating-system error's file and reason."""
    from masspush.data.recording import RecordingError, problem_count

    if isinstance(err, RecordingError):
        first = err.problems[0] if err.problems else ""
        others = problem_count(err.problems) - 1
        more = f"; {others} more: masspush check-episodes" if others > 0 else ""
        return f"{str(err).splitlines()[0]}; the first: {first}{more}"
    if isinstance(err, OSError) and err.filename is not None:
        return f"{err.filename}: {err.strerror}"
    return " ".join(str(err).split()) or type(err).__name__


def _one_line_warning(chosen: str | None) -> Callable[..., None]:
    def show(
        message: Warning | str, category: type[Warning], filename: str, lineno: int,
        file: TextIO | None = None, line: str | None = None,
    ) -> None:  # fmt: skip
        print(f"masspush {chosen}: warning: {_one_line(message)}", file=file or sys.stderr)

    return show


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command. Bad input (exit 2) and a failing file system (exit 1) end in one line
    on stderr, `masspush COMMAND: error: ...`; `--debug` (or MASSPUSH_DEBUG=1) shows the
    traceback instead."""
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv[:1] or os.environ.get(DEBUG_ENV, "0") not in ("", "0")
    argv = argv[1:] if argv[:1] == ["--debug"] else argv
    chosen = _chosen(argv)
    parser = build_parser(only=chosen, everything=False)
    args = parser.parse_args(argv)  # a usage error: argparse's message, exit 2
    try:
        with warnings.catch_warnings():
            if not debug:  # our warnings to a user: one line each, said once
                warnings.showwarning = _one_line_warning(chosen)
                warnings.filterwarnings("once", category=UserWarning, module="masspush")
            return args.func(args)
    except BrokenPipeError:  # the reader stopped listening (`| head`): nothing to say
        sys.stderr.close()
        return 0
    except (ValueError, OSError) as err:
        if debug:
            raise
        print(f"masspush {chosen}: error: {_one_line(err)}", file=sys.stderr)
        return 1 if isinstance(err, OSError) else 2
    except KeyboardInterrupt:
        print(f"masspush {chosen}: interrupted (long runs resume when run again)", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
