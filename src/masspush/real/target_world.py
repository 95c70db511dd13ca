"""A stand-in for the real world: a simulated world that deliberately differs from training.

We have no robot, so the sim-to-real test (docs/real-robot.md) runs the trained models in
a world built to differ from the one they were trained in the ways a real lab does:

- **contact and solver**: pyramidal friction cones, the CG solver with few iterations, a
  0.5 ms step, other link contact stiffness and damping, torsional friction (condim 4),
  the table's friction (not a fixed 0.5) between links and with the tool;
- **friction that varies over the table**: a smooth random field (a few planar waves),
  felt by each link where it lies, updated every physics step; the mean is drawn from a
  wider range than in training;
- **geometry**: wider, taller links with a wider gap, each link's centre of mass off its
  middle, and link lengths that the robot knows only as measured (a few mm off);
- **tracking**: more noise than in training plus a bias held for the whole episode (a
  calibration offset of the camera or the markers);
- **actuation**: a per-episode gain on the push speed and bias on the contact point,
  on top of more noise than in training.

By default every episode draws all of these afresh, as if each were run in a lab of its
own: a stress test. A real lab has one table, one calibration, one robot and one set of
objects, pushed again and again (the paper's UR10 pushed the same 3D-printed chains 30 times
each). `Lab` is that: the table's friction and its field, the tracker's bias, the robot's
speed gain and contact bias and the chain's lengths drawn once from a lab seed, each mass
class's centre-of-mass offsets once per object; only the chain's pose on the table and the
noise change between episodes. A lab's later day (`Lab`'s `day`) keeps its objects but not
quite its table, robot or tracker: a day's drift, drawn once for the day.

`TargetWorldRobot` is a `masspush.real.robot.Robot`: everything that runs on a robot runs in it
(`masspush run --robot target`, `masspush sim2real`). Every number below is our own choice
[ours]; docs/real-robot.md lists them beside the training world's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from masspush.config import EnvConfig, PhysicsConfig, Range
from masspush.real.robot import PushReport, RestPose
from masspush.sim.chain import sample_chain, wrap_angle
from masspush.sim.pushers import make_pusher, reach_governor
from masspush.sim.simulate import ChainSim

if TYPE_CHECKING:
    from masspush.settings import Setting

SOLVERS = {"CG": mujoco.mjtSolver.mjSOL_CG, "Newton": mujoco.mjtSolver.mjSOL_NEWTON,
           "PGS": mujoco.mjtSolver.mjSOL_PGS}  # fmt: skip
CONES = {"pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL, "elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC}


@dataclass(frozen=True)
class TargetWorld:
    """How the target world differs from the training simulation [ours, each]."""

    # --- contact and solver -------------------------------------------------------------
    timestep: float = 0.0005
    """Physics step, s (training: 0.001)."""
    solver: str = "CG"
    """MuJoCo's constraint solver: "CG", "Newton" or "PGS" (training: "Newton")."""
    solver_iterations: int = 20
    """Solver iterations (training: 100)."""
    cone: str = "pyramidal"
    """Friction cones: "pyramidal" or "elliptic" (training: "elliptic")."""
    contact_solref: tuple[float, float] = (0.01, 0.8)
    """Time constant and damping ratio of every link contact (training: MuJoCo's 0.02, 1)."""
    contact_solimp: tuple[float, float, float] = (0.8, 0.95, 0.002)
    """Impedance of every link contact (training: MuJoCo's 0.9, 0.95, 0.001)."""
    torsional_friction: float = 0.01
    """Torsional friction of link contacts, m (condim 4; training: condim 3)."""
    # --- friction over the table ----------------------------------------------------------
    friction_range: Range = (0.4, 1.1)
    """Mean table friction ~ U(range) per episode (training: 0.5-1.0)."""
    friction_variation: float = 0.15
    """Relative std of the friction field over the table."""
    friction_wavelength: Range = (0.15, 0.6)
    """Wavelengths of the field's planar waves ~ U(range), m."""
    friction_waves: int = 6
    # --- geometry -----------------------------------------------------------------------
    link_width: float = 0.045
    """m (training: 0.04); the hinge gap grows with it, so links still meet at +-pi/2."""
    link_height: float = 0.035
    """m (training: 0.03)."""
    com_offset: float = 0.006
    """Each link's centre of mass sits ~ U(-c, c) along it from its middle, m."""
    length_error: float = 0.003
    """Std of the error of the link lengths the robot is told, m."""
    # --- tracking -----------------------------------------------------------------------
    obs_noise: float = 0.015
    """Std of the per-observation noise on each component, m or rad (training: 0.01)."""
    obs_bias: tuple[float, float] = (0.005, 0.02)
    """Std of the per-episode bias: position (m), angles (rad)."""
    # --- actuation ----------------------------------------------------------------------
    action_noise: float = 0.02
    """Std of the per-push noise on each action component (training: 0.01)."""
    speed_gain: Range = (0.85, 1.15)
    """Per-episode factor on a1 (the push speed) ~ U(range)."""
    contact_bias: float = 0.03
    """Std of the per-episode bias on a2 (where along the link the tool lands)."""
    # --- from one day to the next in a lab (`Lab`'s day) ---------------------------------
    day_friction_drift: float = 0.1
    """Relative std of a day's factor on the lab's table friction, the same factor over the
    whole table (cleaned, humid, dusty; the field's pattern stays); the tracker is also
    recalibrated each day (a new bias of `obs_bias`'s std)."""
    day_speed_drift: float = 0.03
    """Relative std of a day's factor on the lab's speed gain (a warm or cold arm, another
    payload setting)."""

    def __post_init__(self) -> None:
        for name in ("timestep", "link_width", "link_height"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)!r}")
        for name in (
            "com_offset", "length_error", "obs_noise", "action_noise", "contact_bias",
            "friction_variation", "torsional_friction", "day_friction_drift", "day_speed_drift",
        ):  # fmt: skip
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        if self.solver not in SOLVERS:
            raise ValueError(f"solver must be one of {list(SOLVERS)}, got {self.solver!r}")
        if self.cone not in CONES:
            raise ValueError(f"cone must be one of {list(CONES)}, got {self.cone!r}")
        if self.solver_iterations < 1 or self.friction_waves < 1:
            raise ValueError("solver_iterations and friction_waves must be >= 1")
        lo, hi = self.friction_range
        if not 0 < lo <= hi:
            raise ValueError(f"friction_range must be 0 < low <= high, got {self.friction_range}")

    def physics(self, base: PhysicsConfig) -> PhysicsConfig:
        """The training world's physics with this world's geometry, step and friction."""
        return replace(
            base,
            timestep=self.timestep,
            link_width=self.link_width,
            link_height=self.link_height,
            joint_gap=base.joint_gap - base.link_width + self.link_width,
            friction_range=tuple(self.friction_range),
        )


TRAINING_KNOBS: dict[str, Any] = {
    # MuJoCo's defaults, which the training scene keeps (`masspush.sim.chain.build_spec`).
    "timestep": PhysicsConfig.timestep,
    "solver": "Newton",
    "solver_iterations": 100,
    "cone": "elliptic",
    "contact_solref": (0.02, 1.0),
    "contact_solimp": (0.9, 0.95, 0.001),
    "torsional_friction": 0.0,
    # The training world's own configuration (`masspush.config`).
    "friction_range": PhysicsConfig.friction_range,
    "friction_variation": 0.0,
    "link_width": PhysicsConfig.link_width,
    "link_height": PhysicsConfig.link_height,
    "com_offset": 0.0,
    "length_error": 0.0,
    "obs_noise": EnvConfig.obs_noise,
    "obs_bias": (0.0, 0.0),
    "action_noise": EnvConfig.action_noise,
    "speed_gain": (1.0, 1.0),
    "contact_bias": 0.0,
}
"""`TargetWorld`'s knobs at the training world's values: with them, only condim 4 and the
links' contact priority are left of the target world's differences."""


def scaled_world(severity: float, world: TargetWorld | None = None) -> TargetWorld:
    """`world` (default: the target world) with every difference from the training world
    scaled by `severity` in [0, 1]: each number moves from its training value (0) to the
    world's (1); the solver and the cones, which cannot be scaled, are the world's for any
    severity above 0. How close to the simulation must a lab be for an accuracy?"""
    if not 0 <= severity <= 1:
        raise ValueError(f"severity must be in [0, 1], got {severity!r}")
    world = world or TargetWorld()
    if severity == 1:  # exactly the world, not a rounding away from it
        return world

    def between(train: Any, target: Any) -> Any:
        if isinstance(target, str):
            return target if severity > 0 else train
        if isinstance(target, tuple):
            return tuple(between(a, b) for a, b in zip(train, target, strict=True))
        value = train + severity * (target - train)
        return round(value) if isinstance(target, int) else float(value)

    return replace(world, **{k: between(v, getattr(world, k)) for k, v in TRAINING_KNOBS.items()})


@dataclass(frozen=True)
class WorldRanges:
    """A distribution over target worlds, for domain randomisation (`masspush.real.randomisation`):
    each episode draws its own `TargetWorld`. Every range holds both the training world's
    value and the target world's, with room on either side, as a lab would pick ranges wide
    enough for what it does not know about its own setup [ours, each]."""

    timesteps: tuple[float, ...] = (0.0005, 0.001)
    """Physics step ~ one of these, s."""
    solvers: tuple[str, ...] = ("Newton", "CG", "PGS")
    solver_iterations: tuple[int, int] = (10, 100)
    cones: tuple[str, ...] = ("elliptic", "pyramidal")
    solref_time: Range = (0.005, 0.03)
    """Contact time constant ~ U(range), s."""
    solref_damping: Range = (0.6, 1.2)
    solimp_low: Range = (0.7, 0.95)
    """The impedance's first value ~ U(range); its second stays 0.95."""
    solimp_width: Range = (0.0005, 0.003)
    torsional_friction: Range = (0.0, 0.02)
    friction_range: Range = (0.3, 1.2)
    friction_variation: Range = (0.0, 0.25)
    link_width: Range = (0.035, 0.05)
    link_height: Range = (0.025, 0.04)
    com_offset: float = 0.01
    length_error: float = 0.005
    obs_noise: Range = (0.005, 0.02)
    obs_bias: tuple[float, float] = (0.008, 0.03)
    """The per-episode tracking bias's std ~ U(0, this): position (m), angles (rad)."""
    action_noise: Range = (0.005, 0.03)
    speed_gain: Range = (0.8, 1.2)
    """The per-episode gain on the push speed ~ U(range)."""
    contact_bias: float = 0.04
    """The per-episode contact bias's std ~ U(0, this)."""

    def __post_init__(self) -> None:
        for name in ("solvers", "cones", "timesteps"):
            if not getattr(self, name):
                raise ValueError(f"{name} must not be empty")
        for solver in self.solvers:
            if solver not in SOLVERS:
                raise ValueError(f"unknown solver {solver!r}; known: {list(SOLVERS)}")
        for cone in self.cones:
            if cone not in CONES:
                raise ValueError(f"unknown cone {cone!r}; known: {list(CONES)}")
        for name in (
            "solver_iterations", "solref_time", "solref_damping", "solimp_low", "solimp_width",
            "torsional_friction", "friction_range", "friction_variation", "link_width",
            "link_height", "obs_noise", "action_noise", "speed_gain",
        ):  # fmt: skip
            lo, hi = getattr(self, name)
            if not 0 <= lo <= hi:
                raise ValueError(f"{name} must be 0 <= low <= high, got {(lo, hi)}")

    def sample(self, rng: np.random.Generator) -> TargetWorld:
        """One world of the distribution."""

        def u(r: tuple[float, float]) -> float:
            return float(rng.uniform(*r))

        return TargetWorld(
            timestep=float(rng.choice(self.timesteps)),
            solver=str(rng.choice(self.solvers)),
            solver_iterations=int(rng.integers(self.solver_iterations[0],
                                               self.solver_iterations[1] + 1)),
            cone=str(rng.choice(self.cones)),
            contact_solref=(u(self.solref_time), u(self.solref_damping)),
            contact_solimp=(u(self.solimp_low), 0.95, u(self.solimp_width)),
            torsional_friction=u(self.torsional_friction),
            friction_range=tuple(self.friction_range),
            friction_variation=u(self.friction_variation),
            link_width=u(self.link_width),
            link_height=u(self.link_height),
            com_offset=self.com_offset,
            length_error=self.length_error,
            obs_noise=u(self.obs_noise),
            obs_bias=(u((0, self.obs_bias[0])), u((0, self.obs_bias[1]))),
            action_noise=u(self.action_noise),
            speed_gain=tuple(self.speed_gain),
            contact_bias=u((0, self.contact_bias)),
        )  # fmt: skip


class FrictionField:
    """Table friction over the plane: mu(p) = mu0 (1 + variation * sum of planar waves),
    normalised so that its std over the table is `variation`, kept within mu0 * [0.5, 1.5]."""

    def __init__(self, mean: float, world: TargetWorld, rng: np.random.Generator):
        k = world.friction_waves
        wavelength = rng.uniform(*world.friction_wavelength, size=k)
        heading = rng.uniform(-math.pi, math.pi, size=k)
        self.k = (2 * math.pi / wavelength)[:, None] * np.stack(
            [np.cos(heading), np.sin(heading)], axis=1
        )
        self.phase = rng.uniform(-math.pi, math.pi, size=k)
        self.mean = mean
        self.amplitude = world.friction_variation * math.sqrt(2.0 / k)

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        """Friction at each of the (m, 2) points."""
        waves = np.cos(np.asarray(xy) @ self.k.T + self.phase).sum(axis=-1)
        return self.mean * np.clip(1.0 + self.amplitude * waves, 0.5, 1.5)


def tracker_bias(world: TargetWorld, rng: np.random.Generator, n_links: int) -> np.ndarray:
    """A calibration's bias on the tracked pose (x, y, then the n_links angles), drawn with
    `world.obs_bias`'s stds."""
    return np.concatenate(
        [rng.normal(0, world.obs_bias[0], 2), rng.normal(0, world.obs_bias[1], n_links)]
    )


class Lab:
    """One lab's constants in `world`, drawn once from `seed` [ours]: what stays the same
    from one episode to the next in a real lab (see the module's docstring).

    `day` 0 is the day its models were calibrated (every lab figure before 2026-12-07 was
    measured on it); another day draws that day's drift from `world` (`day_*`) around day 0
    once, the same for every episode that day: the table's friction and the robot's speed
    gain scaled, the tracker recalibrated. The objects, their lengths and the tool are the
    lab's own on every day."""

    def __init__(self, seed: int, world: TargetWorld, physics: PhysicsConfig, day: int = 0):
        self.seed = seed
        self.day = day
        rng = np.random.default_rng([seed, 11])
        n = physics.n_links
        self.friction = float(rng.uniform(*world.friction_range))
        self.field = FrictionField(self.friction, world, rng)
        self.lengths = rng.uniform(*physics.length_range, size=n)
        self.told_lengths = self.lengths + rng.normal(0, world.length_error, n)
        self.bias = tracker_bias(world, rng, n)
        self.gain = float(rng.uniform(*world.speed_gain))
        self.contact = float(rng.normal(0, world.contact_bias))
        self.com_offset = world.com_offset
        self.friction_factor = self.speed_factor = 1.0
        if day:  # drawn apart from day 0's draws, which stay as they were
            rng = np.random.default_rng([seed, 19, day])
            self.friction_factor = float(np.clip(rng.normal(1, world.day_friction_drift), 0.5, 1.5))
            self.speed_factor = float(np.clip(rng.normal(1, world.day_speed_drift), 0.5, 1.5))
            self.friction *= self.friction_factor
            self.field.mean = self.friction
            self.gain *= self.speed_factor
            self.bias = tracker_bias(world, rng, n)

    def com_offsets(self, masses: np.ndarray) -> np.ndarray:
        """Each link's centre-of-mass offset along it, m, for the object of these masses
        (the same object, so the same offsets, whenever they recur)."""
        milligrams = np.round(np.asarray(masses, dtype=float) * 1e6).astype(np.int64)
        rng = np.random.default_rng([self.seed, 13, *milligrams.tolist()])
        return rng.uniform(-self.com_offset, self.com_offset, size=len(milligrams))


class TargetWorldRobot:
    """The target world as a robot: each `start` places a new chain of the setting (masses
    pinned if given) in a world that differs from training (`TargetWorld`), or in a world
    drawn afresh from `WorldRanges` for each episode. With `lab` (a seed), the world's
    per-episode constants are that one lab's (`Lab`) on its day `day`; the episodes' other
    draws are made as without it, so the same seed places the chain the same way in all."""

    def __init__(
        self,
        setting: str | Setting,
        world: TargetWorld | WorldRanges | None = None,
        pusher: str | None = None,
        seed: int = 0,
        masses: tuple[float, ...] | None = None,
        lab: int | None = None,
        day: int = 0,
    ):
        from masspush.settings import get_setting

        self.setting = get_setting(setting) if isinstance(setting, str) else setting
        # A `WorldRanges` draws a new world at every start (domain randomisation).
        self.ranges = world if isinstance(world, WorldRanges) else None
        self.world = TargetWorld() if world is None or self.ranges else world
        self.physics = self.world.physics(self.setting.physics())
        self.pusher_name = pusher or self.setting.pusher
        # The robot's software knows the setting's chain, not the lab's true one.
        self.governor = reach_governor(self.pusher_name, self.setting.physics())
        """The stationary robot's speed governor (`run_estimation` applies it), or None."""
        self.n_links = self.setting.n_links
        self.seed = seed
        self.pinned = {} if masses is None else {"masses": list(masses)}
        if lab is not None and self.ranges is not None:
            raise ValueError("a lab is one world; it cannot be drawn from WorldRanges")
        if day and lab is None:
            raise ValueError("a day is one lab's; pass lab too")
        self.lab = None if lab is None else Lab(lab, self.world, self.physics, day)
        if self.lab is not None:
            self.pinned |= {"friction": self.lab.friction, "lengths": self.lab.lengths}
        self.truth: dict[str, Any] = {}
        self.sim: ChainSim | None = None

    def start(self) -> RestPose:
        while True:
            self.rng = np.random.default_rng([self.seed, 7])
            self.seed += 1
            if self.ranges is not None:
                self.world = self.ranges.sample(self.rng)
                self.physics = self.world.physics(self.setting.physics())
            # The target world differs from training on purpose: a lab's table and
            # chains need not lie in the setting's ranges.
            chain = sample_chain(self.physics, self.rng, self.pinned, allow_out_of_range=True)
            self.field = FrictionField(chain.friction, self.world, self.rng)
            self._chain = chain
            if self.lab is not None:
                self.field = self.lab.field
            self._boxes: list[int] = []
            self.sim = ChainSim(chain, self.physics, make_pusher(self.pusher_name), self._adjust)
            if self.sim.initial_failure is None:
                break
        w, n = self.world, self.n_links
        self.sim.on_step = self._update_friction
        self.bias = tracker_bias(w, self.rng, n)
        self.gain = self.rng.uniform(*w.speed_gain)
        self.contact = self.rng.normal(0, w.contact_bias)
        told = chain.lengths + self.rng.normal(0, w.length_error, n)
        if self.lab is not None:
            lab = self.lab
            self.bias, self.gain, self.contact, told = (
                lab.bias, lab.gain, lab.contact, lab.told_lengths
            )  # fmt: skip
        self.truth = {
            "masses": np.array(chain.masses),
            "mass_distribution": chain.mass_distribution,
            "friction": chain.friction,
            "config": self.sim.config(),
            "lengths": np.array(chain.lengths),
        }
        return RestPose(self.observe(), told.astype(np.float32))

    def push(self, action: np.ndarray) -> PushReport:
        assert self.sim is not None, "start() first"
        a = np.asarray(action, np.float64)
        executed = np.array([a[0] * self.gain, a[1] + self.contact])
        executed = np.clip(executed + self.rng.normal(0, self.world.action_noise, 2), -1, 1)
        outcome = self.sim.push(executed)
        details = {"executed": executed, "settle_time": outcome.settle_time}
        details["config"] = self.sim.config()
        speed = outcome.executed_speed
        if outcome.failure is not None:
            return PushReport(None, outcome.failure, details, speed)
        return PushReport(self.observe(), None, details, speed)

    def observe(self) -> np.ndarray:
        """The chain's pose as this lab's tracker reports it now (its bias and noise), wherever
        the last push left it (after a failed push too)."""
        assert self.sim is not None
        config = self.sim.config() + self.bias
        config = config + self.rng.normal(0, self.world.obs_noise, config.shape)
        config[2] = wrap_angle(config[2])
        return config.astype(np.float32)

    def close(self) -> None:
        self.sim = None

    # --- the world's differences --------------------------------------------------------
    def _adjust(self, model: mujoco.MjModel) -> None:
        w = self.world
        model.opt.cone = CONES[w.cone]
        model.opt.solver = SOLVERS[w.solver]
        model.opt.iterations = w.solver_iterations
        boxes = [model.geom(f"box{i}").id for i in range(self.n_links)]
        # The links outrank the table and the tool, so their friction (the field's value
        # where each lies) and contact parameters govern all their contacts; link-link
        # contacts take the larger friction of the two.
        for g in boxes:
            model.geom_priority[g] = 2
            model.geom_condim[g] = 4
            model.geom_friction[g] = [self.field.mean, w.torsional_friction, 0.0001]
            model.geom_solref[g] = w.contact_solref
            model.geom_solimp[g, :3] = w.contact_solimp
        offsets = self.rng.uniform(-w.com_offset, w.com_offset, size=len(boxes))
        if self.lab is not None:
            offsets = self.lab.com_offsets(self._chain.masses)
        for g, offset in zip(boxes, offsets, strict=True):
            model.body_ipos[model.geom_bodyid[g], 0] += offset
        self._boxes = boxes

    def _update_friction(self) -> None:
        sim = self.sim
        assert sim is not None
        xy = sim.data.geom_xpos[self._boxes, :2]
        sim.model.geom_friction[self._boxes, 0] = self.field(xy)
