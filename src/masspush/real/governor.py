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
from typing import TYPE_CHECKING

import numpy as np

from masspush.config import PhysicsConfig
from masspush.data.recording import read_recording
from masspush.data.rollout import Episodes
from masspush.sim.pushers import reach_governor
from masspush.sim.workspace import ReachGovernor, fit_slides, push_slides

if TYPE_CHECKING:
    from masspush.settings import Setting


def episode_pushes(episodes: Episodes) -> tuple[np.ndarray, ...]:
    """(before, after, actions, lengths) of every successful push with a rest pose after it,
    one row per push (what `push_slides` reads): a dataset's true poses, a recording's
    observed ones (`Recording.to_episodes`)."""
    before, after = episodes.configs[:, :-1], episodes.configs[:, 1:]
    done = (episodes.failure == 0) & np.isfinite(before).all(-1) & np.isfinite(after).all(-1)
    e, _ = np.nonzero(done)
    rows = (before[done], after[done], episodes.actions[done], episodes.lengths[e])
    return tuple(np.asarray(r, float) for r in rows)


def recording_pushes(path: str | os.PathLike) -> tuple[np.ndarray, ...]:
    """`episode_pushes` of a recording."""
    return episode_pushes(read_recording(path).to_episodes())


def fit_governor(
    governor: ReachGovernor, path: str | os.PathLike, physics: PhysicsConfig | None = None,
    quantile: float = 0.99,
) -> ReachGovernor:  # fmt: skip
    """`governor` with its slide bounds fitted (`fit_slides`) to the pushes recorded in
    `path`; ValueError naming the file where it is no recording of this chain or holds too
    few pushes."""
    physics = physics or governor.physics
    recording = read_recording(path)  # its errors name the file
    if recording.n_links != physics.n_links:
        raise ValueError(
            f"{path}: a recording of {recording.n_links}-link chains; the governor's chain "
            f"has {physics.n_links} links"
        )
    pushes = episode_pushes(recording.to_episodes())
    try:
        bounds = fit_slides(*push_slides(*pushes, physics), quantile=quantile)
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from None
    return ReachGovernor(dataclasses.replace(governor.workspace, **bounds), governor.physics)


def fitted_setting_governor(setting: Setting, path: str | os.PathLike) -> ReachGovernor:
    """The speed governor `setting`'s models were trained with, its slide bounds fitted to the
    random pushes recorded in `path`; ValueError where the setting's robot follows the chain
    (it has none) or the recording cannot be fitted."""
    governor = reach_governor(setting.pusher, setting.physics())
    if governor is None:
        raise ValueError(
            f"governor_fit: {setting.name}'s pusher {setting.pusher!r} follows the chain; "
            "only a stationary robot has a speed governor"
        )
    return fit_governor(governor, path)
