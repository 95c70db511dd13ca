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
