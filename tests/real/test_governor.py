import numpy as np
import pytest

from masspush.data.recording import Recording, write_recording
from masspush.real.governor import fit_governor, recording_pushes
from masspush.settings import get_setting
from masspush.sim import reach_governor

SETTING = get_setting("real-ur10")


def test_a_governor_fitted_to_a_slippery_table_slows_pushes_more(tmp_path, slippery_recording):
    shipped = reach_governor(SETTING.pusher, SETTING.physics())
    path = slippery_recording(tmp_path / "lab.jsonl", slide_per_speed=0.2)
    assert len(recording_pushes(path)[0]) == 400
    fitted = fit_governor(shipped, path)
    ws = fitted.workspace
    assert 0.36 <= ws.slide_base + 2.0 * ws.slide_per_speed <= 0.46  # 2 m/s: 0.2 x 2 m, +-10 %
    assert fitted.workspace.base == shipped.workspace.base  # only the slides change
    near_edge = np.array([0.0, 0.1, 0.0, 0.0])
    asked = np.array([1.0, 0.0], np.float32)
    assert (
        fitted(asked, near_edge, [0.125, 0.125])[0] < shipped(asked, near_edge, [0.125, 0.125])[0]
    )


def test_too_short_a_recording_is_refused_naming_it(tmp_path, slippery_recording):
    shipped = reach_governor(SETTING.pusher, SETTING.physics())
    path = slippery_recording(tmp_path / "short.jsonl", 0.2, pushes=10)
    with pytest.raises(ValueError, match=r"short\.jsonl: too few pushes"):
        fit_governor(shipped, path)


def test_a_recording_of_another_chain_is_refused_naming_it(tmp_path):
    shipped = reach_governor(SETTING.pusher, SETTING.physics())
    episode = {"id": "0", "lengths": [0.1, 0.1, 0.1], "observations": [[0.0] * 5, [0.1] * 5],
               "actions": [[0.5, 0.0]]}  # fmt: skip
    path = write_recording(tmp_path / "three.jsonl", Recording(n_links=3, episodes=[episode]))
    with pytest.raises(ValueError, match=r"three\.jsonl: a recording of 3-link chains"):
        fit_governor(shipped, path)
