"""The demo: a shipped policy pushes a random chain, a shipped predictor estimates its masses.

One episode, live: the policy chooses each push from what it has seen so far, the chain is
pushed and observed at rest, and the predictor's estimate after each push is set against the
truth. A picture shows the rest poses with the pushes and the estimates push by push; a
video (MuJoCo's renderer) replays the same episode on request.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from masspush.config import check_int, check_output
from masspush.learn.policy import model_policy
from masspush.learn.predictor import load_model
from masspush.models import resolve_model
from masspush.real.backends import SimRobot
from masspush.real.robot import PushReport, fmt, run_estimation
from masspush.settings import Setting, get_setting
from masspush.sim.actions import PushSpec, push_geometry
from masspush.sim.chain import link_poses

DEMO_SETTING = "2link-1-10"
"""The demo's default setting: 2 links, 1-10 kg, whose pusher (stiff) simulates fastest."""


@dataclass(frozen=True)
class DemoConfig:
    """`masspush demo`: a shipped policy pushes a random chain; the estimate after each push."""

    setting: str = DEMO_SETTING
    """Named setting with shipped models."""
    model: str = "tp+"
    """Shipped model name (rp, rp+, tp, tp+) or a model file."""
    seed: int = 0
    """The chain's random seed."""
    out: str = "masspush-demo.png"
    """The picture to write (PNG)."""
    video: str | None = None
    """Also render the episode to this MP4 or GIF."""

    def __post_init__(self) -> None:
        check_int("seed", self.seed, 0)
        check_output(self.out, "out", suffixes=(".png",))
        if self.video is not None:
            check_output(self.video, "video", suffixes=(".mp4", ".gif"))


@dataclass
class DemoEpisode:
    """What happened in the demo's episode."""

    setting: Setting
    pusher: str
    model: str
    policy: str
    seed: int
    masses: np.ndarray
    truth: np.ndarray
    lengths: np.ndarray
    configs: list[np.ndarray] = field(default_factory=list)
    """True rest configurations q_0..q_k (the picture draws these)."""
    actions: list[np.ndarray] = field(default_factory=list)
    """Actions as the policy chose them (the simulation adds the setting's action noise)."""
    pushes: list[dict] = field(default_factory=list)
    estimates: list[np.ndarray] = field(default_factory=list)
    failure: str | None = None


def run_demo(
    setting: str | Setting = DEMO_SETTING,
    model: str | os.PathLike = "tp+",
    seed: int = 0,
    report: Callable[[str], object] = print,
) -> DemoEpisode:
    """Run one episode with a trained (shipped) model and its policy; report as it goes."""
    spec = get_setting(setting) if isinstance(setting, str) else setting
    path = resolve_model(model, spec.name)
    predictor, meta = load_model(path, spec.name)
    policy = model_policy(meta, path)
    robot = SimRobot(spec, meta["pusher"], seed)
    rest = robot.start()
    if robot.seed != seed + 1:
        raise RuntimeError(f"seed {seed} gives a chain that fails at rest; try another seed")
    truth = robot.truth
    episode = DemoEpisode(
        setting=spec,
        pusher=robot.pusher,
        model=str(model),
        policy=policy.name,
        seed=seed,
        masses=truth["masses"],
        truth=truth["mass_distribution"],
        lengths=rest.lengths,
        configs=[truth["config"]],
    )
    report(
        f"A {spec.n_links}-link chain on a table ({spec.name}, seed {seed}), pushed by the "
        f"{robot.pusher} pusher; the robot may only push it and look where it comes to rest."
    )
    report(f"  true masses        {fmt(truth['masses'])} kg")
    report(f"  mass distribution  {fmt(episode.truth)}   <- what is to be estimated")
    report(f"  table friction     {truth['friction']:.3f}, link lengths {fmt(rest.lengths)} m")
    report(f"  rest pose q0       {fmt(rest.config)}  (x, y, yaw, joint angles; noisy)")
    report(f"Model {model!r} ({path.name}), pushes chosen by the {policy.name} policy.")

    def on_push(
        k: int, action: np.ndarray, result: PushReport, estimate: np.ndarray | None
    ) -> None:
        push = result.details
        geometry = push_geometry(_spec(push), episode.configs[-1], rest.lengths, robot.env.physics)
        episode.pushes.append(
            {**push, "contact": geometry.contact, "direction": geometry.direction}
        )
        side = "from the right" if push["side"] > 0 else "from the left"
        report(
            f"push {k + 1}: a={fmt(action, 2)} -> link {push['link'] + 1} {side}, "
            f"{push['offset'] * 100:+.1f} cm from its centre, at {push['speed']:.2f} m/s"
        )
        if result.failure is not None:
            report(f"  push failed ({result.failure})")
            return
        episode.actions.append(action)
        episode.configs.append(push["config"])
        episode.estimates.append(estimate)
        error = 100 * np.abs(estimate - episode.truth).mean()
        report(f"  at rest after {push['settle_time']:.2f} s: q{k + 1} = {fmt(result.config)}")
        report(
            f"  estimate           {fmt(estimate)}   truth {fmt(episode.truth)}   "
            f"(mean absolute error x100: {error:.1f})"
        )

    result = run_estimation(
        robot, predictor, policy, robot.env.config.pushes, on_push, start=rest, seed=seed
    )
    episode.failure = result.failure
    return episode


def demo(config: DemoConfig, report: Callable[[str], object] = print) -> list[Path]:
    """The demo: run the episode (reporting each push), draw it, and on request render it
    to a video. Returns the files written."""
    episode = run_demo(config.setting, config.model, config.seed, report)
    written = [draw_demo(episode, config.out)]
    if config.video:
        from masspush.reports.render import render_episode

        result = render_episode(
            episode.setting.name, episode.pusher, config.video, seed=config.seed,
            actions=np.asarray(episode.actions),
        )  # fmt: skip
        written.append(result.video)
    return written


def draw_demo(episode: DemoEpisode, out: str | os.PathLike) -> Path:
    """A picture of the episode: the chain's rest poses seen from above with each push as an
    arrow, and beside it the estimate after each push against the truth."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    physics = episode.setting.physics()
    fig, (top, bars) = plt.subplots(1, 2, figsize=(11, 4.6), width_ratios=(1.3, 1))
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 0.85, len(episode.configs)))
    for k, (config, colour) in enumerate(zip(episode.configs, colours, strict=True)):
        centres, headings = link_poses(config, episode.lengths, physics.joint_gap)
        for centre, heading, length in zip(centres, headings, episode.lengths, strict=True):
            corners = _box(centre, heading, length, physics.link_width)
            top.add_patch(
                Polygon(corners, closed=True, facecolor=colour, edgecolor="black", alpha=0.75)
            )
        top.annotate(f"q{k}", centres[0], fontsize=8, ha="center", va="center", color="white")
    span = max(float(np.sum(episode.lengths)), 0.2)
    for k, push in enumerate(episode.pushes):
        tail = push["contact"] - push["direction"] * 0.25 * span * (0.3 + push["speed"] / 5)
        top.annotate(
            "",
            xy=push["contact"],
            xytext=tail,
            arrowprops={"arrowstyle": "->", "color": "crimson", "lw": 2},
        )
        top.annotate(f"{k + 1}", tail, color="crimson", fontsize=11, fontweight="bold")
    top.set_aspect("equal")
    top.autoscale_view()
    top.margins(0.15)
    top.set_xlabel("x (m)")
    top.set_ylabel("y (m)")
    top.set_title(f"rest poses q0..q{len(episode.configs) - 1} and pushes (red), seen from above")

    n = episode.setting.n_links
    series = [("truth", episode.truth, "black")] + [
        (f"after push {k + 1}", e, plt.get_cmap("autumn")(k / max(1, len(episode.estimates))))
        for k, e in enumerate(episode.estimates)
    ]
    width = 0.8 / len(series)
    for j, (label, values, colour) in enumerate(series):
        x = np.arange(n) + (j - (len(series) - 1) / 2) * width
        bars.bar(x, values, width, label=label, color=colour)
    bars.set_xticks(np.arange(n), [f"link {i + 1}" for i in range(n)])
    bars.set_ylabel("share of the total mass")
    bars.set_ylim(0, 1)
    bars.legend(fontsize=8)
    bars.set_title(f"estimate ({episode.model}, {episode.policy}) vs truth")
    fig.suptitle(
        f"{episode.setting.name}, {episode.pusher} pusher, seed {episode.seed}: "
        f"masses {', '.join(f'{m:.2f}' for m in episode.masses)} kg"
    )
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def _box(centre: np.ndarray, heading: float, length: float, width: float) -> np.ndarray:
    along = np.array([np.cos(heading), np.sin(heading)]) * length / 2
    across = np.array([-np.sin(heading), np.cos(heading)]) * width / 2
    return np.array(
        [centre - along - across, centre + along - across, centre + along + across,
         centre - along + across]
    )  # fmt: skip


def _spec(push: dict) -> PushSpec:
    return PushSpec(
        link=push["link"], offset=push["offset"], side=push["side"], speed=push["speed"]
    )
