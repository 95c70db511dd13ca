"""The `masspush` command line: a thin layer over the package.

Each command's options come from config dataclasses (`masspush.cli.options`); a command
parses, calls one function and prints. Commands live in one module per group (estimate,
data, train, real robot, report). Bad input ends in one line on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from masspush.cli import data, estimate, real, reports, train
from masspush.cli.command import Command

COMMANDS: list[Command] = [
    *estimate.COMMANDS, *data.COMMANDS, *train.COMMANDS, *real.COMMANDS, *reports.COMMANDS
]  # fmt: skip


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
    parser = argparse.ArgumentParser(
        prog="masspush",
        description="Estimate the mass distribution of articulated objects by pushing them.",
        epilog=_grouped_listing(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
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


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    chosen = _chosen(argv)
    parser = build_parser(only=chosen, everything=False)
    try:
        args = parser.parse_args(argv)
        return args.func(args)
    except BrokenPipeError:  # the reader stopped listening (`| head`): nothing to say
        sys.stderr.close()
        return 0
    except (ValueError, OSError) as err:  # bad input: a message, not a traceback
        message = str(err)
        if isinstance(err, OSError) and err.filename is not None:
            message = f"{err.filename}: {err.strerror}"
        print(f"masspush: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("masspush: interrupted (long runs resume when run again)", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
