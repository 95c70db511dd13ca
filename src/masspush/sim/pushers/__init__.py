"""Pushers: what physically delivers a push, and the registry of the known ones.

A pusher implements `base.Pusher`; its `base.PusherKind` states what it can do (batch path,
arm scene). A new pusher is a module beside these and one entry in `PUSHER_KINDS`.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from masspush.config import PhysicsConfig
from masspush.sim.pushers import compiled
from masspush.sim.pushers.arm import ARMS, ArmPusher
from masspush.sim.pushers.base import Pusher, PusherKind, StepHook
from masspush.sim.pushers.speed_equivalent import SpeedEquivalent
from masspush.sim.pushers.stiff import StiffPusher, park
from masspush.sim.workspace import ReachGovernor

PUSHER_KINDS: dict[str, PusherKind] = {
    kind.name: kind
    for kind in (
        PusherKind(
            "stiff", "stiff pusher", StiffPusher, batch=True, arm=False, camera_distance=0.9
        ),
        PusherKind(
            "kuka",
            "KUKA KR 5",
            lambda: ArmPusher("kuka"),
            batch=True,
            arm=True,
            camera_distance=1.6,
        ),
        PusherKind(
            "kuka-far",
            "KUKA KR 5, longer run-up",
            lambda: ArmPusher("kuka-far"),
            batch=True,
            arm=True,
            camera_distance=1.6,
        ),
        PusherKind(
            "ur10", "UR10", lambda: ArmPusher("ur10"), batch=True, arm=True, camera_distance=2.2
        ),
        PusherKind(
            "ur10-stationary",
            "UR10, stationary",
            lambda: ArmPusher("ur10-stationary"),
            # ChainBatch simulates it (tested), but the batch callers do not yet pass its
            # pushes through the reach governor: one chain at a time.
            batch=False,
            arm=True,
            camera_distance=2.2,
            workspace=ARMS["ur10-stationary"].workspace,
        ),
    )
}

PUSHERS = tuple(PUSHER_KINDS)
"""Pusher names accepted by the environment and the CLI."""

IDEAL_PUSHER = "stiff"
"""The idealised pusher: the default, and the stand-in where an arm's pushes are approximated."""


def pusher_kind(name: str) -> PusherKind:
    """The pusher kind called `name`, or a ValueError listing the known ones."""
    try:
        return PUSHER_KINDS[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown pusher {name!r}; known pushers: {list(PUSHERS)}") from None


def on_batch_path(name: str) -> bool:
    """Whether pushes of this pusher run on the batch path (`masspush.sim.batch.ChainBatch`)
    here: a pusher with one, and for an arm the compiled control law it runs in lockstep
    (without a C compiler, arms run one chain at a time, as before)."""
    kind = pusher_kind(name)
    if not kind.batch:
        return False
    return not kind.arm or compiled.library() is not None


def tool_radius(name: str, physics: PhysicsConfig) -> float:
    """The radius of the pusher's tool where it touches the chain, m: an arm's from its
    model file, the stiff pusher's from the physics."""
    pusher = make_pusher(name)
    return pusher.tool_radius if isinstance(pusher, ArmPusher) else physics.pusher_radius


def reach_governor(name: str, physics: PhysicsConfig) -> ReachGovernor | None:
    """The speed governor of a stationary pusher (`ReachGovernor`), None for one whose base
    follows the chain: every caller that chooses pushes for it passes its actions through."""
    workspace = pusher_kind(name).workspace
    return None if workspace is None else ReachGovernor(workspace, physics)


def speed_equivalent(name: str, physics: PhysicsConfig) -> SpeedEquivalent | None:
    """How the pusher `name` reads a push made at a reported speed (`SpeedEquivalent`); None
    for an arm limited by its torques alone, whose plan does not set the speed it reaches."""
    pusher = make_pusher(name)
    return SpeedEquivalent(pusher, physics) if SpeedEquivalent.reads(pusher) else None


def pusher_field(default: str | None = None, arms_only: bool = False) -> Any:
    """A config dataclass field that names a pusher (an arm, where `arms_only`): the known
    names ride in its metadata (`choices`), so that the command line lists them in the
    option's help from this registry instead of a list written by hand."""
    names = tuple(name for name, kind in PUSHER_KINDS.items() if kind.arm or not arms_only)
    return dataclasses.field(default=default, metadata={"choices": names})


def make_pusher(name: str) -> Pusher:
    """A new pusher called `name`, or a ValueError listing the known ones."""
    return pusher_kind(name).make()


__all__ = [
    "IDEAL_PUSHER",
    "PUSHERS",
    "PUSHER_KINDS",
    "ArmPusher",
    "Pusher",
    "PusherKind",
    "SpeedEquivalent",
    "StepHook",
    "StiffPusher",
    "make_pusher",
    "on_batch_path",
    "park",
    "pusher_field",
    "pusher_kind",
    "reach_governor",
    "speed_equivalent",
    "tool_radius",
]
