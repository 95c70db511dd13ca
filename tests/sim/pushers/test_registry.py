import pytest

from masspush.sim.pushers import (
    IDEAL_PUSHER,
    PUSHER_KINDS,
    PUSHERS,
    ArmPusher,
    StiffPusher,
    make_pusher,
    pusher_kind,
)


def test_each_pusher_states_what_it_can_do():
    assert PUSHERS == ("stiff", "kuka", "ur10", "ur10-stationary")
    assert pusher_kind(IDEAL_PUSHER).batch and not pusher_kind(IDEAL_PUSHER).arm
    for name in ("kuka", "ur10", "ur10-stationary"):
        assert pusher_kind(name).arm and not pusher_kind(name).batch
    # Only the stationary robot has a workspace, and its pusher carries the same one.
    assert [n for n, k in PUSHER_KINDS.items() if k.workspace] == ["ur10-stationary"]
    assert make_pusher("ur10-stationary").workspace == pusher_kind("ur10-stationary").workspace
    assert all(kind.name == name for name, kind in PUSHER_KINDS.items())


def test_the_registry_makes_each_pusher_and_refuses_unknown_ones():
    assert isinstance(make_pusher("stiff"), StiffPusher)
    arm = make_pusher("ur10")
    assert isinstance(arm, ArmPusher) and arm.name == "ur10"
    with pytest.raises(ValueError, match="unknown pusher 'nope'; known pushers"):
        make_pusher("nope")
