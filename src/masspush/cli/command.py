"""A command of the `masspush` CLI: its name, group and help, how it adds its options
(only when it is the command being run, so that `masspush --help` imports nothing heavy),
and what it runs."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class Command:
    name: str
    """`masspush <name>`; "bench sim" for a subcommand of bench."""
    group: str
    """Where `masspush --help` lists it."""
    help: str
    options: Callable[[argparse.ArgumentParser], None]
    """Adds the command's options (built from the config dataclasses)."""
    run: Callable[[argparse.Namespace], int]
    """Builds the configs, calls one function and prints; returns the exit status."""
