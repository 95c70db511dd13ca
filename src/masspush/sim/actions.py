"""From an action a = (a1, a2) in [-1, 1]^2 to a push on the chain (pure functions).

The mapping follows the authors' code (shared/notes/paper-details.md):
- speed = push_speed_max * |a1|; the sign of a1 picks the side of the chain
  (a1 >= 0: the pusher comes from the link's right (-y) side and pushes towards +y);
- u = n (a2 + 1) / 2; link = min(floor(u), n - 1);
- offset from the link centre along the link = (u - link - 0.5) * fraction * L.

For a2 in [-1, 1) this is exactly the authors' frac((a2 + 1) n / 2); at a2 = 1 their
formula wraps to the far end of the last link (frac(n) = 0), ours stays continuous at
+fraction/2 * L. Clipped noisy actions land on a2 = 1 often enough for this to matter.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from masspush.config import PhysicsConfig
from masspush.sim.chain import link_poses


@dataclass(frozen=True)
class PushSpec:
    """A push in the chain's own terms."""

    link: int
    """Index of the pushed link."""
    offset: float
    """Contact point's distance from the link centre along the link, m."""
    side: int
    """+1: pushed from its -y face towards +y; -1: from its +y face towards -y."""
    speed: float
    """Target pusher speed, m/s."""


@dataclass(frozen=True)
class PushGeometry:
    """A push in the table frame (2-D), as a pusher executes it."""

    contact: np.ndarray
    """Contact point on the pushed face, (x, y), m."""
    direction: np.ndarray
    """Unit push direction, perpendicular to the face, (x, y)."""
    speed: float
    """Target speed along `direction`, m/s."""


def check_action(action: Sequence[float] | np.ndarray) -> np.ndarray:
    """The action as a float array, or ValueError naming what is wrong with it."""
    try:
        a = np.asarray(action, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"action must be two numbers in [-1, 1], got {action!r}") from None
    if a.shape != (2,):
        raise ValueError(f"action must have shape (2,), got shape {a.shape}: {action!r}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"action contains NaN or inf: {a.tolist()}")
    if np.any(np.abs(a) > 1.0):
        raise ValueError(f"action {a.tolist()} is outside the action box [-1, 1]^2")
    return a


def action_to_push(
    action: np.ndarray, lengths: Sequence[float], physics: PhysicsConfig
) -> PushSpec:
    """Map an action in [-1, 1]^2 to the push it stands for (see module docstring)."""
    a1, a2 = (float(v) for v in check_action(action))
    n = len(lengths)
    u = n * (a2 + 1) / 2
    link = min(math.floor(u), n - 1)
    offset = (u - link - 0.5) * physics.push_offset_fraction * lengths[link]
    return PushSpec(
        link=link, offset=offset, side=1 if a1 >= 0 else -1, speed=physics.push_speed_max * abs(a1)
    )


def push_geometry(
    push: PushSpec, config: np.ndarray, lengths: Sequence[float], physics: PhysicsConfig
) -> PushGeometry:
    """Contact point and direction of a push on a chain in configuration `config`."""
    centres, headings = link_poses(config, lengths, physics.joint_gap)
    h = headings[push.link]
    along = np.array([math.cos(h), math.sin(h)])
    normal = np.array([-math.sin(h), math.cos(h)])  # the link's +y axis
    contact = (
        centres[push.link] + push.offset * along - push.side * (physics.link_width / 2) * normal
    )
    return PushGeometry(contact=contact, direction=push.side * normal, speed=push.speed)
