from dataclasses import replace

import numpy as np
import pytest

from masspush.config import PhysicsConfig
from masspush.settings import get_setting
from masspush.sim.batch import ChainBatch
from masspush.sim.chain import sample_chain
from masspush.sim.pushers import compiled, make_pusher
from masspush.sim.simulate import ChainSim


@pytest.mark.slow
@pytest.mark.parametrize("n_links", [2, 3])
def test_batch_gives_the_same_rest_poses_as_one_at_a_time(n_links):
    physics = PhysicsConfig(n_links=n_links, mass_range=(0.1, 10.0))
    rng = np.random.default_rng(n_links)
    chains = [sample_chain(physics, rng) for _ in range(24)]
    assert len({c.masses for c in chains}) == 24 and len({c.friction for c in chains}) == 24
    actions = rng.uniform(-1, 1, size=(n_links, len(chains), 2))

    _same_as_one_at_a_time("stiff", physics, chains, actions)


def test_batch_checks_its_inputs():
    physics = PhysicsConfig(n_links=2)
    chains = [sample_chain(physics, np.random.default_rng(0))]
    with pytest.raises(ValueError, match="at least one chain"):
        ChainBatch([], physics)
    with pytest.raises(ValueError, match="n_links"):
        ChainBatch(chains, PhysicsConfig(n_links=3))
    with pytest.raises(ValueError, match="unknown pusher"):
        ChainBatch(chains, physics, pusher="robot")
    with pytest.raises(ValueError, match="shape"):
        ChainBatch(chains, physics).push(np.zeros((2, 2)))


def _same_as_one_at_a_time(pusher, physics, chains, actions) -> list[str | None]:
    """Push `chains` in a batch and one at a time; assert equal outcomes and rest poses
    (exactly: the same law in the same order); return every push's failure. Where an arm
    pushes, also one at a time with the arm in every settling step (`settle_alone=False`):
    the batch settles without it, to the same rest poses."""
    batch = ChainBatch(chains, physics, nthread=2, pusher=pusher)
    sims = [ChainSim(c, physics, make_pusher(pusher), settle_alone=False) for c in chains]
    assert batch.initial_failures == [s.initial_failure for s in sims]
    np.testing.assert_array_equal(batch.configs(), [s.config() for s in sims])
    failures = []
    batch.failed[:] = [s.initial_failure is not None for s in sims]
    for step_actions in actions:
        batch_outcomes = batch.push(step_actions)
        for i, sim in enumerate(sims):
            if batch_outcomes[i] is None:  # skipped after an earlier failure
                continue
            outcome = sim.push(step_actions[i])
            assert outcome == batch_outcomes[i]
            failures.append(outcome.failure)
            if outcome.failure is None:
                np.testing.assert_array_equal(batch.configs()[i], sim.config())
    return failures


needs_compiled_law = pytest.mark.skipif(
    compiled.library() is None, reason="the arms' batch path runs the compiled law"
)


@needs_compiled_law
@pytest.mark.slow
@pytest.mark.parametrize("arm", ["kuka", "ur10"])
@pytest.mark.parametrize("n_links", [2, 3])
def test_arms_in_lockstep_give_the_rest_poses_of_one_at_a_time(arm, n_links):
    physics = PhysicsConfig(n_links=n_links)
    rng = np.random.default_rng(10 + n_links)
    chains = [sample_chain(physics, rng) for _ in range(5)]
    actions = rng.uniform(-1, 1, size=(3, len(chains), 2))
    actions[0, 1] = (0.0, 0.4)  # a push of zero speed: the arm does nothing
    failures = _same_as_one_at_a_time(arm, physics, chains, actions)
    assert failures.count(None) >= 12


@needs_compiled_law
@pytest.mark.slow
def test_arms_in_lockstep_fail_as_one_at_a_time():
    # Links 8 cm tall: the KUKA's wrist meets them in some pushes ("arm_contact"), while
    # the other chains of the batch go on.
    physics = replace(PhysicsConfig(), link_height=0.08)
    chains = [sample_chain(physics, np.random.default_rng(1007 + i)) for i in range(4)]
    actions = np.array([[(0.31, -0.64), (0.84, 0.36), (-0.87, 0.58), (0.54, -0.33)]])
    failures = _same_as_one_at_a_time("kuka", physics, chains, actions)
    assert failures == [None, "arm_contact", "arm_contact", "arm_contact"]


@needs_compiled_law
@pytest.mark.slow
def test_a_stationary_arm_in_lockstep_loses_chains_as_one_at_a_time():
    physics = get_setting("real-ur10").env_config().physics
    rng = np.random.default_rng(3)
    chains = [sample_chain(physics, rng) for _ in range(16)]
    actions = rng.uniform(-1, 1, size=(4, len(chains), 2))
    failures = _same_as_one_at_a_time("ur10-stationary", physics, chains, actions)
    assert "left_workspace" in failures and failures.count(None) >= 48


@needs_compiled_law
def test_the_lockstep_gives_back_the_control_callback_it_found():
    import ctypes

    import mujoco

    physics = PhysicsConfig(n_links=2)
    batch = ChainBatch([sample_chain(physics, np.random.default_rng(0))], physics, pusher="kuka")
    assert batch.push(np.array([[0.3, 0.5]]))[0].failure is None
    assert mujoco.get_mjcb_control() is None  # none before, none after
    # A caller's own C callback is back once the arms are done.
    theirs = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p)(lambda m, d: None)
    law = compiled.library()
    mujoco.set_mjcb_control(theirs)
    try:
        with compiled.lockstep_law(law, make_pusher("kuka")._compiled_arm(batch._arms.arm)):
            assert mujoco.get_mjcb_control() is law.masspush_control
        assert mujoco.get_mjcb_control() is theirs
    finally:
        mujoco.set_mjcb_control(None)


@needs_compiled_law
def test_arms_step_together_many_steps_a_call(monkeypatch):
    # Each batch call steps as far as no arm can end its push: far fewer calls than steps.
    physics = PhysicsConfig(n_links=2)
    rng = np.random.default_rng(5)
    batch = ChainBatch([sample_chain(physics, rng) for _ in range(3)], physics, pusher="kuka")
    calls = []
    step = batch.batch.step
    monkeypatch.setattr(
        batch.batch, "step", lambda ids, nstep: calls.append(nstep) or step(ids, nstep)
    )
    arms = batch._arms
    monkeypatch.setattr(arms, "park", lambda i, park=arms.park: calls.append("park") or park(i))
    outcomes = batch.push(np.array([(0.5, 0.5), (-0.3, 0.7), (0.2, -0.6)]))
    controlled = calls[: len(calls) - calls[::-1].index("park")]
    steps = sum(n for n in controlled if n != "park")
    assert steps == max(o.steps - round(o.settle_time / physics.timestep) for o in outcomes)
    assert len(controlled) - 3 < steps / 5


@needs_compiled_law
@pytest.mark.parametrize("cap", [0.01, 0.05])
def test_arms_in_lockstep_time_out_as_one_at_a_time(cap):
    # A settling cap of one rest check (no step in the settling scenes) or of five, from
    # the first push on: pushes end in 'timeout' as with the arm in every step.
    physics = PhysicsConfig(n_links=2)
    rng = np.random.default_rng(8)
    chains = [sample_chain(physics, rng) for _ in range(4)]
    batch = ChainBatch(chains, physics, nthread=2, pusher="kuka")
    sims = [ChainSim(c, physics, make_pusher("kuka"), settle_alone=False) for c in chains]
    capped = replace(physics, settle_time_cap=cap)
    batch.physics = capped
    for sim in sims:
        sim.physics = capped
    actions = np.array([(0.8, 0.5), (-0.9, 0.2), (0.7, -0.6), (0.95, 0.9)])
    outcomes = batch.push(actions)
    for i, sim in enumerate(sims):
        assert sim.push(actions[i]) == outcomes[i]
        np.testing.assert_array_equal(batch.configs()[i], sim.config())
    assert [o.failure for o in outcomes].count("timeout") >= 3
