"""Experimental settings: the paper's six by name, and custom ones from a TOML file.

A settings file holds one table per setting; every key but `links` and `mass_range` is a
`PhysicsConfig` field, validated like the rest:

    [heavy-long-4link]
    links = 4
    mass_range = [1.0, 10.0]
    length_range = [0.15, 0.2]     # any PhysicsConfig field
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from masspush.config import PhysicsConfig

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

PAPER_PUSHER = "kuka"
"""The pusher for reproducing the paper's experiments: its simulated arm, the KUKA KR 5.
With the stiff pusher the [0.1, 1] and [1, 10] kg settings are the same problem up to a
mass scale it cannot see (docs/simulation.md); with the arm they differ, as in the paper.
The stiff pusher stays available everywhere as the fast option (~2-3x faster per push on one
core, and it alone runs on the multi-threaded batch path)."""


@dataclass(frozen=True)
class Setting:
    """A named experimental setting (everything else as in `PhysicsConfig`'s defaults)."""

    name: str
    n_links: int
    mass_range: tuple[float, float]
    """Each link's mass ~ U(mass_range), kg."""
    overrides: dict[str, Any] = field(default_factory=dict)
    """Other PhysicsConfig fields that differ from the defaults."""

    def __post_init__(self) -> None:
        self.physics()  # validates links, mass range and every override

    def physics(self, base: PhysicsConfig | None = None) -> PhysicsConfig:
        known = {f.name for f in fields(PhysicsConfig)}
        unknown = sorted(set(self.overrides) - known)
        if unknown:
            raise ValueError(f"setting {self.name!r}: unknown parameter(s) {unknown}")
        return replace(
            base or PhysicsConfig(),
            n_links=self.n_links,
            mass_range=self.mass_range,
            **{k: tuple(v) if isinstance(v, list) else v for k, v in self.overrides.items()},
        )

    def as_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "n_links": self.n_links,
            "mass_range": list(self.mass_range),
            "overrides": dict(self.overrides),
        }


# The six settings of the paper's Table 1, in its order.
SETTINGS: dict[str, Setting] = {
    s.name: s
    for s in (
        Setting("2link-0.1-1", 2, (0.1, 1.0)),
        Setting("2link-1-10", 2, (1.0, 10.0)),
        Setting("2link-0.1-10", 2, (0.1, 10.0)),
        Setting("3link-0.1-1", 3, (0.1, 1.0)),
        Setting("3link-1-10", 3, (1.0, 10.0)),
        Setting("3link-0.1-10", 3, (0.1, 10.0)),
    )
}


def load_settings(path: str | Path) -> dict[str, Setting]:
    """Custom settings from a TOML file, each validated; errors name the file and setting."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except OSError as err:
        raise ValueError(f"cannot read settings file {path}: {err}") from None
    except tomllib.TOMLDecodeError as err:
        raise ValueError(f"{path} is not valid TOML: {err}") from None
    settings = {}
    for name, table in data.items():
        if not isinstance(table, dict):
            raise ValueError(f"{path}: [{name}] must be a table of parameters")
        table = dict(table)
        try:
            links = table.pop("links")
            mass_range = tuple(table.pop("mass_range"))
        except KeyError as err:
            raise ValueError(f"{path}: setting [{name}] lacks {err}") from None
        try:
            settings[name] = Setting(name, links, mass_range, table)
        except (ValueError, TypeError) as err:
            raise ValueError(f"{path}: setting [{name}]: {err}") from None
    return settings


def get_setting(name: str, settings_file: str | Path | None = None) -> Setting:
    """The named setting (the paper's, or one from `settings_file`), or a clear ValueError."""
    known = dict(SETTINGS)
    if settings_file is not None:
        known.update(load_settings(settings_file))
    try:
        return known[name]
    except KeyError:
        raise ValueError(f"unknown setting {name!r}; known settings: {list(known)}") from None
