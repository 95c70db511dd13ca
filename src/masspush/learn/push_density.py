"""A learned likelihood of a push's outcome: p(observed rest pose | rest pose before, action,
masses, friction, lengths), a mixture density network [Bishop 1994] trained on simulated
episodes of the setting's pusher (`masspush collect`).

Why learn it when the simulator is at hand: a push's outcome is not a function of the
observed pose. The chain's micro-state at rest (height, tilt, residual velocities, far
below what a tracker sees) decides one push in four with two links and two in five with
three (docs/notebook/2026-11-22-bayes.md, "micro-state"), and an arm's push adds its own
scatter. Simulating each particle once and putting a Student-t around the result describes
that draw roughly; a density trained on the simulator's own noisy episodes learns its
actual distribution, multi-modal where a collision makes it so. This is neural likelihood
estimation [Papamakarios, Sterratt & Murray, AISTATS 2019]: the arm is in the likelihood
through its simulated pushes, learned once, and a particle costs a network evaluation
instead of an arm simulation, so the filter can afford thousands.

The outcome is expressed in the frame of the pose before the push (the table is uniform
and the pushes are made relative to the chain): the first link's displacement in its own
frame, its change of heading, and the joint angles after the push. The inputs: the joint
angles before, the commanded action, log masses, log friction, and the link lengths; for a
stationary robot also where the chain lies (`placed`): its arm reaches each place in
another posture, and its joints' speed limits bite in some (held-out log-likelihood on the
stationary UR10's pushes 0.94 with the place, 0.61 without;
docs/notebook/2026-12-04-stationary-ur10-density.md).
A pushed chain that failed (out of reach, a timeout) is not in the training data: the
filter leaves a failed push out, as the episode ends there.
"""

from __future__ import annotations

import hashlib
import os
import time
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Literal, get_args

import numpy as np
import torch
from torch import nn
from torch.distributions import Categorical, MixtureSameFamily, MultivariateNormal

from masspush.config import check_choice, check_int, check_output
from masspush.learn.predictor import check_batch_memory
from masspush.sim.chain import wrap_angle
from masspush.sim.pushers import pusher_kind

PUSH_DENSITY_FILE = "push-density.pt"
"""The learned likelihood's file name in a setting's shipped models (`masspush.models`)."""

FORMAT = 1
"""The model file's format version."""

DensityActions = Literal["commanded", "executed", "executed-speed"]
DENSITY_ACTIONS = get_args(DensityActions)
"""What a density's actions are (`DensityConfig.actions`)."""


DENSITY_BYTES_PER_PUSH = 12_000
"""Training memory per push of a batch at the default network (3 x 256, 8 components) with
three links' 5 outputs: a step on 20,000 pushes took 231 MB, on 100,000 1.08 GB (forward and
backward on this machine's CPU build) [ours, measured]."""


@dataclass(frozen=True)
class DensityConfig:
    """`masspush train-density`: a mixture density network of a push's outcome, the particle
    filter's learned likelihood (`BayesConfig.likelihood`) [ours]."""

    data: tuple[str, ...]
    """Dataset directories of one setting and pusher (`masspush collect`), any policies:
    random pushes cover the actions the filter compares, a learned policy's add depth
    where it pushes. Episodes of `masspush randomise` (worlds drawn per episode) give a
    likelihood that covers what differs between worlds; all directories must have been
    pushed in the same kind of world."""
    out: str
    """The model file to write; its checkpoint beside it (`OUT.ckpt`) resumes a stopped run."""
    steps: int = 60_000
    """Gradient steps (Adam, one-cycle learning rate)."""
    batch_size: int = 1024
    """Pushes per step."""
    lr: float = 2e-3
    """Peak learning rate of the one-cycle schedule."""
    components: int = 8
    """Gaussians in the mixture (full covariance each)."""
    width: int = 256
    """Width of the network's hidden layers."""
    depth: int = 3
    """Hidden layers."""
    held_out: float = 0.02
    """Fraction of each dataset's episodes (its last ones) held out to report the density's
    log-likelihood on pushes it never saw."""
    seed: int = 0
    """Seed of the network's initial weights and of the batches."""
    checkpoint_every: int = 2000
    """Steps between checkpoints."""
    placed: bool | None = None
    """Whether the network sees where the chain lies on the table (`push_inputs`); None:
    where the pusher stands still (a pusher with a workspace), since then a push's outcome
    depends on where the robot reaches to, and elsewhere the table is uniform."""
    actions: DensityActions = "commanded"
    """Which actions the density is conditioned on: as commanded; as the robot executed them
    (the datasets' `executed` actions, the actuation noise added); or the executed speed
    with the commanded contact point. An executed one is a sharper likelihood for a robot
    that reports what it did; the filter then weighs each push at what the robot reported
    (`PushReport.speed`) and a push not reported as commanded. For the stationary UR10
    neither sorted the labs' chains better (docs/notebook/2026-12-05-executed-density.md)."""

    def __post_init__(self) -> None:
        if not self.data:
            raise ValueError("data: name at least one dataset directory")
        for name in ("steps", "batch_size", "components", "width", "depth", "checkpoint_every"):
            check_int(name, getattr(self, name), 1)
        check_int("seed", self.seed, 0)
        check_choice("actions", self.actions, DENSITY_ACTIONS)
        if not (np.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"lr must be a positive number, got {self.lr!r}")
        if not 0 < self.held_out < 0.5:
            raise ValueError(f"held_out must be in (0, 0.5), got {self.held_out!r}")
        check_output(self.out, "out")
        # Memory grows with the network and its mixture; scaled from the measured default.
        size = max(1.0, self.width * self.depth / 768, self.components / 8)
        check_batch_memory(self.batch_size, 1, DENSITY_BYTES_PER_PUSH * size, "pushes")


def push_inputs(
    start: np.ndarray, action: np.ndarray, masses: np.ndarray, friction: np.ndarray,
    lengths: np.ndarray, placed: bool = False,
) -> np.ndarray:  # fmt: skip
    """The network's inputs (m, features) for m particles: `start` (d,) or (m, d) rest
    poses, `action` (2,) or (m, 2), `masses` (m, n), `friction` (m,), `lengths` (n,) or (m, n).
    `placed`: also where the chain lies on the table (the first link's position and
    heading), for a stationary robot, whose pushes differ with where it reaches to."""
    masses = np.atleast_2d(np.asarray(masses, float))
    m = len(masses)
    start = np.broadcast_to(np.atleast_2d(np.asarray(start, float)), (m, masses.shape[1] + 2))
    action = np.broadcast_to(np.atleast_2d(np.asarray(action, float)), (m, 2))
    lengths = np.broadcast_to(np.atleast_2d(np.asarray(lengths, float)), masses.shape)
    friction = np.broadcast_to(np.asarray(friction, float), (m,))
    # Lengths in decimetres keep every input of order one before standardising.
    columns = [start[:, 3:], action, np.log(masses), np.log(friction), 10 * lengths]
    if placed:
        columns += [start[:, :2], np.cos(start[:, 2:3]), np.sin(start[:, 2:3])]
    return np.column_stack(columns)


def push_outputs(start: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """`observed` rest poses (m, d) in the frame of the poses `start` before the push:
    displacement along and across the first link, change of heading, joint angles."""
    start, observed = np.atleast_2d(start), np.atleast_2d(observed)
    c, s = np.cos(start[:, 2]), np.sin(start[:, 2])
    dx, dy = observed[:, 0] - start[:, 0], observed[:, 1] - start[:, 1]
    turn = wrap_angle(observed[:, 2] - start[:, 2])
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy, turn, observed[:, 3:]])


def rest_poses(start: np.ndarray, outputs: np.ndarray) -> np.ndarray:
    """The inverse of `push_outputs`: rest poses (m, d) in the table's frame."""
    start, outputs = np.atleast_2d(start), np.atleast_2d(outputs)
    c, s = np.cos(start[:, 2]), np.sin(start[:, 2])
    x = start[:, 0] + c * outputs[:, 0] - s * outputs[:, 1]
    y = start[:, 1] + s * outputs[:, 0] + c * outputs[:, 1]
    yaw = wrap_angle(start[:, 2] + outputs[:, 2])
    return np.column_stack([x, y, yaw, outputs[:, 3:]])


def episode_pushes(
    episodes: Any, rows: slice = slice(None), placed: bool = False, which: str = "commanded"
) -> tuple[np.ndarray, np.ndarray]:
    """Every push of a dataset's episodes (`rows` of them) that did not fail, and none after
    a failure: inputs and outputs (`push_inputs`, `push_outputs` with `placed`), each from
    the observed (noisy) rest pose before it to the observed one after, as the filter sees
    them; the actions `which` `DensityConfig.actions` names."""
    obs = np.asarray(episodes.observations[rows], float)
    actions = np.array(episodes.actions[rows], float)  # a copy: written below
    if which != "commanded":
        executed = np.asarray(episodes.executed[rows], float)
        parts = slice(None) if which == "executed" else slice(0, 1)  # executed-speed: a1
        actions[..., parts] = executed[..., parts]
    masses = np.asarray(episodes.masses[rows], float)
    friction = np.asarray(episodes.friction[rows], float)
    lengths = np.asarray(episodes.lengths[rows], float)
    intact = np.cumsum(np.asarray(episodes.failure[rows]) != 0, axis=1) == 0
    inputs, outputs = [], []
    for k in range(actions.shape[1]):
        ok = intact[:, k]
        inputs.append(push_inputs(obs[ok, k], actions[ok, k], masses[ok], friction[ok],
                                  lengths[ok], placed))  # fmt: skip
        outputs.append(push_outputs(obs[ok, k], obs[ok, k + 1]))
    return np.concatenate(inputs), np.concatenate(outputs)


class PushDensity(nn.Module):
    """The mixture density network with its inputs' and outputs' standardisation and what
    it was trained for (`meta`: setting, links, pusher, noise, priors)."""

    def __init__(self, inputs: int, outputs: int, components: int = 8, width: int = 256,
                 depth: int = 3, meta: dict | None = None):  # fmt: skip
        super().__init__()
        layers, d = [], inputs
        for _ in range(depth):
            layers += [nn.Linear(d, width), nn.SiLU()]
            d = width
        self.body = nn.Sequential(*layers)
        self.k, self.d = components, outputs
        self.logits = nn.Linear(width, components)
        self.mean = nn.Linear(width, components * outputs)
        self.diag = nn.Linear(width, components * outputs)
        below = torch.tril_indices(outputs, outputs, -1)
        self.register_buffer("below", below, persistent=False)
        self.off = nn.Linear(width, components * below.shape[1])
        for name, size in (("x_mean", inputs), ("x_std", inputs), ("y_mean", outputs),
                           ("y_std", outputs)):  # fmt: skip
            self.register_buffer(name, torch.zeros(size) if "mean" in name else torch.ones(size))
        self.arch = {"inputs": inputs, "outputs": outputs, "components": components,
                     "width": width, "depth": depth}  # fmt: skip
        self.meta = dict(meta or {})

    def mixture(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """For standardised inputs (b, inputs): the components' logits (b, k), means
        (b, k, d) and lower-triangular scales (b, k, d, d) over standardised outputs."""
        h = self.body(x)
        b, k, d = len(x), self.k, self.d
        scale = torch.zeros(b, k, d, d, dtype=x.dtype)
        diag = torch.arange(d)
        # The floor keeps a component from collapsing onto a training point.
        scale[:, :, diag, diag] = nn.functional.softplus(self.diag(h).view(b, k, d)) + 1e-3
        scale[:, :, self.below[0], self.below[1]] = self.off(h).view(b, k, -1)
        return self.logits(h), self.mean(h).view(b, k, d), scale

    def dist(self, x: torch.Tensor) -> MixtureSameFamily:
        """The mixture over standardised outputs for standardised inputs (b, inputs)."""
        logits, mean, scale = self.mixture(x)
        parts = MultivariateNormal(mean, scale_tril=scale)
        return MixtureSameFamily(Categorical(logits=logits), parts)

    @property
    def placed(self) -> bool:
        """Whether the network sees where the chain lies (`push_inputs`)."""
        return bool(self.meta.get("placed", False))

    def _x(self, inputs: np.ndarray) -> torch.Tensor:
        return (torch.as_tensor(inputs, dtype=torch.float32) - self.x_mean) / self.x_std

    def _inputs(
        self, start: np.ndarray, action: np.ndarray, masses: np.ndarray, friction: np.ndarray,
        lengths: np.ndarray,
    ) -> torch.Tensor:  # fmt: skip
        return self._x(push_inputs(start, action, masses, friction, lengths, self.placed))

    def _y(self, outputs: np.ndarray) -> torch.Tensor:
        return (torch.as_tensor(outputs, dtype=torch.float32) - self.y_mean) / self.y_std

    @torch.no_grad()
    def log_prob(
        self, start: np.ndarray, action: np.ndarray, observed: np.ndarray, masses: np.ndarray,
        friction: np.ndarray, lengths: np.ndarray,
    ) -> np.ndarray:  # fmt: skip
        """Log-density (m,) of the `observed` rest pose after `action` from `start`, under
        each of m particles' masses and frictions (up to a constant common to all)."""
        dist = self.dist(self._inputs(start, action, masses, friction, lengths))
        return dist.log_prob(self._y(push_outputs(start, observed))).double().numpy()

    @torch.no_grad()
    def cross_log_prob(
        self, start: np.ndarray, action: np.ndarray, observed: np.ndarray, masses: np.ndarray,
        friction: np.ndarray, lengths: np.ndarray,
    ) -> np.ndarray:  # fmt: skip
        """Log-density (q, m) of each of q `observed` rest poses under each of m particles."""
        dist = self.dist(self._inputs(start, action, masses, friction, lengths))
        y = self._y(push_outputs(start, observed))
        return dist.log_prob(y[:, None, :]).double().numpy()

    @torch.no_grad()
    def sample(
        self, start: np.ndarray, action: np.ndarray, masses: np.ndarray, friction: np.ndarray,
        lengths: np.ndarray, rng: np.random.Generator,
    ) -> np.ndarray:  # fmt: skip
        """One observed rest pose (m, d) per particle, drawn with `rng` (so a seeded filter
        stays deterministic)."""
        logits, means, scales = self.mixture(self._inputs(start, action, masses, friction, lengths))
        m, k, d = means.shape
        p = torch.softmax(logits, dim=-1).double().numpy()
        pick = (rng.uniform(size=(m, 1)) > np.cumsum(p, axis=1)).sum(axis=1).clip(0, k - 1)
        rows = np.arange(m)
        mean, scale = means.double().numpy()[rows, pick], scales.double().numpy()[rows, pick]
        y = mean + np.einsum("mij,mj->mi", scale, rng.normal(size=(m, d)))
        y = y * self.y_std.numpy() + self.y_mean.numpy()
        return rest_poses(start, y)

    def digest(self) -> str:
        """A short fingerprint of the weights (recorded with the filter's settings)."""
        h = hashlib.sha256()
        for value in self.state_dict().values():
            h.update(value.detach().cpu().numpy().tobytes())
        return h.hexdigest()[:12]

    def save(self, path: str | os.PathLike) -> None:
        torch.save({"format": FORMAT, "arch": self.arch, "meta": self.meta,
                    "state": self.state_dict()}, path)  # fmt: skip


def load_push_density(path: str | os.PathLike) -> PushDensity:
    """A model file written by `train_push_density`; a file that is not one is a one-line
    error naming it."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"push density {path}: a directory, not a model file")
    if not path.is_file():
        raise ValueError(f"push density {path}: no such file")
    try:
        blob = torch.load(path, map_location="cpu", weights_only=False)
        if not isinstance(blob, dict) or blob.get("format") != FORMAT:
            raise ValueError("not a push density model file")
        net = PushDensity(**blob["arch"], meta=blob["meta"])
        net.load_state_dict(blob["state"])
    except Exception as err:
        raise ValueError(f"push density {path}: cannot be read ({err})") from None
    return net.eval()


def check_density(net: PushDensity, path: str | os.PathLike, expected: dict) -> None:
    """Refuse a density trained for other chains, another pusher or other noise than the
    filter's (`expected`: the same keys as `net.meta`'s)."""
    for key, want in expected.items():
        have = net.meta.get(key)
        if have is not None and not _same(have, want):
            raise ValueError(f"push density {path} was trained for {key} {have!r}, not {want!r}")


def density_for(path: str | os.PathLike, env_config: Any) -> PushDensity:
    """The push density at `path`, checked against the chains, pusher and noise of
    `env_config` (an `EnvConfig`) that a filter will weigh with it."""
    net = load_push_density(path)
    physics = env_config.physics
    check_density(net, path, {
        "n_links": physics.n_links, "pusher": env_config.pusher,
        "mass_range": list(physics.mass_range), "friction_range": list(physics.friction_range),
        "obs_noise": env_config.obs_noise, "action_noise": env_config.action_noise,
    })  # fmt: skip
    if net.meta.get("actions") == "executed":
        warnings.warn(
            f"push density {path} was trained on the pushes as executed: the filter weighs "
            "each push's speed as the robot reports it but its contact point as commanded "
            "(no robot reports the point it touched)",
            stacklevel=2,
        )
    return net


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, (list, tuple)) or isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) or isinstance(b, float):
        return bool(np.isclose(float(a), float(b)))
    return a == b


def density_meta(manifest: Any, physics: Any) -> dict:
    """What a density is trained for: the chain's links and priors, the pusher, the tool's
    friction, the noise."""
    return {
        "setting": manifest.setting["name"],
        "n_links": int(physics.n_links),
        "pusher": manifest.pusher,
        "mass_range": [float(v) for v in physics.mass_range],
        "friction_range": [float(v) for v in physics.friction_range],
        "obs_noise": float(manifest.obs_noise),
        "action_noise": float(manifest.action_noise),
        # Not checked against the filter's: the target world's tool takes the links' friction,
        # and a lab's own tool is what it measured (docs/real-robot.md).
        "tool_friction": float(physics.tool_friction),
        # "randomised": a likelihood of many worlds, broader than the setting's own
        "worlds": manifest.worlds,
    }


def train_push_density(config: DensityConfig, progress: bool = True) -> dict:
    """Train the density on the datasets' pushes; resumes from `OUT.ckpt`. Returns a
    summary: pushes trained on and held out, the held-out mean log-likelihood (of the
    standardised outcome, nats per push; higher is better), seconds."""
    from tqdm import tqdm

    from masspush.data.dataset import load_dataset, read_manifest
    from masspush.settings import Setting

    manifests = [read_manifest(d) for d in config.data]  # checks every directory first
    first = manifests[0]
    for path, other in zip(config.data[1:], manifests[1:], strict=True):
        for key in ("setting", "pusher", "obs_noise", "action_noise", "worlds"):
            if getattr(other, key) != getattr(first, key):
                raise ValueError(
                    f"data: {path} has {key} {getattr(other, key)!r}, "
                    f"{config.data[0]} has {getattr(first, key)!r}"
                )
    # The physics the episodes were collected in: a settings file's overrides (its tool's
    # friction, its prior) included, which the named built-in setting would not have.
    meta = density_meta(first, Setting.from_dict(first.setting).physics())
    placed = config.placed
    if placed is None:
        placed = pusher_kind(first.pusher).workspace is not None
    meta["placed"] = placed
    meta["actions"] = config.actions
    out, ckpt = Path(config.out), Path(f"{config.out}.ckpt")
    out.parent.mkdir(parents=True, exist_ok=True)
    fit, held = ([], []), ([], [])
    seen = []
    for d in config.data:
        _, episodes = load_dataset(d)
        seen.append(episodes.friction)
        cut = len(episodes.masses) - max(1, round(config.held_out * len(episodes.masses)))
        for part, rows in ((fit, slice(0, cut)), (held, slice(cut, None))):
            x, y = episode_pushes(episodes, rows, placed, config.actions)
            part[0].append(x)
            part[1].append(y)
    x_fit, y_fit = np.concatenate(fit[0]), np.concatenate(fit[1])
    # A mixture density network answers anything for inputs it never saw: the filter keeps
    # its friction prior to what the data held (one lab's episodes hold one friction).
    seen = np.concatenate(seen)
    meta["friction_seen"] = [float(seen.min()), float(seen.max())]
    x_held, y_held = np.concatenate(held[0]), np.concatenate(held[1])
    if not len(x_fit) or not len(x_held):  # said before training, not as a crash after it
        raise ValueError(
            f"data: {len(x_fit)} pushes to train on and {len(x_held)} held out "
            f"(held_out {config.held_out}); collect more episodes"
        )
    torch.manual_seed(config.seed)
    net = PushDensity(x_fit.shape[1], y_fit.shape[1], config.components, config.width,
                      config.depth, meta=meta)  # fmt: skip
    for name, values in (("x", x_fit), ("y", y_fit)):
        getattr(net, f"{name}_mean").copy_(torch.as_tensor(values.mean(0)))
        getattr(net, f"{name}_std").copy_(torch.as_tensor(values.std(0) + 1e-6))
    opt = torch.optim.Adam(net.parameters(), lr=config.lr)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, config.lr, total_steps=config.steps)
    gen = torch.Generator().manual_seed(config.seed)
    step, seconds = 0, 0.0
    recorded = {**asdict(config), "out": None, "checkpoint_every": None}
    if ckpt.is_file():
        state = torch.load(ckpt, map_location="cpu", weights_only=False)
        if state["config"] != recorded:
            raise ValueError(
                f"out: {ckpt} is a checkpoint of another training run; delete it to start over"
            )
        for part, key in ((net, "net"), (opt, "opt"), (sched, "sched")):
            part.load_state_dict(state[key])
        gen.set_state(state["gen"])
        step, seconds = state["step"], state["seconds"]
    xt = net._x(x_fit).detach()
    yt = net._y(y_fit).detach()
    started = time.perf_counter() - seconds
    bar = tqdm(total=config.steps, initial=step, desc="push density", disable=not progress)
    while step < config.steps:
        rows = torch.randint(len(xt), (config.batch_size,), generator=gen)
        loss = -net.dist(xt[rows]).log_prob(yt[rows]).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        step += 1
        bar.update()
        if step % 200 == 0:
            bar.set_postfix(nll=f"{loss.item():.3f}")
        if step % config.checkpoint_every == 0 and step < config.steps:
            torch.save({"config": recorded, "net": net.state_dict(), "opt": opt.state_dict(),
                        "sched": sched.state_dict(), "gen": gen.get_state(), "step": step,
                        "seconds": time.perf_counter() - started}, ckpt)  # fmt: skip
    bar.close()
    net.eval()
    with torch.no_grad():
        total = sum(
            net.dist(net._x(x_held[i : i + 8192]))
            .log_prob(net._y(y_held[i : i + 8192]))
            .sum()
            .item()
            for i in range(0, len(x_held), 8192)
        )
    held_ll = total / len(x_held)
    summary = {"pushes": len(x_fit), "held_out_pushes": len(x_held),
               "held_out_log_likelihood": held_ll, "steps": config.steps,
               "seconds": time.perf_counter() - started, "data": list(config.data)}  # fmt: skip
    net.meta["training"] = summary
    net.save(out)
    ckpt.unlink(missing_ok=True)
    return summary
