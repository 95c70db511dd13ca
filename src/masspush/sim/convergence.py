"""How trustworthy is a simulated rest pose? Time-step convergence and chaotic sensitivity.

Two measurements over the same random single pushes, grouped by push speed:
- convergence: the rest pose at each time step against a 4x finer reference step;
- sensitivity: the rest pose after perturbing the initial joint angles by 1e-6 rad, at the
  default step. Where this is large the physics itself is chaotic, and no time step can
  make single rest poses reproducible, only their distribution.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike
from tqdm import tqdm

from masspush.config import PhysicsConfig
from masspush.sim.chain import ChainParams, sample_chain, wrap_angle
from masspush.sim.simulate import ChainSim

SPEED_BINS = ((0.0, 0.25), (0.25, 0.5), (0.5, 0.75), (0.75, 1.0))
"""Bins of |a1|: push speeds 0-1.25, 1.25-2.5, 2.5-3.75, 3.75-5 m/s."""


@dataclass(frozen=True)
class Deviation:
    """Median and 90th percentile of rest-pose differences in one speed bin."""

    label: str
    speed_bin: tuple[float, float]
    pushes: int
    position_median_mm: float
    position_p90_mm: float
    angle_median_rad: float
    angle_p90_rad: float


def _rest_pose(chain: ChainParams, physics: PhysicsConfig, action: np.ndarray) -> np.ndarray | None:
    sim = ChainSim(chain, physics)
    outcome = sim.push(action)
    return None if outcome.failure else sim.config()


def _summarise(label: str, speeds: ArrayLike, diffs: ArrayLike) -> list[Deviation]:
    rows = []
    speeds = np.asarray(speeds)
    diffs = np.asarray(diffs)
    for lo, hi in SPEED_BINS:
        sel = (speeds >= lo) & (speeds < hi) if hi < 1 else (speeds >= lo)
        if not sel.any():
            continue
        d = diffs[sel]
        pos = np.linalg.norm(d[:, :2], axis=1) * 1000
        ang = np.abs(d[:, 2:]).max(axis=1)
        rows.append(
            Deviation(
                label=label,
                speed_bin=(lo, hi),
                pushes=int(sel.sum()),
                position_median_mm=float(np.median(pos)),
                position_p90_mm=float(np.percentile(pos, 90)),
                angle_median_rad=float(np.median(ang)),
                angle_p90_rad=float(np.percentile(ang, 90)),
            )
        )
    return rows


def _difference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = a - b
    d[2:] = wrap_angle(d[2:])
    return d


def validate_physics(
    n_links: int = 2,
    mass_range: tuple[float, float] = (0.1, 1.0),
    pushes: int = 64,
    timesteps: tuple[float, ...] = (0.002, 0.001, 0.0005),
    seed: int = 0,
    progress: bool = True,
) -> list[Deviation]:
    """Rest-pose deviations for each time step (vs timesteps[-1] / 4) and under 1e-6 rad."""
    base = PhysicsConfig(n_links=n_links, mass_range=mass_range)
    rng = np.random.default_rng(seed)
    cases = [(sample_chain(base, rng), rng.uniform(-1, 1, size=2)) for _ in range(pushes)]
    reference_dt = timesteps[-1] / 4
    configs = {dt: replace(base, timestep=dt) for dt in (*timesteps, reference_dt)}
    speeds: list[float] = []
    diffs: dict[str, list[np.ndarray]] = {f"dt {dt * 1000:g} ms": [] for dt in timesteps}
    diffs["1e-6 rad perturbation"] = []
    kept_speeds: dict[str, list[float]] = {k: [] for k in diffs}
    for chain, action in tqdm(cases, desc="validating physics", disable=not progress):
        speed = abs(float(action[0]))
        speeds.append(speed)
        reference = _rest_pose(chain, configs[reference_dt], action)
        if reference is None:
            continue
        for dt in timesteps:
            pose = _rest_pose(chain, configs[dt], action)
            if pose is not None:
                diffs[f"dt {dt * 1000:g} ms"].append(_difference(pose, reference))
                kept_speeds[f"dt {dt * 1000:g} ms"].append(speed)
        nudged = replace(chain, joint_angles=tuple(a + 1e-6 for a in chain.joint_angles))
        default = _rest_pose(chain, base, action)
        pose = _rest_pose(nudged, base, action)
        if default is not None and pose is not None:
            diffs["1e-6 rad perturbation"].append(_difference(pose, default))
            kept_speeds["1e-6 rad perturbation"].append(speed)
    rows: list[Deviation] = []
    for label, d in diffs.items():
        if d:
            rows.extend(_summarise(label, kept_speeds[label], d))
    return rows


def format_table(rows: list[Deviation]) -> str:
    lines = [
        "| comparison | push speed (m/s) | pushes | position median / p90 (mm) "
        "| angle median / p90 (rad) |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        lo, hi = (5 * v for v in r.speed_bin)
        lines.append(
            f"| {r.label} | {lo:.2f}-{hi:.2f} | {r.pushes} "
            f"| {r.position_median_mm:.2f} / {r.position_p90_mm:.1f} "
            f"| {r.angle_median_rad:.4f} / {r.angle_p90_rad:.3f} |"
        )
    return "\n".join(lines)
