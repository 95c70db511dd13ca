"""Learned uncertainty: a Dirichlet head on a trained predictor.

The predictor's estimate p (a point on the simplex) stays what it was; a small head reads
the same LSTM features and gives a precision s, and the mass distribution is modelled as
Dirichlet(s * p). The head is fitted by maximum likelihood on fresh episodes of the
model's own policy (not the predictor's training episodes, on which it is overconfident),
with the predictor frozen. Each link's share is then Beta(s p_j, s (1 - p_j)), whose
central quantiles are the credible interval reported beside the Bayesian filter's.

The head ships beside its model as `<model>.dirichlet.pt`; `masspush evaluate` reports the
interval coverage whenever one is there.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from torch import nn

from masspush.data.rollout import Episodes
from masspush.learn.predictor import (
    Predictor,
    predictor_digest,
    read_torch_file,
    step_inputs,
)
from masspush.sim.pushers import IDEAL_PUSHER

if TYPE_CHECKING:
    from masspush.settings import Setting

FORMAT, VERSION = "masspush-dirichlet-head", 1


class StaleHeadError(ValueError):
    """A head fitted on another predictor's features (the model was retrained since)."""


@dataclass(frozen=True)
class HeadConfig:
    """The Dirichlet head: its size, its fit and the intervals it gives."""

    hidden: int = 32
    steps: int = 600
    """Full-batch Adam steps [ours]."""
    lr: float = 3e-3
    weight_decay: float = 1e-4
    episodes: int = 4000
    """Fresh episodes of the model's policy to fit the head on [ours]."""
    credible: float = 0.9
    seed: int = 0

    def __post_init__(self) -> None:
        if self.hidden < 1 or self.steps < 1 or self.episodes < 10:
            raise ValueError("hidden >= 1, steps >= 1 and episodes >= 10 are required")
        if not 0 < self.credible < 1:
            raise ValueError(f"credible must be in (0, 1), got {self.credible}")


class PrecisionHead(nn.Module):
    """LSTM features (.., 64) -> log precision (..)."""

    def __init__(self, in_dim: int = 64, hidden: int = 32):
        super().__init__()
        self.net = nn.Sequential(nn.Linear(in_dim, hidden), nn.ReLU(), nn.Linear(hidden, 1))
        nn.init.constant_(self.net[-1].bias, float(np.log(50.0)))  # a moderate start

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        return self.net(features).squeeze(-1)


def _inputs(predictor: Predictor, episodes: Episodes) -> tuple[torch.Tensor, torch.Tensor]:
    """(E, K, 64) features and (E, K, n) estimates, the predictor frozen."""
    q0, steps = step_inputs(episodes, predictor.features_kind)
    with torch.no_grad():
        predictor.eval()
        features = predictor.features(torch.as_tensor(q0), torch.as_tensor(steps))
        estimate = predictor.estimate(features)
    return features, estimate


def concentration(predictor: Predictor, head: PrecisionHead, episodes: Episodes) -> np.ndarray:
    """(E, K, n) Dirichlet concentrations after each push."""
    features, estimate = _inputs(predictor, episodes)
    with torch.no_grad():
        head.eval()
        return (torch.exp(head(features)).unsqueeze(-1) * estimate).numpy()


def fit_head(
    predictor: Predictor, episodes: Episodes, config: HeadConfig = HeadConfig()
) -> PrecisionHead:
    """Fit the precision head by the Dirichlet likelihood of the true distributions, keeping
    the parameters that score best on a held-out fifth of the episodes (a head that reads
    64 features memorises a few thousand episodes and then claims too much)."""
    torch.manual_seed(config.seed)
    features, estimate = _inputs(predictor, episodes)
    seen = torch.as_tensor(episodes.seen)
    truth = torch.as_tensor(episodes.mass_distribution, dtype=torch.float32).clamp_min(1e-4)
    truth = (truth / truth.sum(-1, keepdim=True)).unsqueeze(1).expand_as(estimate)
    held = torch.as_tensor(np.random.default_rng(config.seed).random(len(episodes)) < 0.2)
    held = held.unsqueeze(1).expand_as(seen)
    parts = [(features[seen & m], estimate[seen & m], truth[seen & m]) for m in (~held, held)]
    head = PrecisionHead(features.shape[-1], config.hidden)
    opt = torch.optim.Adam(head.parameters(), config.lr, weight_decay=config.weight_decay)

    def nll(x: torch.Tensor, p: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        alpha = torch.exp(head(x)).unsqueeze(-1) * p + 1e-6
        return -torch.distributions.Dirichlet(alpha).log_prob(y).mean()

    best, best_state = float("inf"), None
    for _ in range(config.steps):
        opt.zero_grad()
        nll(*parts[0]).backward()
        opt.step()
        with torch.no_grad():
            score = float(nll(*parts[1]))
        if score < best:
            best, best_state = score, {k: v.clone() for k, v in head.state_dict().items()}
    if best_state is not None:
        head.load_state_dict(best_state)
    head.eval()
    return head


def intervals(
    alpha: np.ndarray, credible: float = 0.9, samples: int = 4000, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Central credible intervals of each share under Dirichlet(alpha) (.., n): its Beta
    marginals' quantiles, by sampling (torch has no Beta quantile function)."""
    gen = torch.Generator().manual_seed(seed)
    a = torch.as_tensor(alpha, dtype=torch.float64)
    b = a.sum(-1, keepdim=True) - a
    # Beta(a, b) = X / (X + Y) with X ~ Gamma(a), Y ~ Gamma(b).
    x = torch._standard_gamma(a.expand(samples, *a.shape).contiguous(), generator=gen)
    y = torch._standard_gamma(b.expand(samples, *b.shape).contiguous(), generator=gen)
    draws = x / (x + y)
    tail = (1 - credible) / 2
    q = torch.quantile(draws, torch.tensor([tail, 1 - tail], dtype=torch.float64), dim=0)
    return q[0].numpy(), q[1].numpy()


def coverage(
    predictor: Predictor, head: PrecisionHead, episodes: Episodes, credible: float = 0.9
) -> float:
    """Share of true per-link values inside the intervals after each episode's last push."""
    alpha = concentration(predictor, head, episodes)
    final = alpha[np.arange(len(alpha)), episodes.last_seen()]
    low, high = intervals(final, credible)
    truth = episodes.mass_distribution
    return float(np.mean((low <= truth) & (truth <= high)))


class LearnedPosterior:
    """A trained predictor with its Dirichlet head, read as a density over the mass
    distribution given an episode's history (what `experiments/bayes/pool_learned.py` pools with the
    particle filter's posterior)."""

    def __init__(self, predictor: Predictor, head: PrecisionHead):
        self.predictor, self.head = predictor, head

    @classmethod
    def load(cls, path: str | os.PathLike, setting: str) -> LearnedPosterior:
        """A model file for `setting` (`masspush.models.resolve_model` finds a shipped
        one's), and its head beside it."""
        from masspush.learn.predictor import load_model

        model = Path(path).stem
        predictor, _ = load_model(path, setting)
        if not head_path(path).exists():
            raise ValueError(
                f"model {model!r} for {setting!r} has no Dirichlet head ({head_path(path)}); "
                f"fit one with `masspush calibrate --setting {setting} --model {model}`"
            )
        return cls(predictor, load_head(head_path(path), setting, predictor))

    def concentration(self, history: Episodes) -> np.ndarray:
        """(n,) the Dirichlet's concentration after the last push of a one-episode history."""
        return concentration(self.predictor, self.head, history)[0, -1]

    def log_density(self, history: Episodes, shares: np.ndarray) -> np.ndarray:
        """(m,) log Dirichlet density of the distributions `shares` (m, n) after the last
        push, up to a constant."""
        alpha = self.concentration(history)
        return np.log(np.clip(shares, 1e-12, None)) @ (alpha - 1.0)


def head_path(model_file: str | os.PathLike) -> Path:
    model_file = Path(model_file)
    return model_file.with_name(f"{model_file.stem}.dirichlet.pt")


def save_head(path: str | os.PathLike, head: PrecisionHead, meta: dict[str, Any]) -> Path:
    path = Path(path)
    torch.save({"format": FORMAT, "version": VERSION, "state_dict": head.state_dict(),
                "hidden": head.net[0].out_features, "in_dim": head.net[0].in_features,
                "meta": meta}, path)  # fmt: skip
    return path


def load_head(
    path: str | os.PathLike, setting: str | None = None, predictor: Predictor | None = None
) -> PrecisionHead:
    """A saved head; refused for another setting than `setting`, and (`StaleHeadError`) for
    another predictor than `predictor`: a head reads the features of the one it was fitted
    on, and those of a retrained model mean something else."""
    payload = read_torch_file(path, "Dirichlet head")
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise ValueError(f"{path} is not a masspush Dirichlet head")
    meta = payload["meta"]
    if setting is not None and meta.get("setting") != setting:
        raise ValueError(f"{path} belongs to setting {meta.get('setting')!r}, not {setting!r}")
    if predictor is not None and meta.get("predictor") != predictor_digest(predictor):
        raise StaleHeadError(
            f"{path} was fitted on another predictor than {meta.get('model', 'its model')!r} "
            f"is now; refit it with `masspush calibrate --setting {meta.get('setting')} "
            f"--model {meta.get('model', '<model>')}`"
        )
    head = PrecisionHead(payload["in_dim"], payload["hidden"])
    head.load_state_dict(payload["state_dict"])
    head.eval()
    return head


def calibrate(
    setting: Setting,
    path: str | os.PathLike,
    config: HeadConfig = HeadConfig(),
    out: str | os.PathLike | None = None,
    workers: int | None = None,
    model: str | None = None,
) -> dict[str, Any]:
    """Fit and save the Dirichlet head of the model file `path` (named `model` in the head's
    metadata, the file by default) on fresh episodes of its policy."""
    from masspush.data.rollout import TRAIN, run_episodes
    from masspush.learn.policy import model_policy
    from masspush.learn.predictor import load_model

    model = model or str(path)
    predictor, meta = load_model(path, setting.name)
    env_config = setting.env_config(meta.get("pusher", IDEAL_PUSHER))
    # Base seed 7919: a stream the recipes' collections (base seeds 0-99) never use.
    run = run_episodes(
        env_config, model_policy(meta, path), np.arange(config.episodes), TRAIN, 7919, workers
    )
    good = run.select(run.ok)
    head = fit_head(predictor, good, config)
    target = Path(out) if out else head_path(path)
    save_head(target, head, {"setting": setting.name, "model": str(model),
                             "predictor": predictor_digest(predictor),
                             "config": asdict(config), "episodes": len(good)})  # fmt: skip
    return {"file": str(target), "episodes": len(good),
            "coverage_on_fit": coverage(predictor, head, good, config.credible)}  # fmt: skip
