"""The Bayesian estimator beside Table 1: error, interval coverage and time per episode, and
the learned TP+ predictor's own coverage (its Dirichlet head), in every setting.

Each measurement is cached as results/bayes/<setting>-<model>.json, so an interrupted
`masspush bayes-table` resumes with what is missing; the table is rebuilt from the cache.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from masspush.bayes.estimator import BAYES_MODELS
from masspush.bayes.filter import filter_for
from masspush.cluster.pool import Workers, check_address, open_pool
from masspush.config import check_int
from masspush.evaluate import evaluate
from masspush.metrics import paired_difference_interval, paired_percentage_errors
from masspush.models import load_estimator, resolve_model
from masspush.reports.baselines import PAPER_TABLE, paper_settings
from masspush.settings import get_setting

MODELS = ("bayes", "bayes-random", "tp+")
ADDED_SETTINGS = {"arm_model": "arm", "simulated_pusher": "stiff", "move_sweeps": 0,
                  "move_scale": 0.5}  # fmt: skip
"""Filter settings recorded only since later versions, with the values that describe the
measurements made before: they simulated the stiff pusher (an arm's surrogate where an arm
pushed), `arm_model` did not act where the stiff pusher pushes, and resampling jittered the
particles (Liu-West) instead of moving them by Metropolis-Hastings."""


PAIRED = "-same-episodes"
"""Cache suffix of TP+ measured on the filter's episodes (the first `episodes` of the
evaluation stream, the same chains and noise): Table 1's TP+ figure comes from 800
episodes, and the first few dozen are not an average sample of them. The two are compared
on the episodes both scored (`paired_percentage_errors`)."""


def cache_path(root: str | Path, setting: str, model: str, suffix: str = "") -> Path:
    """Where one setting's and model's measurement is cached."""
    return Path(root) / "results" / "bayes" / f"{setting}-{model}{suffix}.json"


def measure(
    setting: str,
    model: str,
    episodes: int,
    root: str | Path = ".",
    seed: int = 0,
    suffix: str = "",
    workers: Workers = None,
) -> dict[str, Any]:
    """One setting and model on `episodes` fresh evaluation episodes, cached under the
    model's name and `suffix`; for the paired comparison (the filter, and TP+ on its
    episodes) with each episode's estimate."""
    paired = model == "bayes" or suffix == PAIRED
    path = cache_path(root, setting, model, suffix)
    files = None if model in BAYES_MODELS else model_files_digest(setting, model)
    if path.exists():
        cached = json.loads(path.read_text())
        if (
            cached.get("requested_episodes") == episodes
            and (files is None or cached.get("model_files") == files)
            and (model not in BAYES_MODELS
                 or {**ADDED_SETTINGS, **cached.get("filter", {})} == filter_settings(setting))
            and (not paired or "per_episode" in cached)
        ):  # fmt: skip
            return cached
    result = run_model(setting, model, episodes, seed, paired, workers)
    result["requested_episodes"] = episodes
    if files is not None:
        result["model_files"] = files
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(result, indent=2) + "\n")
    return result


def run_model(
    setting: str, model: str, episodes: int, seed: int, per_episode: bool,
    workers: Workers = None,
) -> dict:  # fmt: skip
    """`masspush evaluate`'s JSON for one setting and model."""
    spec = get_setting(setting)
    estimator = load_estimator(model, spec)
    return evaluate(spec, estimator, episodes, seed, workers, per_episode).to_dict()


def model_files_digest(setting: str, model: str) -> str:
    """sha256 of a learned model's files (predictor, policy, Dirichlet head): a measurement
    cached for a model since retrained or recalibrated is measured again."""
    path = resolve_model(model, setting)
    digest = hashlib.sha256()
    for part in (path, path.with_name(f"{path.stem}.policy.zip"),
                 path.with_name(f"{path.stem}.dirichlet.pt")):  # fmt: skip
        digest.update(part.name.encode())
        digest.update(part.read_bytes() if part.exists() else b"absent")
    return digest.hexdigest()


def filter_settings(setting: str) -> dict[str, Any]:
    """The particle filter's configuration for `setting` as `evaluate` would run it, as it
    reads back from JSON: a cached measurement with another one is measured again."""
    spec = get_setting(setting)
    estimator = load_estimator("bayes", spec, progress=False)  # the shipped density, if any
    filt = filter_for(spec, estimator.pusher, estimator.config, density=estimator.density)
    try:
        return json.loads(json.dumps(filt.settings()))
    finally:
        filt.close()


def table_markdown(rows: list[dict[str, Any]]) -> str:
    def num(value: float | None, fmt: str = "{:.2f}") -> str:
        return "not yet" if value is None else fmt.format(value)

    def pct(value: float | None) -> str:
        return "not yet" if value is None else f"{100 * value:.0f} %"

    lines = [
        "| setting | TP+ ours / paper | Bayes, info-seeking "
        "| Bayes / TP+ on the episodes both scored (how many; 95 % interval of the difference) "
        "| Bayes, random pushes "
        "| coverage of 90 % intervals: Bayes / Bayes-random / TP+ (Dirichlet) "
        "| Bayes s per episode | episodes (Bayes) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        b, br, tp = r.get("bayes"), r.get("bayes-random"), r.get("tp+")
        same = r.get("tp+" + PAIRED)
        if b and same and "per_episode" in b and "per_episode" in same:
            bayes_err, tp_err, n = paired_percentage_errors(b["per_episode"],
                                                            same["per_episode"])  # fmt: skip
            low, high = paired_difference_interval(b["per_episode"], same["per_episode"])
            paired = f"{bayes_err:.2f} / {tp_err:.2f} ({n}; {low:+.2f} to {high:+.2f})"
        else:
            paired = "not yet"
        lines.append(
            f"| {r['setting']} | {num(tp and tp['percentage_error'])} / "
            f"{PAPER_TABLE[r['setting']]['tp+']:.2f} "
            f"| **{num(b and b['percentage_error'])}** | {paired} "
            f"| {num(br and br['percentage_error'])} "
            f"| {pct(b and b['coverage'])} / {pct(br and br['coverage'])} / "
            f"{pct(tp and tp.get('coverage'))} "
            f"| {num(b and b['seconds_per_episode'], '{:.1f}')} "
            f"| {num(b and b['episodes'], '{}')} |"
        )
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class BayesTableConfig:
    """`masspush bayes-table`: the Bayesian estimator and the learned uncertainty beside
    Table 1 (each measurement cached: a rerun resumes)."""

    settings: str = "all"
    """all, or a comma-separated list of named settings."""
    episodes: int = 50
    """Episodes per setting for the filter (and TP+ on the same episodes)."""
    models: tuple[str, ...] = MODELS
    """The estimators to measure."""
    tp_episodes: int = 800
    """Episodes for TP+'s own figure and its coverage."""
    table_only: bool = False
    """Only rebuild the table from the cache."""
    ray: str | None = None
    """Run the episodes on a Ray cluster: auto, local, ray://HOST:PORT or HOST:PORT
    (pip install 'masspush[ray]')."""

    def names(self) -> list[str]:
        return paper_settings(self.settings)

    def __post_init__(self) -> None:
        self.names()  # each named setting exists
        check_address(self.ray)
        check_int("episodes", self.episodes)
        check_int("tp_episodes", self.tp_episodes)
        unknown = set(self.models) - set(MODELS)
        if unknown:
            raise ValueError(f"models must be among {list(MODELS)}, got {sorted(unknown)}")


def bayes_table_run(config: BayesTableConfig) -> str:
    """The table (Markdown), measuring what is missing unless `table_only`."""
    with open_pool(None if config.table_only else config.ray) as workers:
        return bayes_table(
            config.names(), config.episodes, config.models, tp_episodes=config.tp_episodes,
            measure_missing=not config.table_only, workers=workers,
        )  # fmt: skip


def bayes_table(
    settings: Sequence[str],
    episodes: int,
    models: Sequence[str] = MODELS,
    root: str | Path = ".",
    tp_episodes: int = 800,
    measure_missing: bool = True,
    workers: Workers = None,
) -> str:
    """Measure what is missing (unless told not to), then write results/bayes.md. With TP+
    among the models, TP+ is measured twice: on `tp_episodes` (Table 1's figure and its
    coverage) and on the filter's `episodes` (the paired comparison). The table also keeps
    the cached rows of the settings not asked for, so that measuring one setting does not
    drop the others from it."""
    rows = []
    for setting in dict.fromkeys([*paper_settings("all"), *settings]):
        asked = setting in settings
        row: dict[str, Any] = {"setting": setting}
        runs = [(m, tp_episodes if m == "tp+" else episodes, "") for m in models]
        if "tp+" in models:
            runs.append(("tp+", episodes, PAIRED))
        for model, n, suffix in runs:
            path = cache_path(root, setting, model, suffix)
            if measure_missing and asked:
                row[model + suffix] = measure(setting, model, n, root, suffix=suffix,
                                              workers=workers)  # fmt: skip
            elif path.exists():
                row[model + suffix] = json.loads(path.read_text())
        if asked or len(row) > 1:
            rows.append(row)
    text = table_markdown(rows)
    out = Path(root) / "results" / "bayes.md"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    return text
