import numpy as np
import pytest

from masspush.data.recording import Recording, write_recording


def _slippery_recording(path, slide_per_speed: float, pushes: int = 400):
    """Random pushes on chains along +x, each carried slide_per_speed x speed along the push
    (a real-ur10 recording, for fitting a speed governor)."""
    rng = np.random.default_rng(1)
    episodes = []
    for i in range(pushes):
        a1 = rng.uniform(0.02, 1.0)  # > 0: towards +y on a chain along +x
        slide = min(slide_per_speed * 5.0 * a1, 0.3) * rng.uniform(0.5, 1.0)
        start = [0.0, -0.1, 0.0, 0.0]
        episodes.append({"id": str(i), "lengths": [0.125, 0.125],
                         "observations": [start, [0.0, -0.1 + slide, 0.0, 0.0]],
                         "actions": [[a1, 0.0]]})  # fmt: skip
    return write_recording(path, Recording(n_links=2, setting="real-ur10", episodes=episodes))


@pytest.fixture
def slippery_recording():
    """Writes `_slippery_recording(path, slide_per_speed, pushes=400)`; returns the path."""
    return _slippery_recording
