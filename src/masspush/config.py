"""Every physical constant and paper value of the simulated world, in one place.

Sources named in the comments:
- [paper]   Kumar, Essa, Ha, Liu, "Estimating Mass Distribution of Articulated Objects
            using Non-prehensile Manipulation", CoRL 2020 (Sec. 3.4 and 4).
- [code]    the authors' research code, as summarised in shared/notes/paper-details.md.
- [notes]   our MuJoCo measurements, shared/notes/mujoco-chain-physics.md.
- [ours]    our own choice; docs/simulation.md explains each one.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

Range = tuple[float, float]


def check_range(name: str, value: Range, *, low: float | None = None) -> None:
    """Raise ValueError unless value is a finite (lo, hi) pair with lo <= hi (and lo >= low)."""
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a (low, high) pair, got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    if lo > hi:
        raise ValueError(f"{name} is empty: low {lo} > high {hi}")
    if low is not None and lo < low:
        raise ValueError(f"{name} must not go below {low}, got {value!r}")


class MismatchError(ValueError):
    """A file made for another setting, pusher or chain than it is used with."""


def check_match(
    what: str, where: str, theirs: Any, ours: Any, allow: bool = False, allowable: bool = True
) -> None:
    """Refuse `where` (a file), made for `what` `theirs`, where `ours` is asked for; unless
    `allow` (--allow-mismatch) and the difference is one a model can be run across
    (`allowable`: not the number of links, which changes every array's shape)."""
    if theirs is None or theirs == ours:
        return
    if allow and allowable:
        return
    hint = "; pass --allow-mismatch to use it anyway" if allowable else ""
    raise MismatchError(f"{where} is for {what} {theirs!r}, not {ours!r}{hint}")


SEED_MAX = 2**32 - 1
"""The largest seed a run or session takes: its chains' seeds are the seed times a block of
a million or fewer, times the runs of an episode, and must fit the policies' 64-bit seeds."""


def check_int(
    name: str, value: Any, low: int = 1, optional: bool = False, high: int | None = None
) -> None:
    """Raise ValueError unless value is an integer >= low, and <= high where given (or None,
    where `optional`)."""
    if optional and value is None:
        return
    if not isinstance(value, int) or isinstance(value, bool) or value < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    if high is not None and value > high:
        raise ValueError(f"{name} must be an integer <= {high}, got {value!r}")


def check_choice(name: str, value: Any, choices: tuple, optional: bool = False) -> None:
    """Raise ValueError unless value is one of `choices` (or None, where `optional`)."""
    if optional and value is None:
        return
    if value not in choices:
        raise ValueError(f"{name} must be one of {list(choices)}, got {value!r}")


def check_input(path: str, name: str) -> None:
    """Raise ValueError unless `path` is an existing file (not a directory)."""
    p = Path(path)
    if p.is_dir():
        raise ValueError(f"{name}: {path} is a directory, not a file")
    if not p.exists():
        raise ValueError(f"{name}: no file at {path}")


def check_output(path: str, name: str, suffixes: tuple[str, ...] = ()) -> None:
    """Raise ValueError unless `path` can be written as a file: not a directory, in a
    directory that exists or can be made, not read-only, ending in one of `suffixes`. Checked
    before any work, so that a run never fails at its save."""
    p = Path(path)
    if suffixes and p.suffix.lower() not in suffixes:
        raise ValueError(f"{name} must end in {' or '.join(suffixes)}, got {str(path)!r}")
    if p.is_dir():
        raise ValueError(f"{name}: {path} is a directory, not a file")
    if p.exists() and not os.access(p, os.W_OK):
        raise ValueError(f"{name}: {path} is not writable")
    parent = next((q for q in [p.parent, *p.parent.parents] if q.exists()), Path("."))
    if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
        raise ValueError(f"{name}: cannot write under {parent}")


def _check_positive(name: str, value: float) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")


def _check_non_negative(name: str, value: float) -> None:
    if not (
        isinstance(value, (int, float)) and not isinstance(value, bool)
        and math.isfinite(value) and value >= 0
    ):  # fmt: skip
        raise ValueError(f"{name} must be a non-negative finite number, got {value!r}")


MAX_PUSHES = 1000
"""The most pushes one episode may have. The paper's episodes have 2-4 pushes and our
longest runs 32; episodes are padded to the longest, so a stated limit keeps a typo from
costing gigabytes [ours]."""
MAX_NOISE = 1.0
"""The largest noise std accepted (m, rad, action units): beyond, an observation says
nothing and an action is clipped to the box's corners [ours]."""

MAX_LINKS = 64
"""The longest chain supported. Every length up to it resets and pushes (tests/sim); a
64-link episode already takes seconds, and 100 links tens of seconds a push [ours]."""

PLAUSIBLE: dict[str, tuple[float, float]] = {
    "masses": (1e-3, 1e3),
    "friction": (1e-3, 3.0),
    "lengths": (1e-3, 2.0),
    "root_xy": (-1e3, 1e3),
}
"""Limits no chain on a table can be outside, whatever a setting or `allow_out_of_range`
says: a link of 1 g to a tonne, a friction coefficient up to 3 (rubber on rubber is about
1-2), links of 1 mm to 2 m, a chain within a kilometre of the table's origin. Values beyond
are typos or unit mistakes (grams for kilograms), and MuJoCo would not simulate them
faithfully at a 1 ms step [ours]."""


def check_plausible(name: str, values: Any) -> None:
    """Raise ValueError unless every value of `name` (a PLAUSIBLE key) is within its limits."""
    lo, hi = PLAUSIBLE[name]
    items = [float(v) for v in (values if isinstance(values, (list, tuple)) else [values])]
    if not all(lo <= v <= hi for v in items):  # NaN fails too
        raise ValueError(
            f"{name} {items} outside what a chain on a table can have, [{lo:g}, {hi:g}]"
        )


@dataclass(frozen=True)
class PhysicsConfig:
    """The simulated world: chain, table, push mapping and simulation numerics.

    Each episode samples one chain from the ranges here (see `masspush.sim.chain.sample_chain`).
    Lengths in metres, masses in kilograms, angles in radians, times in seconds.
    """

    # --- the chain and its sampling distributions ---------------------------------------
    n_links: int = 2
    """Number of links; the paper studies 2 and 3 [paper]."""
    mass_range: Range = (0.1, 1.0)
    """Each link's mass ~ U(mass_range), kg; the paper uses [0.1,1], [1,10], [0.1,10] [paper]."""
    friction_range: Range = (0.5, 1.0)
    """Table friction coefficient mu ~ U(friction_range) per episode [paper Sec. 4.2]."""
    length_range: Range = (0.1, 0.15)
    """Each link's length (the pushable face) ~ U(length_range), m [paper Sec. 4.2]."""
    link_width: float = 0.04
    """Width of a link box, m (the pushed faces are link_width apart) [ours, notes' model]."""
    link_height: float = 0.03
    """Height of a link box, m [ours, notes' model]."""
    joint_gap: float = 0.04
    """Gap between neighbouring boxes, hinge in its middle, m. With gap = width the boxes
    first touch at +-pi/2, just past the joint limit, so self-collision backs the limit [ours]."""
    joint_limit: float = 1.55
    """Hinge range +-joint_limit, rad [code]."""
    init_joint_range: float = 0.75
    """Initial joint angles ~ U(-init_joint_range, init_joint_range), rad [code]."""
    root_xy_range: float = 0.1
    """Initial root link centre ~ U(-r, r)^2 on the table, m [ours]."""
    root_yaw_range: Range = (-math.pi, math.pi)
    """Initial yaw of the root link ~ U(root_yaw_range), rad: any heading by default [ours];
    narrower for a chain put down by hand in a chosen direction (`masspush sim2real
    --start-yaw`)."""
    link_friction: float = 0.5
    """Friction of link-link contacts (the table's mu governs link-table) [ours]. A link-pusher
    contact takes the larger of it and `tool_friction` (MuJoCo's rule for geoms of equal
    priority), so with the defaults it is 1.0, not 0.5."""
    tool_friction: float = 1.0
    """Friction of the pusher's tool (the stiff pusher's tip, an arm's end-effector) [MuJoCo's
    default geom friction, which every shipped model was trained with]. In contact the link's
    face slides along the tool up or down, so the tool's friction presses the link onto the
    table (the force on the tool points down by about this times its push). With 1.0, a chain
    on a table of friction 1 moved a fifth as far (median) as on one of 0.5 under the
    stationary UR10's pushes (seven tenths with a tool of 0.5), and half as far under the stiff
    pusher's (as far with 0.5) (docs/notebook/2026-12-07-sticky-tables.md)."""

    # --- the push -----------------------------------------------------------------------
    push_speed_max: float = 5.0
    """Push speed = push_speed_max * |a1|, m/s [code]."""
    push_offset_fraction: float = 0.9
    """Contact point offset from the link centre spans +-fraction/2 of its length [code]."""
    push_hold_time: float = 0.010
    """Time the pusher holds the target speed in contact, s: 10 steps of 1 ms [paper, code]."""
    push_ramp_time: float = 0.005
    """Linear ramp from rest to the target speed before the hold, s. The paper's arm reaches
    its target speed with time constant 1/kd = 6.6 ms; an instant jump converges badly in dt
    [notes]."""
    pusher_radius: float = 0.01
    """Radius of the stiff pusher's tip, m (a vertical capsule, like the dowel of the paper's
    real setup: a ball can ride up a rocking link's edge and throw the chain) [ours]."""
    pusher_clearance: float = 0.001
    """Gap between the ball and the pushed face when the push starts, m [ours]."""
    pusher_contact_time: float = 0.005
    """Time constant of the pusher-link contact (MuJoCo solref), s: stiffer than the
    default 0.02 s so the tip does not sink ~2 mm into the link [notes]."""
    pusher_mass: float = 1.0e4
    """Mass of the idealised stiff pusher, kg: >300x the heaviest chain, so a chain's
    mass barely slows it (the property that makes a common mass scale unobservable) [ours]."""

    # --- simulation numerics ------------------------------------------------------------
    timestep: float = 0.001
    """Physics step, s [paper: 1 ms]. 5 ms is unusable [notes]."""
    rest_velocity: float = 1.0e-3
    """At rest when every chain velocity component is below this (m/s, rad/s). The paper
    used 0.05; the stricter value moves the rest pose by < 0.3 mm and costs ~10 ms sim [notes]."""
    rest_check_steps: int = 10
    """The rest and failure checks run every this many steps (the same in every path) [ours]."""
    settle_time_cap: float = 10.0
    """A push not at rest after this much simulated time is a 'timeout' failure, s. The
    paper capped at 100 s; pushes here settle in < 2 s, so 10 s is a wide margin [ours]."""
    arena_memory: int = 1 << 20
    """Bytes of MuJoCo arena (contacts, constraints) per simulation. The batch reserves one
    per chain; MuJoCo's default for these models (13.6 MB) reserved 7.7 GB of virtual memory
    per 1000 chains, enough to make a later fork fail. 1 MB gives identical results (the
    scene needs a few dozen contacts) at 0.6 GB per 1000 chains [ours]. Long chains get more
    (`arena_bytes`)."""
    max_velocity: float = 500.0
    """Any chain velocity component above this (m/s, rad/s) is an 'unstable' failure [ours]."""
    max_tilt: float = 0.1
    """A chain that comes to rest tilted more than this from flat (tipped onto a side)
    is an 'unstable' failure, rad. Transient rocking during impacts is allowed [ours]."""
    max_lift: float = 0.25
    """A root link more than this above its resting height (thrown off the table) is an
    'unstable' failure, m. Hard pushes make links hop a few cm and land flat [ours]."""

    def __post_init__(self) -> None:
        if not isinstance(self.n_links, int) or isinstance(self.n_links, bool) or self.n_links < 2:
            raise ValueError(f"n_links must be an integer >= 2, got {self.n_links!r}")
        if self.n_links > MAX_LINKS:
            raise ValueError(f"n_links must be at most {MAX_LINKS} (supported), got {self.n_links}")
        check_range("mass_range", self.mass_range)
        if float(self.mass_range[0]) <= 0:
            raise ValueError(f"mass_range must be positive, got {self.mass_range!r}")
        check_range("friction_range", self.friction_range)
        if float(self.friction_range[0]) <= 0:
            raise ValueError(f"friction_range must be positive, got {self.friction_range!r}")
        check_range("length_range", self.length_range)
        if float(self.length_range[0]) <= 0:
            raise ValueError(f"length_range must be positive, got {self.length_range!r}")
        check_range("root_yaw_range", self.root_yaw_range)
        # Normalise ranges to float tuples so configs compare and serialise cleanly.
        for name in ("mass_range", "friction_range", "length_range", "root_yaw_range"):
            object.__setattr__(self, name, tuple(float(v) for v in getattr(self, name)))
        check_plausible("masses", self.mass_range)
        check_plausible("friction", self.friction_range)
        check_plausible("lengths", self.length_range)
        for name in (
            "link_width",
            "link_height",
            "joint_gap",
            "joint_limit",
            "push_speed_max",
            "push_offset_fraction",
            "push_hold_time",
            "pusher_radius",
            "pusher_mass",
            "timestep",
            "rest_velocity",
            "settle_time_cap",
            "max_velocity",
            "max_tilt",
            "max_lift",
            "link_friction",
            "tool_friction",
            "pusher_contact_time",
        ):
            _check_positive(name, getattr(self, name))
        for name in ("init_joint_range", "root_xy_range", "push_ramp_time", "pusher_clearance"):
            _check_non_negative(name, getattr(self, name))
        if self.push_offset_fraction > 1:
            raise ValueError(f"push_offset_fraction must be <= 1, got {self.push_offset_fraction}")
        if self.init_joint_range > self.joint_limit:
            raise ValueError(
                f"init_joint_range {self.init_joint_range} exceeds joint_limit {self.joint_limit}"
            )
        if self.pusher_radius >= self.link_height:
            raise ValueError(f"pusher_radius {self.pusher_radius} must be below link_height")
        if not isinstance(self.arena_memory, int) or self.arena_memory < (256 << 10):
            raise ValueError(
                f"arena_memory must be an integer >= 262144, got {self.arena_memory!r}"
            )
        if not isinstance(self.rest_check_steps, int) or self.rest_check_steps < 1:
            raise ValueError(
                f"rest_check_steps must be an integer >= 1, got {self.rest_check_steps!r}"
            )

    @property
    def push_steps(self) -> tuple[int, int]:
        """(ramp, hold) durations of the push in physics steps."""
        return (
            round(self.push_ramp_time / self.timestep),
            max(1, round(self.push_hold_time / self.timestep)),
        )

    @property
    def arena_bytes(self) -> int:
        """MuJoCo arena for this chain: `arena_memory`, or more for long chains, whose
        constraint count grows with the square of the links (measured: 50 links need 2 MB,
        100 links 4 MB; 1 kB per link squared covers both) [ours]."""
        return max(self.arena_memory, 1024 * self.n_links**2)

    @property
    def obs_dim(self) -> int:
        """Length of a chain configuration: root x, y, yaw and n - 1 joint angles."""
        return 3 + self.n_links - 1

    @property
    def geometry(self) -> ChainGeometry:
        """The simulated chain's cross-section and hinge gap, with the stiff pusher's tip
        radius (an arm's tool has its own: `masspush.sim.pushers.tool_radius`)."""
        return ChainGeometry(self.link_width, self.link_height, self.joint_gap, self.pusher_radius)

    def with_geometry(self, geometry: ChainGeometry) -> PhysicsConfig:
        """This world with a measured chain's cross-section and hinge gap (what `push_geometry`
        reads to place a push on the chain); the tool's radius stays the model's."""
        return replace(
            self,
            link_width=geometry.link_width,
            link_height=geometry.link_height,
            joint_gap=geometry.joint_gap,
        )


@dataclass(frozen=True)
class ChainGeometry:
    """The shape of a chain where a push meets it, as a lab measures it on its own object
    (docs/real-robot.md, "Your chain's geometry"). No defaults: a lab enters its own.

    `push_geometry` places a push from the link width (which face is touched) and the hinge
    gap (where each link's centre is); a model was trained for one geometry, and a chain of
    another is pushed differently (`masspush.real.robot.check_geometry` warns)."""

    link_width: float
    """Distance between a link's two pushed faces, m."""
    link_height: float
    """Height of a link above the table, m."""
    joint_gap: float
    """Gap between the ends of neighbouring links, the hinge in its middle, m."""
    tool_radius: float
    """Radius of the tool where it touches the link (the dowel's, the ball's), m."""

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "joint_gap":  # links may touch end to end
                _check_non_negative(f.name, value)
            else:
                _check_positive(f.name, value)
            if value > 0.5:
                raise ValueError(f"{f.name} = {value} m: a chain's geometry is in metres")

    def differences(self, other: ChainGeometry, tolerance: float = 1e-3) -> list[str]:
        """'name: ours vs theirs' for each measure that differs by more than `tolerance` m."""
        return [
            f"{f.name} {getattr(self, f.name)} m vs {getattr(other, f.name)} m"
            for f in fields(self)
            if abs(getattr(self, f.name) - getattr(other, f.name)) > tolerance
        ]


def default_pushes(n_links: int) -> int:
    """Pushes per episode: 2 for 2 links, 3 for 3 links [code]; n for longer chains [ours]."""
    return n_links


@dataclass(frozen=True)
class EnvConfig:
    """What the Gymnasium environment adds to the world: episode length and sensing noise."""

    physics: PhysicsConfig = field(default_factory=PhysicsConfig)
    """The simulated world."""
    pushes: int | None = None
    """Pushes per episode K; None for the paper's default (`default_pushes`)."""
    obs_noise: float = 0.01
    """Std of Gaussian noise on each observed configuration component (m, rad) [paper]."""
    action_noise: float = 0.01
    """Std of Gaussian noise added to each action component before execution [paper]."""
    pusher: str = "stiff"
    """Which pusher delivers the pushes; see `masspush.sim.pushers.PUSHERS`."""

    def __post_init__(self) -> None:
        if self.pushes is None:
            object.__setattr__(self, "pushes", default_pushes(self.physics.n_links))
        if not isinstance(self.pushes, int) or isinstance(self.pushes, bool) or self.pushes < 1:
            raise ValueError(f"pushes must be an integer >= 1, got {self.pushes!r}")
        if self.pushes > MAX_PUSHES:
            raise ValueError(f"pushes must be at most {MAX_PUSHES}, got {self.pushes}")
        for name in ("obs_noise", "action_noise"):
            _check_non_negative(name, getattr(self, name))
            if getattr(self, name) > MAX_NOISE:
                raise ValueError(f"{name} must be at most {MAX_NOISE}, got {getattr(self, name)}")


def physics_with(physics: PhysicsConfig | None = None, **overrides: Any) -> PhysicsConfig:
    """A PhysicsConfig with some fields replaced; unknown field names raise a clear error."""
    base = physics or PhysicsConfig()
    known = {f.name for f in fields(PhysicsConfig)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise ValueError(f"unknown physics parameter(s) {unknown}; known: {sorted(known)}")
    return replace(base, **overrides)
