"""The articulated chain on the table: its parameters, sampling, MuJoCo model and kinematics.

The chain lies flat on the table. Link 0 is the root (a free joint at its centre); link i
hangs off link i-1 by a hinge about the vertical axis in the middle of the gap between
their boxes. A chain *configuration* is (root x, root y, root yaw, joint angles), the
quantity the robot observes at rest.
"""

from __future__ import annotations

import copy
import math
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from masspush.config import PhysicsConfig, check_plausible

#: Option keys accepted by `sample_chain` to pin parameters instead of sampling them.
PIN_KEYS = ("masses", "friction", "lengths", "joint_angles", "root_pose")

# Contact bits: the table touches links only; the pusher touches links only.
_LINK_BITS = 1  # contype and conaffinity of links: links collide with each other
_TABLE_BITS = 2
_PUSHER_BITS = 4


@dataclass(frozen=True)
class ChainParams:
    """One concrete chain: its unknowns (masses, friction) and its known geometry and pose."""

    masses: tuple[float, ...]
    """Mass of each link, kg."""
    friction: float
    """Table friction coefficient."""
    lengths: tuple[float, ...]
    """Length of each link, m."""
    joint_angles: tuple[float, ...]
    """Initial hinge angles, rad (n - 1 of them)."""
    root_pose: tuple[float, float, float]
    """Initial root link centre x, y (m) and yaw (rad)."""

    def __post_init__(self) -> None:
        n = len(self.masses)
        if n < 2:
            raise ValueError(f"a chain needs at least 2 links, got masses {self.masses!r}")
        _check_vector("masses", self.masses, n, positive=True)
        _check_vector("lengths", self.lengths, n, positive=True)
        _check_vector("joint_angles", self.joint_angles, n - 1)
        _check_vector("root_pose", self.root_pose, 3)
        if not (math.isfinite(self.friction) and self.friction > 0):
            raise ValueError(f"friction must be a positive finite number, got {self.friction!r}")

    @classmethod
    def at_pose(
        cls, masses: Sequence[float], friction: float, lengths: Sequence[float],
        pose: Sequence[float],
    ) -> ChainParams:  # fmt: skip
        """The chain resting at `pose`, a configuration as observed: root x, y, yaw, then
        the hinge angles."""
        pose = [float(v) for v in pose]
        return cls(
            tuple(float(m) for m in masses), float(friction), tuple(float(v) for v in lengths),
            tuple(pose[3:]), (pose[0], pose[1], pose[2]),
        )  # fmt: skip

    @property
    def n_links(self) -> int:
        return len(self.masses)

    @property
    def mass_distribution(self) -> np.ndarray:
        """Masses divided by the total mass: what the estimators predict."""
        m = np.asarray(self.masses, dtype=float)
        return m / m.sum()

    @property
    def initial_config(self) -> np.ndarray:
        """The configuration (x, y, yaw, joint angles) the chain starts in."""
        return np.array([*self.root_pose, *self.joint_angles], dtype=float)


def _check_vector(name: str, value: Any, length: int, positive: bool = False) -> None:
    if isinstance(value, (str, bytes)) or any(
        isinstance(v, (bool, str, bytes, np.bool_)) for v in np.ravel(np.asarray(value, object))
    ):  # numpy would read True as 1.0 and "0.5" as 0.5
        raise ValueError(f"{name} must be {length} numbers, got {value!r}")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {length} numbers, got {value!r}") from None
    if arr.shape != (length,):
        raise ValueError(f"{name} must have {length} values, got {value!r}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    if positive and np.any(arr <= 0):
        raise ValueError(f"{name} must be positive, got {value!r}")


_RANGES = {"masses": "mass_range", "friction": "friction_range", "lengths": "length_range"}


def _check_pinned(physics: PhysicsConfig, key: str, value: Any, allow_out_of_range: bool) -> None:
    values = np.atleast_1d(np.asarray(value, dtype=float)).tolist()
    if key == "root_pose":
        check_plausible("root_xy", values[:2])
    if key not in _RANGES:
        return
    check_plausible(key, values)
    lo, hi = getattr(physics, _RANGES[key])
    slack = 1e-6 * max(abs(lo), abs(hi))  # recordings round to 6 digits
    if not allow_out_of_range and not all(lo - slack <= v <= hi + slack for v in values):
        raise ValueError(
            f"pinned {key} {values} outside the setting's {_RANGES[key]} [{lo:g}, {hi:g}]; "
            "pass allow_out_of_range to simulate them anyway"
        )


def sample_chain(
    physics: PhysicsConfig,
    rng: np.random.Generator,
    pinned: Mapping[str, Any] | None = None,
    allow_out_of_range: bool = False,
) -> ChainParams:
    """Draw a chain from the setting's distributions; `pinned` fixes any of PIN_KEYS.

    Every draw is made whether or not it is pinned, so pinning one parameter leaves the
    others exactly as the same seed would have drawn them. Pinned masses, friction and
    lengths must lie in the setting's ranges (a model trained on them knows nothing
    outside) unless `allow_out_of_range`; values no table holds (`config.PLAUSIBLE`) are
    refused always.
    """
    pinned = dict(pinned or {})
    unknown = sorted(set(pinned) - set(PIN_KEYS))
    if unknown:
        raise ValueError(f"unknown option(s) {unknown}; valid options: {list(PIN_KEYS)}")
    n = physics.n_links
    drawn = {
        "masses": rng.uniform(*physics.mass_range, size=n),
        "friction": float(rng.uniform(*physics.friction_range)),
        "lengths": rng.uniform(*physics.length_range, size=n),
        "joint_angles": rng.uniform(
            -physics.init_joint_range, physics.init_joint_range, size=n - 1
        ),
        "root_pose": np.array(
            [
                rng.uniform(-physics.root_xy_range, physics.root_xy_range),
                rng.uniform(-physics.root_xy_range, physics.root_xy_range),
                rng.uniform(*physics.root_yaw_range),
            ]
        ),
    }
    yaw = drawn["root_pose"][2]
    if not -math.pi <= yaw < math.pi:  # a range about +-pi: seen wrapped, drawn wrapped
        drawn["root_pose"][2] = wrap_angle(yaw)
    for key, value in pinned.items():
        expected = {"masses": n, "lengths": n, "joint_angles": n - 1, "root_pose": 3}.get(key)
        if key == "friction":
            if isinstance(value, (bool, str, bytes, np.bool_)):
                raise ValueError(f"friction must be a number, got {value!r}")
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"friction must be a number, got {value!r}") from None
        else:
            _check_vector(key, value, expected, positive=key in ("masses", "lengths"))
        _check_pinned(physics, key, value, allow_out_of_range)
        drawn[key] = value
    angles = np.asarray(drawn["joint_angles"], dtype=float)
    if np.any(np.abs(angles) > physics.joint_limit):
        raise ValueError(
            f"joint_angles {angles.tolist()} exceed the joint limit +-{physics.joint_limit} rad"
        )
    return ChainParams(
        masses=tuple(float(v) for v in drawn["masses"]),
        friction=float(drawn["friction"]),
        lengths=tuple(float(v) for v in drawn["lengths"]),
        joint_angles=tuple(float(v) for v in angles),
        root_pose=tuple(float(v) for v in drawn["root_pose"]),
    )


def box_inertia(mass: float, size: Sequence[float]) -> list[float]:
    """Principal moments of a solid box with full edge lengths `size`."""
    a, b, c = size
    return [mass / 12 * (b * b + c * c), mass / 12 * (a * a + c * c), mass / 12 * (a * a + b * b)]


def build_spec(
    chain: ChainParams,
    physics: PhysicsConfig,
    add_pusher: Callable[[mujoco.MjSpec, PhysicsConfig], None] | None = None,
) -> mujoco.MjSpec:
    """The scene as an MjSpec: table, chain (in its initial pose) and, optionally, a pusher."""
    w, h, gap = physics.link_width, physics.link_height, physics.joint_gap
    spec = mujoco.MjSpec()
    spec.modelname = f"chain{chain.n_links}"
    spec.compiler.degree = False  # MjSpec defaults to degrees: joint ranges here are radians
    spec.memory = physics.arena_bytes
    opt = spec.option
    opt.timestep = physics.timestep
    # Stiff velocity servos need implicit damping; elliptic cones give isotropic Coulomb
    # friction, which the sliding-distance test checks against v^2 / (2 mu g) [notes].
    opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    opt.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    # MuJoCo skips parent-child contacts by default; neighbours must collide [notes].
    # Without auto-reset a diverged simulation keeps its NaNs, so we report, not hide, it.
    opt.disableflags |= (
        mujoco.mjtDisableBit.mjDSBL_FILTERPARENT | mujoco.mjtDisableBit.mjDSBL_AUTORESET
    )

    # Parked pushers sit ~1 km away; without fixed statistics the renderer's clipping
    # planes, which scale with the model's extent, would clip the whole scene.
    spec.stat.extent = 2.0
    spec.stat.center = [0.0, 0.0, 0.0]
    spec.worldbody.add_light(
        name="sun", pos=[0, 0, 3], dir=[0, 0, -1], type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
    )
    # The table's priority makes its mu govern link-table contacts exactly.
    spec.worldbody.add_geom(
        name="table",
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[0, 0, 0.05],
        friction=[chain.friction, 0.005, 0.0001],
        priority=1,
        contype=_TABLE_BITS,
        conaffinity=_LINK_BITS,
        rgba=[0.85, 0.85, 0.8, 1],
    )
    x, y, yaw = chain.root_pose
    parent = spec.worldbody
    for i, (length, mass) in enumerate(zip(chain.lengths, chain.masses, strict=True)):
        if i == 0:
            body = parent.add_body(name="link0", pos=[x, y, h / 2], quat=_yaw_quat(yaw))
            body.add_freejoint(name="root")
            centre = [0.0, 0.0, 0.0]
        else:
            # Child frame at the hinge, in the middle of the gap after the parent's box.
            # Built straight: the initial joint angles go into a keyframe (`compile_scene`).
            # The root's frame is at its centre; every other link's frame is at its hinge.
            to_hinge = chain.lengths[i - 1] / 2 + gap / 2 if i == 1 else chain.lengths[i - 1] + gap
            body = parent.add_body(name=f"link{i}", pos=[to_hinge, 0, 0])
            body.add_joint(
                name=f"joint{i}",
                type=mujoco.mjtJoint.mjJNT_HINGE,
                axis=[0, 0, 1],
                range=[-physics.joint_limit, physics.joint_limit],
                limited=mujoco.mjtLimited.mjLIMITED_TRUE,
            )
            centre = [gap / 2 + length / 2, 0.0, 0.0]
            # A short cylinder marks the hinge; visual only, as it is rotationally symmetric.
            body.add_geom(
                name=f"hinge{i}",
                type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                size=[0.4 * w, h / 2, 0],
                contype=0,
                conaffinity=0,
                mass=0,
                rgba=[0.3, 0.3, 0.3, 1],
            )
        body.explicitinertial = True
        body.mass = mass
        body.ipos = centre
        body.inertia = box_inertia(mass, (length, w, h))
        body.add_geom(
            name=f"box{i}",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[length / 2, w / 2, h / 2],
            pos=centre,
            friction=[physics.link_friction, 0.005, 0.0001],
            condim=3,
            contype=_LINK_BITS,
            conaffinity=_LINK_BITS | _TABLE_BITS | _PUSHER_BITS,
            rgba=_link_colour(i),
            mass=0,
        )
        parent = body
    if add_pusher is not None:
        add_pusher(spec, physics)
    return spec


def compile_scene(
    chain: ChainParams,
    physics: PhysicsConfig,
    add_pusher: Callable[[mujoco.MjSpec, PhysicsConfig], None] | None = None,
    reuse: str | None = None,
) -> mujoco.MjModel:
    """Compile the scene; keyframe INITIAL_KEY holds the chain's initial configuration.

    MuJoCo measures hinge angles from qpos0, so qpos0 stays straight (angle 0) and the
    initial angles live in a keyframe; `mj_resetDataKeyframe` / `Batch.reset` load it.

    `reuse` names the scene (the pusher's name, say): the first chain's scene under that
    name and `physics` is compiled and kept, and every later one is a copy of it with this
    chain's masses, inertias, lengths, friction and pose written in (`write_chain`): the
    same model as a compile's to the last bit (tested), in a fraction of the time.
    """
    if reuse is not None:
        template = _TEMPLATES.get((reuse, physics))
        if template is None:
            if len(_TEMPLATES) >= 32:
                _TEMPLATES.pop(next(iter(_TEMPLATES)))
            model = compile_scene(chain, physics, add_pusher)
            template = _TEMPLATES[reuse, physics] = (model, mujoco.MjData(model))
        model = copy.copy(template[0])
        with _SCRATCH_LOCK:
            write_chain(model, chain, physics, template[1])
        return model
    spec = build_spec(chain, physics, add_pusher)
    spec.add_key(name="initial")
    model = spec.compile()
    layout = ChainLayout.of(model, chain.n_links)
    model.key_qpos[INITIAL_KEY] = model.qpos0
    model.key_qpos[INITIAL_KEY, layout.joint_qpos] = chain.joint_angles
    return model


_TEMPLATES: dict[tuple[str, PhysicsConfig], tuple[mujoco.MjModel, mujoco.MjData]] = {}
"""This process's compiled scenes that `compile_scene(reuse=...)` copies, by name and
physics, each with a scratch `MjData` for `write_chain` (one costs more than the copy)."""
_SCRATCH_LOCK = threading.Lock()


def write_chain(
    model: mujoco.MjModel, chain: ChainParams, physics: PhysicsConfig,
    scratch: mujoco.MjData | None = None,
) -> None:  # fmt: skip
    """Make a compiled scene of `physics` the scene of `chain`, exactly as `compile_scene`
    would compile it: what `build_spec` puts into the spec, then `mj_setConst` for what
    depends on it and, as the compiler does, the model's statistics (which the solver's
    tolerance scales with). `scratch`: an `MjData` of the scene to compute in."""
    w, h, gap = physics.link_width, physics.link_height, physics.joint_gap
    x, y, yaw = chain.root_pose
    model.geom_friction[model.geom("table").id, 0] = chain.friction
    for i, (length, mass) in enumerate(zip(chain.lengths, chain.masses, strict=True)):
        body, geom = model.body(f"link{i}").id, model.geom(f"box{i}").id
        if i == 0:
            model.body_pos[body] = [x, y, h / 2]
            model.body_quat[body] = _yaw_quat(yaw)  # unit to 1e-16: the compiler keeps it
            centre = [0.0, 0.0, 0.0]
        else:
            to_hinge = chain.lengths[i - 1] / 2 + gap / 2 if i == 1 else chain.lengths[i - 1] + gap
            model.body_pos[body] = [to_hinge, 0.0, 0.0]
            centre = [gap / 2 + length / 2, 0.0, 0.0]
        model.body_mass[body] = mass
        model.body_ipos[body] = centre
        model.body_inertia[body] = box_inertia(mass, (length, w, h))
        model.geom_size[geom] = [length / 2, w / 2, h / 2]
        model.geom_pos[geom] = centre
    layout = ChainLayout.of(model, chain.n_links)
    root = model.body("link0").id
    r = layout.root_qpos
    model.qpos0[r : r + 3] = model.body_pos[root]
    model.qpos0[r + 3 : r + 7] = model.body_quat[root]
    model.qpos_spring[r : r + 7] = model.qpos0[r : r + 7]
    model.key_qpos[INITIAL_KEY] = model.qpos0
    model.key_qpos[INITIAL_KEY, layout.joint_qpos] = chain.joint_angles
    data = mujoco.MjData(model) if scratch is None else scratch
    mujoco.mj_setConst(model, data)
    _set_statistics(model, data)


def _set_statistics(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """`model.stat`'s mean size, mass and inertia as MuJoCo's compiler computes them (its
    `setStat`, in qpos0, in the same order of operations); the extent and centre are fixed
    by `build_spec`."""
    data.qpos[:] = model.qpos0
    mujoco.mj_forward(model, data)

    def dist(a: np.ndarray, b: np.ndarray) -> float:
        d0, d1, d2 = float(a[0] - b[0]), float(a[1] - b[1]), float(a[2] - b[2])
        return math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)

    size = [0.0] * model.nbody
    for j in range(model.njnt):
        body = int(model.jnt_bodyid[j])
        size[body] = max(size[body], dist(data.xipos[body], data.xanchor[j]))
        parent = int(model.body_parentid[body])
        size[parent] = max(size[parent], dist(data.xipos[parent], data.xanchor[j]))
    size[0] = 0.0
    for body in range(1, model.nbody):
        first = int(model.body_geomadr[body])
        for g in range(first, first + int(model.body_geomnum[body])):
            if model.geom_rbound[g] > 0:
                reach = float(model.geom_rbound[g]) + dist(data.xipos[body], data.geom_xpos[g])
                size[body] = max(size[body], reach)
    n = model.nbody - 1
    meansize = meanmass = 0.0
    for body in range(1, model.nbody):
        meansize += max(size[body], 1e-5) / n
    for body in range(1, model.nbody):
        meanmass += float(model.body_mass[body])
    meaninertia = 0.0
    diagonal = model.M_rowadr + model.M_rownnz - 1
    for i in range(model.nv):
        meaninertia += float(data.M[diagonal[i]])
    model.stat.meansize = meansize
    model.stat.meanmass = meanmass / n
    model.stat.meaninertia = meaninertia / model.nv


def _yaw_quat(yaw: float) -> list[float]:
    return [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]


def _link_colour(i: int) -> list[float]:
    palette = [(0.12, 0.47, 0.71), (1.0, 0.5, 0.05), (0.17, 0.63, 0.17), (0.84, 0.15, 0.16)]
    return [*palette[i % len(palette)], 1.0]


INITIAL_KEY = 0
"""Index of the keyframe that holds a compiled scene's initial configuration."""

PUSHER_CONTACT_BITS = (_PUSHER_BITS, _LINK_BITS)
"""(contype, conaffinity) for pusher geoms: they touch the chain, never the table."""


@dataclass(frozen=True)
class ChainLayout:
    """Where a chain's state lives in a compiled model's qpos / qvel (looked up once)."""

    n_links: int
    root_qpos: int
    root_dof: int
    joint_qpos: np.ndarray
    nq: int
    nv: int

    @classmethod
    def of(cls, model: mujoco.MjModel, n_links: int) -> ChainLayout:
        root = model.joint("root")
        joints = [model.joint(f"joint{i}") for i in range(1, n_links)]
        jq = np.array([int(j.qposadr[0]) for j in joints], dtype=int)
        # The chain's joints come first in the model, so its dofs are 0 .. 6 + n - 1.
        return cls(
            n_links,
            int(root.qposadr[0]),
            int(root.dofadr[0]),
            jq,
            nq=7 + n_links - 1,
            nv=6 + n_links - 1,
        )

    def config(self, qpos: np.ndarray) -> np.ndarray:
        """(…, nq_model) qpos -> (…, 3 + n - 1) configuration (x, y, yaw, joint angles)."""
        r = self.root_qpos
        quat = qpos[..., r + 3 : r + 7]
        return np.concatenate(
            [qpos[..., r : r + 2], quat_yaw(quat)[..., None], qpos[..., self.joint_qpos]], axis=-1
        )

    def set_config(self, qpos: np.ndarray, config: np.ndarray, height: float) -> None:
        """Write a flat configuration into qpos (root at `height`, upright)."""
        r = self.root_qpos
        qpos[r : r + 3] = [config[0], config[1], height]
        qpos[r + 3 : r + 7] = _yaw_quat(float(config[2]))
        qpos[self.joint_qpos] = config[3:]


def quat_yaw(quat: np.ndarray) -> np.ndarray:
    """Yaw (rotation about z) of (…, 4) quaternions (w, x, y, z), in (-pi, pi]."""
    w, x, y, z = (quat[..., k] for k in range(4))
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def wrap_angle(a: np.ndarray | float) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def link_poses(
    config: np.ndarray, lengths: Sequence[float], joint_gap: float
) -> tuple[np.ndarray, np.ndarray]:
    """Planar forward kinematics: (..., n, 2) link box centres and (..., n) headings for
    (..., d) configurations (one configuration: (n, 2) and (n,))."""
    config = np.asarray(config, dtype=float)
    n = len(lengths)
    headings = config[..., 2:3] + np.concatenate(
        [np.zeros((*config.shape[:-1], 1)), np.cumsum(config[..., 3 : 3 + n - 1], axis=-1)], -1
    )
    units = np.stack([np.cos(headings), np.sin(headings)], -1)
    centres = np.zeros((*config.shape[:-1], n, 2))
    centres[..., 0, :] = config[..., :2]
    for i in range(1, n):
        joint = centres[..., i - 1, :] + (lengths[i - 1] / 2 + joint_gap / 2) * units[..., i - 1, :]
        centres[..., i, :] = joint + (joint_gap / 2 + lengths[i] / 2) * units[..., i, :]
    return centres, headings
