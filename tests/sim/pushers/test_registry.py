import pytest

from masspush.sim.pushers import (
    IDEAL_PUSHER,
    PUSHER_KINDS,
    PUSHERS,
    ArmPusher,
    StiffPusher,
    make_pusher,
    on_batch_path,
    pusher_field,
    pusher_kind,
)


def test_each_pusher_states_what_it_can_do():
    assert PUSHERS == ("stiff", "kuka", "kuka-far", "ur10", "ur10-stationary")
    assert pusher_kind(IDEAL_PUSHER).batch and not pusher_kind(IDEAL_PUSHER).arm
    for name in ("kuka", "ur10", "ur10-stationary"):
        assert pusher_kind(name).arm
    # The following arms run in lockstep where their compiled law is; the stationary one,
    # whose pushes pass its reach governor, one chain at a time.
    assert pusher_kind("kuka").batch and pusher_kind("ur10").batch
    assert not pusher_kind("ur10-stationary").batch and not on_batch_path("ur10-stationary")
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


def test_a_pusher_field_carries_the_registrys_names():
    from dataclasses import dataclass, fields

    @dataclass(frozen=True)
    class Config:
        pusher: str | None = pusher_field()
        arm: str = pusher_field("kuka", arms_only=True)

    assert Config() == Config(None, "kuka")
    by_name = {f.name: f.metadata["choices"] for f in fields(Config)}
    assert by_name["pusher"] == PUSHERS
    assert by_name["arm"] == tuple(n for n in PUSHERS if pusher_kind(n).arm)
    assert IDEAL_PUSHER not in by_name["arm"]


def test_arms_leave_the_batch_path_without_their_compiled_law(monkeypatch):
    from masspush.sim.pushers import compiled

    assert on_batch_path("stiff")
    monkeypatch.setattr(compiled, "library", lambda: None)
    assert on_batch_path("stiff") and not on_batch_path("kuka") and not on_batch_path("ur10")
