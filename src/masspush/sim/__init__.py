"""The simulation: chains on a table (`chain`), actions to pushes (`actions`), one chain
pushed to rest (`simulate`) or many in lockstep (`batch`), the pushers (`pushers`), where a
stationary robot reaches (`workspace`) and whether its arm can make a push
(`arm_reach`), and how trustworthy a simulated rest pose is
(`convergence`). No learning, no torch.

The names below are its public API (what experiments/ may import)."""

from masspush._exports import lazy, names

EXPORTS = {
    "chain": ("ChainParams", "link_poses", "sample_chain", "wrap_angle"),
    "actions": ("PushGeometry", "PushSpec", "action_to_push", "push_geometry"),
    "simulate": ("FAILURES", "REACH_FAILURES", "ChainSim", "PushOutcome"),
    "batch": ("ChainBatch",),
    "pushers": ("PUSHERS", "PUSHER_KINDS", "ArmPusher", "StiffPusher", "make_pusher",
                "pusher_kind", "reach_governor", "SpeedEquivalent", "speed_equivalent"),
    "convergence": ("format_table", "validate_physics"),
    "workspace": ("ReachGovernor", "Workspace", "fit_slides", "push_slides"),
    "arm_reach": ("ReachCheck", "reach_check"),
}  # fmt: skip
__getattr__ = lazy(__name__, EXPORTS)
__all__ = names(EXPORTS)
