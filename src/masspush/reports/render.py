"""Pictures and videos of pushes: an episode rendered headless, with what happened written on it.

Frames come from MuJoCo's own renderer (EGL when there is no display, chosen in
`masspush/__init__.py`; set MUJOCO_GL to choose another backend) and are written by
imageio: MP4 through imageio-ffmpeg, GIF through Pillow. Pushes last tens of
milliseconds, so they are recorded every few milliseconds and shown in slow motion; the
slide to rest plays in real time.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import imageio.v3 as iio
import mujoco
import numpy as np
from PIL import Image, ImageDraw, ImageFont

from masspush.config import check_int, check_output
from masspush.env import ChainEnv
from masspush.settings import get_setting
from masspush.sim.chain import link_poses
from masspush.sim.pushers import pusher_field, pusher_kind

VIDEO_FPS = 30
PUSH_FRAME_TIME = 0.004
"""Simulated seconds between frames while the pusher acts: 7.5x slow motion at 30 fps."""
SLIDE_FRAME_TIME = 1.0 / VIDEO_FPS
"""Simulated seconds between frames while the chain slides: real time."""


@dataclass(frozen=True)
class RenderConfig:
    """`masspush render`: one episode of random pushes as a video, optionally with stills."""

    setting: str = "2link-0.1-1"
    """Named setting of the chain."""
    pusher: str = pusher_field("stiff")
    """The pusher (its own camera distance)."""
    out: str = "episode.mp4"
    """The video to write: .mp4 or .gif."""
    seed: int = 0
    """Random seed of the chain and its pushes."""
    width: int = 640
    """Frame width, pixels."""
    height: int = 480
    """Frame height, pixels."""
    png: bool = False
    """Also write one still per rest pose."""

    def __post_init__(self) -> None:
        pusher_kind(self.pusher)
        check_int("seed", self.seed, 0)
        check_int("width", self.width, 16)
        check_int("height", self.height, 16)
        check_output(self.out, "out", suffixes=(".mp4", ".gif"))


def render(config: RenderConfig) -> RenderResult:
    """`render_episode` as `config` says."""
    return render_episode(
        config.setting, config.pusher, config.out, seed=config.seed, width=config.width,
        height=config.height, stills=config.png,
    )  # fmt: skip


@dataclass(frozen=True)
class RenderResult:
    """What `render_episode` wrote."""

    video: Path
    stills: list[Path]
    frames: int
    failures: list[str | None]


class _Recorder:
    """Called after every physics step; renders a frame whenever one is due."""

    def __init__(self, env: ChainEnv, width: int, height: int, pusher: str):
        self.env = env
        self.sim = env.sim
        self.renderer = mujoco.Renderer(self.sim.model, height, width)
        self.camera = mujoco.MjvCamera()
        self.camera.distance = pusher_kind(pusher).camera_distance
        self.camera.elevation = -40.0
        self.camera.azimuth = 135.0
        self.pusher = pusher
        self.frames: list[np.ndarray] = []
        self.caption = ""
        self.next_time = 0.0
        self._centre = self._chain_centre()

    def _chain_centre(self) -> np.ndarray:
        chain = self.env.chain
        centres, _ = link_poses(self.sim.config(), chain.lengths, self.env.physics.joint_gap)
        return centres.mean(axis=0)

    def __call__(self) -> None:
        if self.sim.data.time + 1e-9 < self.next_time:
            return
        pushing = self.sim.phase == "push"
        self.next_time = self.sim.data.time + (PUSH_FRAME_TIME if pushing else SLIDE_FRAME_TIME)
        self.frames.append(self.frame(slow=pushing))

    def frame(self, slow: bool = False) -> np.ndarray:
        # Follow the chain smoothly; it can slide a metre or more in one push.
        self._centre = 0.9 * self._centre + 0.1 * self._chain_centre()
        self.camera.lookat[:] = [*self._centre, 0.0]
        self.renderer.update_scene(self.sim.data, self.camera)
        image = Image.fromarray(self.renderer.render())
        draw = ImageDraw.Draw(image)
        text = self.caption + ("   [slow motion x7.5]" if slow else "")
        size = max(10, image.height // 28)
        font = ImageFont.load_default(size=size)
        draw.rectangle((0, 0, image.width, 2 * size + 10), fill=(0, 0, 0))
        draw.text((6, 3), text, fill=(255, 255, 255), font=font)
        truth = ", ".join(f"{m:.2f}" for m in self.env.chain.mass_distribution)
        draw.text(
            (6, size + 6), f"true mass distribution [{truth}]", fill=(255, 220, 120), font=font
        )
        return np.asarray(image)

    def close(self) -> None:
        self.renderer.close()


def render_episode(
    setting: str,
    pusher: str = "stiff",
    out: str | os.PathLike = "episode.mp4",
    seed: int = 0,
    width: int = 640,
    height: int = 480,
    stills: bool = False,
    actions: np.ndarray | None = None,
) -> RenderResult:
    """Render one episode of random (or given) pushes to a video; optionally PNG stills."""
    out = Path(out)
    if out.suffix.lower() not in (".mp4", ".gif"):
        raise ValueError(f"output must end in .mp4 or .gif, got {out.name!r}")
    if width < 16 or height < 16:
        raise ValueError(f"frame size must be at least 16x16, got {width}x{height}")
    spec = get_setting(setting)
    out.parent.mkdir(parents=True, exist_ok=True)
    # The setting's own physics, so that a replay of an episode (seed, actions) is that episode.
    env = ChainEnv.from_config(spec.env_config(pusher))
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    recorder = _Recorder(env, width, height, pusher)
    env.sim.on_step = recorder
    k = env.config.pushes
    label = pusher_kind(pusher).label
    still_paths: list[Path] = []
    failures: list[str | None] = []

    def rest(index: int) -> None:
        recorder.caption = f"{setting} | {label} | at rest after push {index}/{k}"
        image = recorder.frame()
        recorder.frames.extend([image] * (VIDEO_FPS // 2))  # half a second on each rest pose
        if stills:
            path = out.with_name(f"{out.stem}_rest{index}.png")
            iio.imwrite(path, image)
            still_paths.append(path)

    rest(0)
    for i in range(k):
        action = actions[i] if actions is not None else rng.uniform(-1, 1, size=2)
        recorder.caption = f"{setting} | {label} | push {i + 1}/{k}"
        recorder.next_time = env.sim.data.time
        _, _, terminated, _, info = env.step(np.asarray(action, dtype=np.float32))
        failures.append(info["failure"])
        rest(i + 1)
        if terminated:
            break
    recorder.close()
    if out.suffix.lower() == ".gif":
        iio.imwrite(out, recorder.frames, duration=1000 / VIDEO_FPS, loop=0)
    else:
        iio.imwrite(out, recorder.frames, fps=VIDEO_FPS, codec="libx264", macro_block_size=1)
    return RenderResult(
        video=out, stills=still_paths, frames=len(recorder.frames), failures=failures
    )
