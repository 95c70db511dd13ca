"""A stationary robot's speed governor fitted to a lab's own pushes.

The shipped governor's slide bounds were measured in the training world
(`masspush.sim.workspace.Workspace.slide_*`); on another table the chain may slide further
(in the target world's lab 5 about twice as far per m/s) and the governor then lets it
leave. `fit_governor` measures the slides of a recording of random pushes made on your own
table and gives the governor with bounds fitted to them.
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np

from masspush.config import PhysicsConfig
from masspush.data.recording import read_recording
from masspush.sim.workspace import ReachGovernor, fit_slides, push_slides


def recording_pushes(path: str | os.PathLike) -> tuple[np.ndarray, ...]:
    """(before, after, actions, lengths) of every push in a recording that has a rest pose
    after it, one row per push (what `push_slides` reads)."""
    rows: tuple[list, ...] = ([], [], [], [])
    for episode in read_recording(path).episodes:
        obs, actions = np.asarray(episode["observations"]), np.asarray(episode["actions"])
        for t in range(len(obs) - 1):
            for row, value in zip(
                rows, (obs[t], obs[t + 1], actions[t], episode["lengths"]), strict=True
            ):
                row.append(value)
    return tuple(np.array(r, float) for r in rows)


def fit_governor(
    governor: ReachGovernor, path: str | os.PathLike, physics: PhysicsConfig | None = None,
    quantile: float = 0.99,
) -> ReachGovernor:  # fmt: skip
    """`governor` with its slide bounds fitted (`fit_slides`) to the pushes recorded in
    `path`; ValueError naming the file where it holds too few pushes."""
    physics = physics or governor.physics
    try:
        bounds = fit_slides(*push_slides(*recording_pushes(path), physics), quantile=quantile)
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from None
    return ReachGovernor(dataclasses.replace(governor.workspace, **bounds), governor.physics)
