"""The paper's random-policy baselines RP and RP+ for one setting, as resumable stages.

    collect (RP+'s episodes; RP uses the first half) -> train RP -> train RP+
    -> evaluate both on 800 fresh episodes -> results/<setting>.json

Every stage resumes: the collection computes only missing shards, training continues from
its last checkpoint, and finished stages are skipped. `ship` copies the trained predictors
into the package so that `masspush evaluate --model rp` works after install.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from masspush.cluster.pool import Workers, check_address, open_pool
from masspush.config import check_int
from masspush.data.dataset import code_version, collect, load_dataset
from masspush.evaluate import evaluate
from masspush.learn.estimator import PredictorEstimator
from masspush.learn.predictor import FAST, TrainConfig, train_predictor
from masspush.models import ship
from masspush.settings import get_setting
from masspush.sim.pushers import pusher_field, pusher_kind

# Episodes for RP and RP+ [paper Sec. 4.1]: 32k / 64k (2 links), 64k / 128k (3 links).
EPISODES = {2: (32_000, 64_000), 3: (64_000, 128_000)}


@dataclass(frozen=True)
class BaselinesConfig:
    """`masspush baselines`: the paper's RP and RP+ for a setting (resumable)."""

    setting: str | None = None
    """Named setting (needed unless --table)."""
    table: bool = False
    """Print the table of every setting's results and stop."""
    pusher: str | None = pusher_field()
    """The pusher (default: the setting's, `masspush.settings`)."""
    fast: bool = False
    """Train with the fast option (Adam, batch 256, 20k steps)."""
    features: str | None = None
    """The predictor's input features: paper or relative (default: the training option's)."""
    episodes: tuple[int, int] | None = None
    """Episodes for RP and RP+ (default: the paper's)."""
    eval_episodes: int = 800
    """Fresh episodes each model is evaluated on."""
    ship: bool = False
    """Ship the trained models into the package."""
    ship_only: bool = False
    """Only ship models already trained."""
    ray: str | None = None
    """Run the collection and the evaluations on a Ray cluster: auto, local,
    ray://HOST:PORT or HOST:PORT (pip install 'masspush[ray]')."""

    def __post_init__(self) -> None:
        if self.setting is None and not self.table:
            raise ValueError("setting is required (unless --table)")
        check_address(self.ray)
        if self.pusher is not None:
            pusher_kind(self.pusher)
        check_int("eval_episodes", self.eval_episodes)
        if self.episodes is not None:
            for n in self.episodes:
                check_int("episodes", n, 2)


def baselines(config: BaselinesConfig) -> list[str]:
    """`masspush baselines`: the table, or the baselines run (and shipped); the report."""
    if config.table:
        return [baselines_table(config.pusher)]
    pusher = config.pusher or get_setting(config.setting).pusher
    lines = []
    if not config.ship_only:
        train = FAST if config.fast else TrainConfig()
        if config.features:
            train = replace(train, features=config.features)
        with open_pool(config.ray) as workers:
            results = run_baselines(
                config.setting, pusher, train, eval_episodes=config.eval_episodes,
                episodes=config.episodes, workers=workers,
            )  # fmt: skip
        for name, r in results["models"].items():
            lines.append(
                f"{name:4s} percentage error {r['percentage_error']:6.2f}  relative "
                f"{r['relative_error']:6.2f}  (constant floor {r['constant_floor']:.2f}, "
                f"evaluated on {r['episodes']} episodes, {r['failures']} failed)"
            )
        lines.append(f"timings: {results['timings']}")
    if config.ship or config.ship_only:
        lines += [f"shipped {path}" for path in ship_baselines(config.setting, pusher)]
    return lines


def baseline_paths(setting: str, pusher: str, root: str | Path = ".") -> dict[str, Path]:
    root = Path(root)
    return {
        "data": root / "data" / f"{setting}-{pusher}-random",
        "rp": root / "runs" / f"{setting}-{pusher}-rp",
        "rp+": root / "runs" / f"{setting}-{pusher}-rp+",
        "results": root / "results" / f"{setting}-{pusher}-baselines.json",
    }


def run_baselines(
    setting: str,
    pusher: str,
    train: TrainConfig,
    eval_episodes: int = 800,
    eval_seed: int = 0,
    root: str | Path = ".",
    episodes: tuple[int, int] | None = None,
    workers: Workers = None,
) -> dict[str, Any]:
    """Collect, train RP and RP+, evaluate (episodes on `workers`: local processes or a
    cluster's pool); returns (and writes) the results with timings."""
    spec = get_setting(setting)
    n_rp, n_rp_plus = episodes or EPISODES[spec.n_links]
    paths = baseline_paths(setting, pusher, root)
    timings: dict[str, float] = {}

    t0 = time.perf_counter()
    collect(spec, paths["data"], episodes=n_rp_plus, pusher=pusher, workers=workers)
    timings["collect_s"] = time.perf_counter() - t0

    results: dict[str, Any] = {
        "setting": setting,
        "pusher": pusher,
        "code_version": code_version(),
        "train_config": asdict(train),
        "models": {},
    }
    for name, n in (("rp", n_rp), ("rp+", n_rp_plus)):
        manifest, data = load_dataset(paths["data"], limit=n)
        meta = {
            "setting": manifest.setting,
            "pusher": pusher,
            "policy": "random",
            "dataset": str(paths["data"]),
            "dataset_episodes": n,
            "code_version": code_version(),
            "baseline": name,
        }
        t0 = time.perf_counter()
        _, summary = train_predictor(data, paths[name], replace(train), meta)
        timings[f"train_{name}_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        estimator = PredictorEstimator.from_file(paths[name] / "predictor.pt", spec.name)
        scores = evaluate(spec, estimator, eval_episodes, eval_seed, workers).to_dict()
        timings[f"evaluate_{name}_s"] = time.perf_counter() - t0
        results["models"][name] = {
            "train_episodes": n,
            "usable_episodes": summary["episodes"],
            "best_step": summary["best_step"],
            "samples_per_s": summary["samples_per_s"],
            **scores,
        }
    results["timings"] = timings
    paths["results"].parent.mkdir(parents=True, exist_ok=True)
    paths["results"].write_text(json.dumps(results, indent=2))
    return results


def ship_baselines(setting: str, pusher: str, root: str | Path = ".") -> list[Path]:
    """Ship the trained RP and RP+ predictors as the package's models for `setting`."""
    paths = baseline_paths(setting, pusher, root)
    return ship(setting, {name: paths[name] / "predictor.pt" for name in ("rp", "rp+")})


# The paper's Table 1, percentage error (its metric as coded) [paper, Table 1].
PAPER_TABLE = {
    "2link-0.1-1": {"rp": 15.26, "rp+": 14.80, "tp": 10.39, "tp+": 6.07},
    "2link-1-10": {"rp": 17.12, "rp+": 17.40, "tp": 14.03, "tp+": 8.26},
    "2link-0.1-10": {"rp": 26.68, "rp+": 26.78, "tp": 21.27, "tp+": 12.03},
    "3link-0.1-1": {"rp": 29.08, "rp+": 28.88, "tp": 26.89, "tp+": 12.02},
    "3link-1-10": {"rp": 30.88, "rp+": 30.84, "tp": 29.75, "tp+": 15.99},
    "3link-0.1-10": {"rp": 54.28, "rp+": 53.59, "tp": 50.49, "tp+": 23.93},
}


def paper_settings(text: str) -> list[str]:
    """ "all" (the paper's six settings) or a comma-separated list of named settings, each
    checked to exist."""
    names = list(PAPER_TABLE) if text == "all" else text.split(",")
    for name in names:
        get_setting(name)
    return names


def baselines_table(pusher: str | None = None, root: str | Path = ".") -> str:
    """Markdown: measured RP / RP+ beside the paper's, for every setting with results, each
    with `pusher` (default: the setting's own)."""
    lines = [
        "| setting | pusher | paper RP | ours RP | paper RP+ | ours RP+ | constant floor "
        "| ours RP / RP+ relative error | wall clock (train RP, RP+) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for setting, paper in PAPER_TABLE.items():
        used = pusher or get_setting(setting).pusher
        path = baseline_paths(setting, used, root)["results"]
        if not path.exists():
            lines.append(
                f"| {setting} | {used} | {paper['rp']:.2f} | not yet | {paper['rp+']:.2f} "
                "| not yet | | | |"
            )
            continue
        r = json.loads(path.read_text())
        rp, rpp, t = r["models"]["rp"], r["models"]["rp+"], r["timings"]
        lines.append(
            f"| {setting} | {used} | {paper['rp']:.2f} | **{rp['percentage_error']:.2f}** "
            f"| {paper['rp+']:.2f} | **{rpp['percentage_error']:.2f}** "
            f"| {rp['constant_floor']:.2f} | {rp['relative_error']:.2f} / "
            f"{rpp['relative_error']:.2f} | {t['train_rp_s'] / 60:.1f} min, "
            f"{t['train_rp+_s'] / 60:.1f} min |"
        )
    return "\n".join(lines)
