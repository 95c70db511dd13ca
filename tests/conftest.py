import numpy as np
import pytest

from masspush.config import PhysicsConfig


@pytest.fixture
def physics2() -> PhysicsConfig:
    return PhysicsConfig(n_links=2)


@pytest.fixture
def physics3() -> PhysicsConfig:
    return PhysicsConfig(n_links=3)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


@pytest.fixture(scope="session")
def predictor_file(tmp_path_factory):
    """A briefly trained 2link-0.1-1 predictor (stiff pusher), for policy tests."""
    from masspush.config import EnvConfig
    from masspush.data.rollout import TRAIN, RandomPolicy, run_batch
    from masspush.learn.predictor import TrainConfig, train_predictor
    from masspush.settings import get_setting

    config = EnvConfig(physics=get_setting("2link-0.1-1").physics(), pusher="stiff")
    episodes = run_batch(config, RandomPolicy(), np.arange(300), TRAIN, 0)
    run = tmp_path_factory.mktemp("predictor")
    train = TrainConfig(
        optimizer="adam", steps=50, batch_size=32, lr=1e-3, eval_every=25, features="relative"
    )
    train_predictor(episodes, run, train, {"setting": {"name": "2link-0.1-1"}}, progress=False)
    return run / "predictor.pt"


@pytest.fixture(scope="session")
def model_file(tmp_path_factory):
    """An untrained 2link-0.1-1 predictor with a random policy, for evaluation tests."""
    from masspush.config import EnvConfig
    from masspush.data.rollout import TRAIN, RandomPolicy, run_batch
    from masspush.learn.predictor import MassPredictor, save_model, step_inputs
    from masspush.settings import get_setting

    setting = get_setting("2link-0.1-1")
    eps = run_batch(EnvConfig(physics=setting.physics()), RandomPolicy(), np.arange(50), TRAIN, 0)
    q0, steps = step_inputs(eps.select(eps.ok), "relative")
    model = MassPredictor(2, q0.shape[1], steps.shape[2], "relative")
    model.set_normaliser(q0, steps)
    path = tmp_path_factory.mktemp("m") / "model.pt"
    save_model(path, model, {"setting": setting.as_dict(), "pusher": "stiff", "policy": "random"})
    return path


@pytest.fixture(scope="session")
def density_file(tmp_path_factory):
    """A briefly trained 2link-1-10 push density (stiff pusher): a cheap learned likelihood
    for the particle filter's tests."""
    from masspush.data.dataset import CollectConfig, collect_dataset
    from masspush.learn.push_density import DensityConfig, train_push_density

    root = tmp_path_factory.mktemp("density")
    collect_dataset(CollectConfig(setting="2link-1-10", out=str(root / "data"), episodes=60,
                                  shard_size=30), progress=False)  # fmt: skip
    config = DensityConfig(data=(str(root / "data"),), out=str(root / "density.pt"), steps=200,
                           batch_size=64, width=32, depth=2, components=2)  # fmt: skip
    train_push_density(config, progress=False)
    return root / "density.pt"


class SerialPool:
    """A `TaskPool` that runs its tasks here, in reverse order (a cluster returns them in
    any order): the driver-side logic of the pool path without a cluster. `stop_after`
    interrupts the run after that many results, as a killed driver would."""

    def __init__(self, size: int = 2, stop_after: int | None = None):
        self.size, self.stop_after, self.tasks = size, stop_after, 0

    def imap(self, fn, jobs, shared=None, desc=None):
        import pickle

        shared = pickle.loads(pickle.dumps(shared))  # what travels to a worker is a copy
        for i in reversed(range(len(jobs))):
            if self.stop_after is not None and self.tasks >= self.stop_after:
                raise KeyboardInterrupt
            self.tasks += 1
            yield i, fn(shared, jobs[i])


@pytest.fixture
def serial_pool():
    return SerialPool


@pytest.fixture(scope="session")
def ray_cluster():
    """A local Ray cluster of two CPUs for the session, as `--ray local` starts one; this
    process stays connected, so `open_pool(...)` and `connect(...)` reuse it."""
    ray = pytest.importorskip("ray")
    import logging

    ray.init(address="local", num_cpus=2, include_dashboard=False, logging_level=logging.ERROR)
    yield "local"
    ray.shutdown()


@pytest.fixture
def perturbed_pair():
    """Makes an ensemble of a predictor and a copy whose output layer is nudged: two members
    that estimate differently, without training a second one."""
    import copy

    import torch

    from masspush.learn.predictor import PredictorEnsemble

    def pair(predictor):
        other = copy.deepcopy(predictor)
        with torch.no_grad():
            other.head.weight.add_(0.3 * torch.randn_like(other.head.weight))
        return PredictorEnsemble([predictor, other])

    return pair
