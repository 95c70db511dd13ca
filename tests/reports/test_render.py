import imageio.v3 as iio
import numpy as np
import pytest

from masspush.cli import main
from masspush.reports.render import render_episode


@pytest.mark.slow
@pytest.mark.parametrize(("pusher", "suffix"), [("stiff", ".gif"), ("kuka", ".mp4")])
def test_renders_non_blank_frames_of_the_requested_size(tmp_path, pusher, suffix):
    out = tmp_path / f"episode{suffix}"
    result = render_episode(
        "2link-0.1-1",
        pusher=pusher,
        out=out,
        width=160,
        height=120,
        stills=True,
        actions=np.array([[0.3, -0.5], [-0.2, 0.5]]),
    )
    frames = iio.imread(out)
    assert frames.shape[1:3] == (120, 160)
    # A GIF merges identical consecutive frames (the held rest poses); MP4 keeps them all.
    assert 20 < len(frames) <= result.frames
    # Not blank: real contrast in the picture area, below the caption bar.
    picture = frames[:, 30:].astype(float)
    assert picture.std() > 10
    # The scene changes over the episode (the chain moves).
    assert np.abs(frames[0].astype(float) - frames[-1].astype(float)).mean() > 0.5
    assert [p.name for p in result.stills] == [f"episode_rest{i}.png" for i in range(3)]
    assert iio.imread(result.stills[0]).shape == (120, 160, 3)


def test_render_refuses_bad_requests(tmp_path, capsys):
    with pytest.raises(ValueError, match=r"mp4 or \.gif"):
        render_episode("2link-0.1-1", out=tmp_path / "x.avi")
    assert main(["render", "--setting", "4link-1-2", "--out", str(tmp_path / "x.gif")]) == 2
    assert "unknown setting" in capsys.readouterr().err
