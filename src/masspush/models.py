"""Shipped models, in one place: finding them by name, loading any estimator, exporting.

The files themselves lie in the folder beside this module, `models/<setting>/<name>.pt`
(a predictor, with `<name>.policy.zip`, its learned policy, and `<name>.dirichlet.pt`, its
uncertainty head, where it has them). Names: rp, rp+, tp, tp+ (the paper's four), tp+dr
(TP+ fine-tuned in randomised worlds), and the particle filter's bayes and bayes-random,
which need no file.
"""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from masspush.bayes.estimator import BAYES_MODELS, BayesEstimator
from masspush.cluster.pool import open_pool
from masspush.config import check_match, check_output
from masspush.evaluate import Estimator, EvalResult, EvaluateConfig, evaluate
from masspush.learn.estimator import PredictorEstimator
from masspush.learn.policy import model_policy, strip_policy
from masspush.learn.predictor import Predictor, load_model, save_model
from masspush.learn.push_density import PUSH_DENSITY_FILE, density_for
from masspush.learn.uncertainty import (
    HeadConfig,
    StaleHeadError,
    calibrate,
    head_path,
    load_head,
)
from masspush.settings import Setting, get_setting

SHIPPED_DIR = Path(__file__).parent / "models"
"""Trained models shipped with the package: models/<setting>/<name>.pt."""
SHIPPED_NAMES = ("rp", "rp+", "tp", "tp+", "tp+dr")


def shipped_file(setting: str, name: str) -> Path:
    """Where the shipped model `name` of `setting` lies (or would lie)."""
    return SHIPPED_DIR / setting / f"{name}.pt"


def shipped_density(setting: str) -> Path:
    """Where the shipped push density of `setting` lies (or would lie)."""
    return shipped_file(setting, Path(PUSH_DENSITY_FILE).stem)


def resolve_model(model: str | os.PathLike, setting: str) -> Path:
    """A shipped model's file for `setting` (by name: rp, rp+, tp, tp+, tp+dr), or a path."""
    if str(model) in SHIPPED_NAMES:
        path = shipped_file(setting, str(model))
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
) -> tuple[Predictor, dict[str, Any], Any]:
    """A model (shipped name or path) for `setting`: its predictor, metadata and the
    policy it was trained with (`masspush.learn.policy.model_policy`)."""
    path = resolve_model(model, setting)
    predictor, meta = load_model(path, setting)
    return predictor, meta, model_policy(meta, path)


def load_estimator(
    model: str | os.PathLike, setting: Setting, pusher: str | None = None,
    bayes: dict[str, Any] | None = None, progress: bool = True, allow_mismatch: bool = False,
) -> Estimator:  # fmt: skip
    """The estimator called `model` for `setting`: the particle filter (bayes,
    bayes-random; its configuration changed by `bayes`, `BayesConfig` fields; with the
    setting's shipped push density as its likelihood where there is one and the pusher is
    the setting's, unless `bayes` says likelihood=simulator), or a
    predictor with its policy (a shipped name or a model file). `pusher` overrides the
    pusher the model was made for."""
    if str(model) in BAYES_MODELS:
        bayes, density = dict(bayes or {}), None
        shipped = shipped_density(setting.name)
        if "likelihood" not in bayes and shipped.exists() and pusher in (None, setting.pusher):
            # A shipped density is the setting's default likelihood: in the KUKA cells it
            # halves the error of simulating the arm per particle, at a twentieth of the time
            # (docs/notebook/2026-12-04-learned-likelihood.md).
            bayes["likelihood"] = "learned"
        if bayes.get("likelihood") == "learned":
            # density None (recorded so) is the shipped one; a file given is recorded by name
            path = bayes.get("density") or shipped
            if bayes.get("density") is None and not shipped.exists():
                raise ValueError(
                    f"no shipped push density for setting {setting.name!r}: train one "
                    "(`masspush train-density`) and pass --bayes density=FILE"
                )
            # a bad file is refused before any episode
            density = density_for(path, setting.env_config(pusher))
        return BayesEstimator(
            setting, str(model), pusher, overrides=bayes or None, progress=progress,
            density=density,
        )  # fmt: skip
    if bayes:
        raise ValueError(f"bayes options apply to the particle filter, not to {model!r}")
    path = resolve_model(model, setting.name)
    return PredictorEstimator.from_file(
        path, setting.name, pusher, str(model), allow_mismatch, setting.n_links
    )


def ship_model(
    source: str | os.PathLike, target: str | os.PathLike, shared_policy: str | None = None
) -> list[Path]:
    """Export the predictor file `source` as `target` (a .pt path), with the learned policy
    its metadata names, stripped of its optimiser state, beside it as
    `<target stem>.policy.zip`; or, with `shared_policy`, naming that policy file, already
    beside `target`, instead. A Dirichlet head beside `target` fitted on another predictor is
    removed (`masspush calibrate` fits a new one). Returns the files written."""
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
    stale = head_path(target)
    if stale.exists():  # fitted on the model this one replaces
        try:
            load_head(stale, predictor=model)
        except StaleHeadError:
            stale.unlink()
            warnings.warn(
                f"removed {stale}: fitted on the model {target.name} replaced; fit one for the "
                f"new model with `masspush calibrate --setting "
                f"{meta.get('setting', {}).get('name')} --model {target}`",
                stacklevel=2,
            )
    return written


def ship(setting: str, sources: Mapping[str, str | os.PathLike]) -> list[Path]:
    """Ship predictors as the package's models for `setting`: {name: predictor file}."""
    written: list[Path] = []
    for name, source in sources.items():
        if not Path(source).exists():
            raise ValueError(f"{source} does not exist: train the {name!r} model first")
        written += ship_model(source, shipped_file(setting, name))
    return written


def evaluate_model(
    config: EvaluateConfig, bayes: dict[str, Any] | None = None, progress: bool = True
) -> EvalResult:
    """`masspush evaluate`: the estimator `config.model` on fresh episodes, paired with an
    earlier result where `config.paired_with` names one (read before any work)."""
    spec = get_setting(config.setting, config.settings_file)
    other = None
    if config.paired_with is not None:
        try:
            other = json.loads(Path(config.paired_with).read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
            raise ValueError(
                f"paired_with: {config.paired_with} is not a result's JSON ({err})"
            ) from None
        if not isinstance(other, dict) or "per_episode" not in other:
            raise ValueError(
                f"paired_with: {config.paired_with} has no per-episode record (--per-episode)"
            )
        # Pairing matches episodes by number: only the same stream has the same chains.
        where = f"paired_with: {config.paired_with}"
        for what, ours in (("setting", spec.name), ("seed", config.seed)):
            check_match(what, where, other.get(what), ours, config.allow_mismatch)
    estimator = load_estimator(
        config.model, spec, config.pusher, bayes, progress, config.allow_mismatch
    )
    with open_pool(config.ray, config.workers) as workers:
        result = evaluate(
            spec, estimator, config.episodes, config.seed, workers,
            per_episode=config.per_episode or other is not None,
        )  # fmt: skip
    if other is not None:
        result.pair_with(other)
    return result


@dataclass(frozen=True)
class CalibrateJob:
    """`masspush calibrate`: fit a model's learned uncertainty (a Dirichlet head)."""

    setting: str
    """Named setting of the model."""
    model: str = "tp+"
    """Shipped name or file of the predictor."""
    out: str | None = None
    """Where to write the head (default: <model>.dirichlet.pt beside it, where
    `masspush evaluate` finds it)."""
    settings_file: str | None = None
    """TOML file with custom settings."""

    def __post_init__(self) -> None:
        if self.out is not None:
            check_output(self.out, "out")


def calibrate_model(job: CalibrateJob, head: HeadConfig) -> str:
    """Fit and save the model's head on fresh episodes of its policy; the report."""
    setting = get_setting(job.setting, job.settings_file)
    path = resolve_model(job.model, setting.name)
    result = calibrate(setting, path, head, job.out, model=job.model)
    return (
        f"wrote {result['file']} (fitted on {result['episodes']} episodes; 90 % intervals "
        f"cover {100 * result['coverage_on_fit']:.1f} % of them); "
        f"`masspush evaluate --setting {setting.name} --model {job.model}` reports coverage"
    )
