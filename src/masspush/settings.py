"""Experimental settings: the paper's six by name, and custom ones from a TOML file.

A settings file holds one table per setting; every key but `links`, `mass_range`, `pusher`
(default "kuka") and `pushes` (per episode; default the paper's) is a `PhysicsConfig` field,
validated like the rest:

    [heavy-long-4link]
    links = 4
    mass_range = [1.0, 10.0]
    pusher = "stiff"
    pushes = 5
    length_range = [0.15, 0.2]     # any PhysicsConfig field
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from masspush.config import EnvConfig, PhysicsConfig
from masspush.sim.pushers import PUSHERS

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

PAPER_PUSHER = "kuka"
"""The pusher for reproducing the paper's experiments: its simulated arm, the KUKA KR 5.
The stiff pusher stays available everywhere as the fast option (~2-3x faster per push on one
core, and it alone runs on the multi-threaded batch path)."""
HEAVY_PUSHER = "stiff"
"""The pusher for the settings whose links weigh up to 10 kg. Our torque-limited KR 5 moves
such chains a median 0.6 mm per push, below the 1 cm observation noise (docs/notebook,
"heavy chains"), while the paper's [1, 10] kg errors (RP 17.1, near its 15.3 for [0.1, 1])
show that its arm moved them. The stiff pusher does literally what the paper's controller
was told to do, hold the push velocity for 10 ms of contact, whatever the chain weighs."""
LONG_RUN_UP_PUSHER = "kuka-far"
"""The pusher for the 3-link [0.1, 1] kg cell: the same KR 5, same model and torques,
placed 0.64 m behind the contact with a 13 cm run-up instead of 0.60 m and 8 cm. The
torque-limited tip's top speed is set by its run-up (v^2 = 2 a d: 2.6 m/s over 8 cm, 3.2 m/s
over 13 cm), and the paper does not say where its arm stood. With 3 links the farther arm's
pushes taught more at every stage of the recipe (TP 23.90 against 28.71, TP+ of five
predictors 13.05 against 14.47 on fresh episodes) and the particle filter gained 5 points
(docs/notebook/2026-12-01-arm-speed.md, "The run-up sets the arm's speed"). With 2 links it
did not pay: the same recipe through it reached TP+ 7.73 against `kuka`'s 5.29, so
2link-0.1-1 keeps `PAPER_PUSHER` [ours]."""


@dataclass(frozen=True)
class Setting:
    """A named experimental setting (everything else as in `PhysicsConfig`'s defaults)."""

    name: str
    n_links: int
    mass_range: tuple[float, float]
    """Each link's mass ~ U(mass_range), kg."""
    overrides: dict[str, Any] = field(default_factory=dict)
    """Other PhysicsConfig fields that differ from the defaults."""
    pusher: str = PAPER_PUSHER
    """The pusher that collection, baselines and training use unless told otherwise."""
    pushes: int | None = None
    """Pushes per episode; None: the paper's (2 for two links, 3 for three)."""

    def __post_init__(self) -> None:
        self.physics()  # validates links, mass range and every override
        if self.pusher not in PUSHERS:
            raise ValueError(f"unknown pusher {self.pusher!r}; known pushers: {list(PUSHERS)}")
        self.env_config()  # validates pushes

    def env_config(self, pusher: str | None = None, **noise: float) -> EnvConfig:
        """The episode of this setting: its physics, pushes per episode and pusher (the
        setting's unless `pusher` is given); `noise`: obs_noise / action_noise overrides."""
        return EnvConfig(
            physics=self.physics(), pushes=self.pushes, pusher=pusher or self.pusher, **noise
        )

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

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Setting:
        """The setting `as_dict` wrote (e.g. a dataset manifest's), overrides included: a
        settings file's physics, not the named built-in's. `as_dict` keeps no pusher (a
        manifest records the one it used): the default's."""
        return cls(d["name"], int(d["n_links"]), tuple(d["mass_range"]),
                   dict(d.get("overrides", {})), pushes=d.get("pushes"))  # fmt: skip

    def as_dict(self) -> dict[str, Any]:
        extra = {} if self.pushes is None else {"pushes": self.pushes}
        return {
            "name": self.name,
            "n_links": self.n_links,
            "mass_range": list(self.mass_range),
            "overrides": dict(self.overrides),
            **extra,
        }


# The six settings of the paper's Table 1, in its order.
SETTINGS: dict[str, Setting] = {
    s.name: s
    for s in (
        Setting("2link-0.1-1", 2, (0.1, 1.0)),
        Setting("2link-1-10", 2, (1.0, 10.0), pusher=HEAVY_PUSHER),
        Setting("2link-0.1-10", 2, (0.1, 10.0), pusher=HEAVY_PUSHER),
        Setting("3link-0.1-1", 3, (0.1, 1.0), pusher=LONG_RUN_UP_PUSHER),
        Setting("3link-1-10", 3, (1.0, 10.0), pusher=HEAVY_PUSHER),
        Setting("3link-0.1-10", 3, (0.1, 10.0), pusher=HEAVY_PUSHER),
    )
}

REAL_SETTING = Setting(
    "real-ur10",
    2,
    (0.01, 0.3),
    {"root_xy_range": 0.2, "init_joint_range": 1.55},
    pusher="ur10-stationary",
)
"""The paper's real experiment, trained in simulation: a UR10 standing beside the table
(`ur10-stationary`: it cannot follow the chain, and a chain out of its reach ends the
episode) pushes a 2-link chain whose links weigh 0.01-0.3 kg (its five test classes lie
inside), hinge range +-pi/2 (our joint_limit, 1.55 rad, with self-collision at pi/2)
[paper-details.md, "Real robot"; the stationary robot: paper Sec. 5]. Chains start with
their first link within 0.2 m of the origin, over most of the robot's workspace (95 % of
them wholly inside it), so that its policy learns to push from anywhere in reach, as it must
when runs of the policy follow one another [ours; with 0.1 m, 19 of 40 chains were lost
over 8 runs, docs/notebook 2026-12-01-stationary-robot]. Start angles span the whole hinge
range, as later runs find the chain (pushes fold it: |q| 0.71 rad on average at a later
run's start against 0.36 with the paper's +-0.75) [ours, docs/notebook
2026-12-02-runs-of-the-policy]. The robot's speed governor keeps the chain in reach
(`masspush.sim.ReachGovernor`)."""

REAL_SETTING_4 = Setting(
    "real-ur10-4push",
    2,
    (0.01, 0.3),
    {"root_xy_range": 0.2, "init_joint_range": 1.55},
    pusher="ur10-stationary",
    pushes=4,
)
"""The real setup with 4 pushes per episode instead of the paper's 2 [ours]: whether more
pushes per episode separate the paper's close mass classes (docs/notebook, Sim-to-real).
The same stationary UR10, start poses and speed governor as `REAL_SETTING`."""

KNOWN_SETTINGS: dict[str, Setting] = {
    s.name: s for s in (*SETTINGS.values(), REAL_SETTING, REAL_SETTING_4)
}
"""Every built-in setting: the paper's six and the real setup's (2 and 4 pushes)."""


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
        pusher = table.pop("pusher", PAPER_PUSHER)
        pushes = table.pop("pushes", None)
        try:
            settings[name] = Setting(name, links, mass_range, table, pusher, pushes)
        except (ValueError, TypeError) as err:
            raise ValueError(f"{path}: setting [{name}]: {err}") from None
    return settings


def get_setting(name: str, settings_file: str | Path | None = None) -> Setting:
    """The named setting (the paper's, or one from `settings_file`), or a clear ValueError."""
    known = dict(KNOWN_SETTINGS)
    if settings_file is not None:
        known.update(load_settings(settings_file))
    try:
        return known[name]
    except KeyError:
        raise ValueError(f"unknown setting {name!r}; known settings: {list(known)}") from None
