import numpy as np
import pytest

from masspush.config import PhysicsConfig
from masspush.sim.batch import ChainBatch
from masspush.sim.chain import sample_chain
from masspush.sim.simulate import ChainSim


@pytest.mark.slow
@pytest.mark.parametrize("n_links", [2, 3])
def test_batch_gives_the_same_rest_poses_as_one_at_a_time(n_links):
    physics = PhysicsConfig(n_links=n_links, mass_range=(0.1, 10.0))
    rng = np.random.default_rng(n_links)
    chains = [sample_chain(physics, rng) for _ in range(24)]
    assert len({c.masses for c in chains}) == 24 and len({c.friction for c in chains}) == 24
    actions = rng.uniform(-1, 1, size=(n_links, len(chains), 2))

    batch = ChainBatch(chains, physics, nthread=2)
    sims = [ChainSim(c, physics) for c in chains]
    np.testing.assert_array_equal(batch.configs(), [s.config() for s in sims])
    for step_actions in actions:
        batch_outcomes = batch.push(step_actions)
        for i, sim in enumerate(sims):
            if batch_outcomes[i] is None:  # skipped after an earlier failure
                continue
            outcome = sim.push(step_actions[i])
            assert outcome == batch_outcomes[i]
            if outcome.failure is None:
                np.testing.assert_array_equal(batch.configs()[i], sim.config())


def test_batch_checks_its_inputs():
    physics = PhysicsConfig(n_links=2)
    chains = [sample_chain(physics, np.random.default_rng(0))]
    with pytest.raises(ValueError, match="at least one chain"):
        ChainBatch([], physics)
    with pytest.raises(ValueError, match="n_links"):
        ChainBatch(chains, PhysicsConfig(n_links=3))
    with pytest.raises(ValueError, match="stiff pusher only"):
        ChainBatch(chains, physics, pusher="kuka")
    with pytest.raises(ValueError, match="shape"):
        ChainBatch(chains, physics).push(np.zeros((2, 2)))
