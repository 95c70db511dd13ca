"""Shipped models, in one place: finding them by name, loading any estimator, exporting.

The files themselves lie in the folder beside this module, `models/<setting>/<name>.pt`
(a predictor, with `<name>.policy.zip`, its learned policy, and `<name>.dirichlet.pt`, its
uncertainty head, where it has them). Names: rp, rp+, tp, tp+ (the paper's four), tp+dr
(TP+ fine-tuned in randomised worlds), and the particle filter's bayes and bayes-random,
which need no file.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from masspush.bayes.estimator import BAYES_MODELS, BayesEstimator
from masspush.evaluate import Estimator
from masspush.learn.estimator import PredictorEstimator
from masspush.learn.policy import model_policy, strip_policy
from masspush.learn.predictor import MassPredictor, load_model, save_model
from masspush.settings import Setting

SHIPPED_DIR = Path(__file__).parent / "models"
"""Trained models shipped with the package: models/<setting>/<name>.pt."""
SHIPPED_NAMES = ("rp", "rp+", "tp", "tp+", "tp+dr")


def resolve_model(model: str | os.PathLike, setting: str) -> Path:
    """A shipped model's file for `setting` (by name: rp, rp+, tp, tp+, tp+dr), or a path."""
    if str(model) in SHIPPED_NAMES:
        path = SHIPPED_DIR / setting / f"{model}.pt"
        if not path.exists():
            have = sorted(p.stem for p in (SHIPPED_DIR / setting).glob("*.pt"))
            raise ValueError(
                f"no shipped {model!r} model for setting {setting!r} yet"
                + (f" (shipped for it: {have})" if have else "")
            )
        return path
    path = Path(model)
    if path.is_dir():
        raise ValueError(f"{path} is a directory, not a model file")
    if not path.exists():
        raise ValueError(f"no model file at {path} (shipped names: {list(SHIPPED_NAMES)})")
    return path


def model_and_policy(
    model: str | os.PathLike, setting: str
) -> tuple[MassPredictor, dict[str, Any], Any]:
    """A model (shipped name or path) for `setting`: its predictor, metadata and the
    policy it was trained with (`masspush.learn.policy.model_policy`)."""
    path = resolve_model(model, setting)
    predictor, meta = load_model(path, setting)
    return predictor, meta, model_policy(meta, path)


def load_estimator(
    model: str | os.PathLike, setting: Setting, pusher: str | None = None,
    bayes: dict[str, Any] | None = None, progress: bool = True,
) -> Estimator:  # fmt: skip
    """The estimator called `model` for `setting`: the particle filter (bayes,
    bayes-random; its configuration changed by `bayes`, `BayesConfig` fields), or a
    predictor with its policy (a shipped name or a model file). `pusher` overrides the
    pusher the model was made for."""
    if str(model) in BAYES_MODELS:
        return BayesEstimator(setting, str(model), pusher, overrides=bayes, progress=progress)
    if bayes:
        raise ValueError(f"bayes options apply to the particle filter, not to {model!r}")
    path = resolve_model(model, setting.name)
    return PredictorEstimator.from_file(path, setting.name, pusher, name=str(model))


def ship_model(
    source: str | os.PathLike, target: str | os.PathLike, shared_policy: str | None = None
) -> list[Path]:
    """Export the predictor file `source` as `target` (a .pt path), with the learned policy
    its metadata names, stripped of its optimiser state, beside it as
    `<target stem>.policy.zip`; or, with `shared_policy`, naming that policy file, already
    beside `target`, instead. Returns the files written."""
    source, target = Path(source), Path(target)
    model, meta = load_model(source)
    target.parent.mkdir(parents=True, exist_ok=True)
    written = [target]
    if shared_policy is not None:
        meta = {**meta, "policy_file": shared_policy}
    elif meta.get("policy_file"):
        policy_target = target.with_name(f"{target.stem}.policy.zip")
        strip_policy(source.parent / meta["policy_file"], policy_target)
        meta = {**meta, "policy_file": policy_target.name}
        written.append(policy_target)
    save_model(target, model, meta)
    return written


def ship(setting: str, sources: Mapping[str, str | os.PathLike]) -> list[Path]:
    """Ship predictors as the package's models for `setting`: {name: predictor file}."""
    written: list[Path] = []
    for name, source in sources.items():
        if not Path(source).exists():
            raise ValueError(f"{source} does not exist: train the {name!r} model first")
        written += ship_model(source, SHIPPED_DIR / setting / f"{name}.pt")
    return written
