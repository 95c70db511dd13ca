"""The paper's Table 1 and figures from our own runs, beside the paper's numbers.

RP / RP+ come from `masspush baselines` (results/<setting>-<pusher>-baselines.json), TP /
TP+ from `masspush train` (runs/<setting>-<pusher>-train/state.json). `reproduce` runs
whatever is missing (both resume) and then writes:
- results/table1.md and results/table1.csv: RP, RP+, TP, TP+ per setting, ours and the paper's;
- results/meta-iterations.png: error after each meta-iteration (2-link and 3-link panels);
- results/ppo-error.png: the frozen predictor's error on the policy's episodes during PPO;
- results/recipe-times.md: wall-clock minutes per kind of stage of each finished run;
- results/runs/<setting>-<pusher>-train.json: each run's record (its state and PPO progress),
  small and committed, so that the table and figures outlive the run directories (bulky,
  not in git); a run directory, where there is one, is read before its record.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from masspush.cluster.pool import check_address, open_pool
from masspush.learn.predictor import FAST, load_model
from masspush.learn.recipe import Recipe, RecipeConfig, recorded_final
from masspush.models import ship, shipped_file
from masspush.reports.baselines import (
    PAPER_TABLE,
    baseline_paths,
    paper_settings,
    run_baselines,
    ship_baselines,
)
from masspush.settings import get_setting
from masspush.sim.pushers import pusher_field, pusher_kind

if TYPE_CHECKING:
    from matplotlib.axes import Axes

COLUMNS = ("rp", "rp+", "tp", "tp+")


@dataclass(frozen=True)
class TrainJob:
    """`masspush train`: the alternating recipe for one setting (resumable)."""

    setting: str
    """Named setting."""
    out: str | None = None
    """Run directory; a rerun resumes it (default: runs/<setting>-<pusher>-train)."""
    pusher: str | None = pusher_field()
    """The pusher (default: the setting's)."""
    ship: bool = False
    """Ship TP and TP+ into the package (and RP, for a setting with none yet)."""
    settings_file: str | None = None
    """TOML file with custom settings."""
    ray: str | None = None
    """Run the collections, evaluations and (for an arm with --no-lockstep-arms) PPO's
    environments on a Ray cluster: auto, local, ray://HOST:PORT or HOST:PORT (pip install
    'masspush[ray]')."""

    def __post_init__(self) -> None:
        if self.pusher is not None:
            pusher_kind(self.pusher)
        check_address(self.ray)


def train_setting(
    job: TrainJob, recipe: RecipeConfig, log: Callable[[str], object] = print
) -> list[str]:
    """Run the recipe for one setting (and ship it); the report."""
    setting = get_setting(job.setting, job.settings_file)
    pusher = job.pusher or setting.pusher
    out = job.out or train_dir(setting.name, pusher)
    with open_pool(job.ray) as workers:
        run = Recipe(setting, pusher, out, recipe, log=log, workers=workers)
        state = run.run()
    lines = [
        f"{h['stage']:16s} percentage error {h['percentage_error']:6.2f}  "
        f"(constant floor {h['constant_floor']:.2f}, {h['episodes']} episodes)"
        for h in state["history"]
    ]
    lines.append(f"wall clock per stage (s): {state['timings']}")
    if job.ship:
        lines += [f"shipped {path}" for path in ship_recipe(run)]
    return lines


def ship_recipe(run: Recipe, root: str | Path = ".") -> list[Path]:
    """Ship a finished recipe's TP and TP+, and its predictor-0 as RP where none is shipped
    for this setting and pusher (none at all, or one of another pusher or setting's physics:
    an RP of another world would not be the baseline of these)."""
    rp = shipped_file(run.setting.name, "rp")
    has_rp = False
    if rp.exists():
        meta = load_model(rp)[1]
        has_rp = meta.get("pusher") == run.pusher and meta.get("setting") == run.setting.as_dict()
    shipped = ship(run.setting.name, run.exports(shipped_rp=has_rp))
    write_record(Path(run.dir), run.setting.name, run.pusher, root)
    return shipped


@dataclass(frozen=True)
class ReproduceConfig:
    """`masspush reproduce`: the paper's Table 1 and figures, running what is missing."""

    settings: str = "all"
    """all, or a comma-separated list of named settings."""
    table_only: bool = False
    """Only write the table and figures from the runs there are."""
    pusher: str | None = pusher_field()
    """The pusher (default: each setting's)."""
    ship: bool = False
    """Ship every finished model into the package."""

    def names(self) -> list[str]:
        return paper_settings(self.settings)

    def __post_init__(self) -> None:
        self.names()  # each named setting exists
        if self.pusher is not None:
            pusher_kind(self.pusher)


def reproduce(config: ReproduceConfig, recipe: RecipeConfig, root: str | Path = ".") -> list[Path]:
    """RP, RP+ (`masspush baselines`) and TP, TP+ (`masspush train`) for each setting where
    missing, then Table 1 and the figures; returns the files written."""
    names = config.names()
    settings = [get_setting(name) for name in names]
    pushers = {s.name: config.pusher or s.pusher for s in settings}
    if not config.table_only:
        for s in settings:
            run_baselines(s.name, pushers[s.name], replace(FAST, features="relative"), root=root)
            run = Recipe(s, pushers[s.name], train_dir(s.name, pushers[s.name], root), recipe)
            run.run()
            if config.ship:
                ship_baselines(s.name, pushers[s.name], root)
                ship_recipe(run, root)
    return write_outputs(names, pushers, root)


def train_dir(setting: str, pusher: str, root: str | Path = ".") -> Path:
    return Path(root) / "runs" / f"{setting}-{pusher}-train"


def record_path(setting: str, pusher: str, root: str | Path = ".") -> Path:
    """The committed record of a setting's recipe run."""
    return Path(root) / "results" / "runs" / f"{setting}-{pusher}-train.json"


def run_record(run_dir: Path) -> dict[str, Any] | None:
    """A run directory's state and each policy's PPO progress (rows of timesteps and
    error), or None where it has no state."""
    state = _load(run_dir / "state.json")
    if state is None:
        return None
    policies = sorted(run_dir.glob("policy-*"), key=lambda p: int(p.name.split("-")[1]))
    progress = {p.name: _read_progress(p / "progress.csv") for p in policies}
    return {"state": state, "progress": progress}


def write_record(run_dir: Path, setting: str, pusher: str, root: str | Path = ".") -> Path | None:
    """Record a run directory's state and progress as the setting's run in results/runs
    (when it has a state)."""
    record = run_record(run_dir)
    if record is None:
        return None
    path = record_path(setting, pusher, root)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record, indent=1) + "\n")
    return path


def load_record(setting: str, pusher: str, root: str | Path = ".") -> dict[str, Any] | None:
    """A setting's run: from its run directory where there is one, else from its record."""
    return run_record(train_dir(setting, pusher, root)) or _load(record_path(setting, pusher, root))


def _state(setting: str, pusher: str, root: str | Path) -> dict[str, Any] | None:
    """A setting's run state, as `load_record` finds it, without reading its PPO progress."""
    state = _load(train_dir(setting, pusher, root) / "state.json")
    if state is None:
        state = (_load(record_path(setting, pusher, root)) or {}).get("state")
    return state


def _load(path: Path) -> dict[str, Any] | None:
    return json.loads(path.read_text()) if path.exists() else None


def collect_rows(
    settings: Sequence[str], pushers: dict[str, str], root: str | Path = "."
) -> list[dict]:
    """One row per setting: our four errors (None where not run yet) and the paper's. A
    setting with neither a run directory nor a record keeps its row of the last table
    written (results/table1.csv), marked as carried over."""
    rows = []
    earlier = _earlier_rows(Path(root) / "results" / "table1.csv")
    for setting in settings:
        pusher = pushers[setting]
        row: dict[str, Any] = {"setting": setting, "pusher": pusher}
        base = _load(baseline_paths(setting, pusher, root)["results"])
        for name in ("rp", "rp+"):
            row[name] = base["models"][name]["percentage_error"] if base else None
        row["constant_floor"] = base["models"]["rp"]["constant_floor"] if base else None
        for name in COLUMNS:
            row[f"paper_{name}"] = PAPER_TABLE[setting][name]
        state = _state(setting, pusher, root)
        if state is None and (setting, pusher) in earlier:
            # Measured by a run whose directory is gone and which predates the records.
            rows.append({**row, **earlier[setting, pusher], "carried": True})
            continue
        by_stage = {h["stage"]: h for h in (state or {}).get("history", [])}
        row["tp"] = by_stage.get("predictor-1", {}).get("percentage_error")
        row["tp+"] = by_stage.get("predictor-final", {}).get("percentage_error")
        if row["constant_floor"] is None and by_stage:
            row["constant_floor"] = next(iter(by_stage.values()))["constant_floor"]
        config = (state or {}).get("config", {})
        row["recipe"] = recipe_summary(state, setting) if config else None
        row["train_minutes"] = (
            round(sum(state["timings"].values()) / 60, 1) if state and row["tp+"] else None
        )
        rows.append(row)
    return rows


def _earlier_rows(path: Path) -> dict[tuple[str, str], dict[str, Any]]:
    """TP, TP+, recipe and its time per (setting, pusher) from a table1.csv written before."""
    if not path.exists():
        return {}
    with path.open() as f:
        rows = list(csv.DictReader(f))

    def number(value: str) -> float | None:
        return float(value) if value else None

    return {
        (r["setting"], r["pusher"]): {
            "tp": number(r["tp"]),
            "tp+": number(r["tp+"]),
            "recipe": r["recipe"] or None,
            "train_minutes": number(r["train_minutes"]),
        }
        for r in rows
        if r.get("tp+")
    }


def _cell(value: float | None) -> str:
    return "not yet" if value is None else f"{value:.2f}"


def table_markdown(rows: list[dict]) -> str:
    lines = [
        "| setting | pusher | RP ours / paper | RP+ ours / paper | TP ours / paper "
        "| TP+ ours / paper | constant floor | recipe | recipe wall clock |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        cells = [f"**{_cell(r[n])}** / {r[f'paper_{n}']:.2f}" for n in COLUMNS]
        minutes = "" if r["train_minutes"] is None else f"{r['train_minutes']} min"
        if r.get("carried"):
            minutes += " (carried over)"
        floor = "" if r["constant_floor"] is None else f"{r['constant_floor']:.2f}"
        lines.append(
            f"| {r['setting']} | {r['pusher']} | {' | '.join(cells)} | {floor} "
            f"| {r['recipe'] or ''} | {minutes} |"
        )
    return "\n".join(lines)


STAGE_GROUPS = {
    "data-0": "random rollouts",
    "predictor-0": "first predictor",
    "policy": "PPO (all meta-iterations)",
    "data": "policy rollouts",
    "predictor": "fine-tuning",
    "evaluate": "evaluations",
    "data-final": "deterministic rollouts",
    "predictor-final": "TP+ fine-tuning",
}


def stage_group(stage: str) -> str:
    """The STAGE_GROUPS key of a recipe stage ("policy-3" -> "policy")."""
    return stage if stage in STAGE_GROUPS else stage.split("-")[0]


def timings_markdown(
    settings: Sequence[str], pushers: dict[str, str], root: str | Path = "."
) -> str:
    """Wall-clock minutes per kind of stage of each finished recipe run."""
    lines = [
        "| setting | recipe | " + " | ".join(STAGE_GROUPS.values()) + " | total |",
        "|---|---|" + "---|" * (len(STAGE_GROUPS) + 1),
    ]
    earlier = _earlier_timing_lines(Path(root) / "results" / "recipe-times.md")
    for setting in settings:
        state = _state(setting, pushers[setting], root)
        if state is None and setting in earlier:
            lines.append(earlier[setting])  # carried over, as in the table (`collect_rows`)
            continue
        if not state or "evaluate-final" not in state["timings"]:
            continue
        minutes = dict.fromkeys(STAGE_GROUPS, 0.0)
        for stage, seconds in state["timings"].items():
            minutes[stage_group(stage)] += seconds / 60
        recipe = recipe_summary(state, setting)
        cells = " | ".join(f"{m:.1f}" for m in minutes.values())
        lines.append(f"| {setting} | {recipe} | {cells} | {sum(minutes.values()):.1f} |")
    return "\n".join(lines)


def _earlier_timing_lines(path: Path) -> dict[str, str]:
    """The rows of a recipe-times.md written before, by setting."""
    if not path.exists():
        return {}
    rows = [line for line in path.read_text().splitlines()[2:] if line.startswith("| ")]
    return {line.split("|")[1].strip(): line for line in rows}


def write_csv(rows: list[dict], path: Path) -> None:
    keys = ["setting", "pusher", *COLUMNS, *(f"paper_{n}" for n in COLUMNS)]
    keys += ["constant_floor", "recipe", "train_minutes", "carried"]
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=keys, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)


def recipe_summary(state: dict[str, Any], setting: str) -> str:
    """A run's sizes in a few words: meta-iterations x PPO pushes, TP+'s episodes,
    fine-tuning steps, a width other than the paper's and, where several, predictors
    averaged."""
    config = state["config"]
    final = recorded_final(state, get_setting(setting).n_links)
    width = final["finetune"].get("width")
    wide = f", {width} wide" if width is not None else ""
    averaged = f", {final['members']} averaged" if final["members"] > 1 else ""
    return (
        f"{config['meta_iterations']} x {config['policy']['steps'] / 1000:g}k PPO, "
        f"TP+ on {final['episodes'] / 1000:g}k, {final['finetune']['steps'] / 1000:g}k steps"
        f"{wide}{averaged}"
    )


def plot_meta_iterations(
    settings: Sequence[str], pushers: dict[str, str], root: str | Path, path: Path
) -> None:
    """Error after each meta-iteration, one line per setting, 2-link and 3-link panels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=False)
    for ax, links in zip(axes, ("2link", "3link"), strict=True):
        missing = []
        for setting in (s for s in settings if s.startswith(links)):
            state = _state(setting, pushers[setting], root)
            missing += [setting] if state is None else []
            history = [
                h
                for h in (state or {}).get("history", [])
                if h["stage"].removeprefix("predictor-").isdigit()
            ]
            if not history:
                continue
            x = [int(h["stage"].split("-")[1]) for h in history]
            line = ax.plot(x, [h["percentage_error"] for h in history], "o-", label=setting)[0]
            final = next((h for h in state["history"] if h["stage"] == "predictor-final"), None)
            if final:
                ax.plot(x[-1] + 0.5, final["percentage_error"], "*", ms=12, color=line.get_color())
            ax.axhline(PAPER_TABLE[setting]["tp+"], ls=":", color=line.get_color(), lw=1)
        _say_missing(ax, missing)
        ax.set(title=f"{links[0]}-link chains", xlabel="meta-iteration (0: random pushes)")
        ax.set_ylabel("percentage error (paper's metric)")
        ax.grid(alpha=0.3)
        if ax.lines:
            ax.legend(fontsize=8, title="star: TP+; dotted: paper's TP+", title_fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_ppo_error(
    settings: Sequence[str], pushers: dict[str, str], root: str | Path, path: Path
) -> None:
    """The frozen predictor's error on the policy's own episodes during PPO training."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    missing = []
    for setting in settings:
        record = load_record(setting, pushers[setting], root)
        if record is None:
            missing.append(setting)
            continue
        xs, ys, offset = [], [], 0
        for rows in record["progress"].values():
            xs += [offset + t for t, _ in rows]
            ys += [e for _, e in rows]
            offset += rows[-1][0] if rows else 0
        if xs:
            ax.plot(xs, ys, label=setting, lw=1)
    _say_missing(ax, missing)
    ax.set(xlabel="PPO steps (pushes), all meta-iterations", ylabel="percentage error")
    ax.set_title("Predictor error on the policy's episodes during PPO")
    ax.grid(alpha=0.3)
    if ax.lines:
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _say_missing(ax: Axes, missing: list[str]) -> None:
    """Name, in the panel, the settings with neither a run directory nor a record (runs
    from before the records: their rows in the table are carried over, their curves lost)."""
    if missing:
        ax.text(0.02, 0.02, "no run record: " + ", ".join(missing), transform=ax.transAxes,
                fontsize=7, color="0.4", va="bottom")  # fmt: skip


def _read_progress(path: Path) -> list[tuple[int, float]]:
    if not path.exists():
        return []
    with path.open() as f:
        rows = {int(r["timesteps"]): float(r["percentage_error"]) for r in csv.DictReader(f)}
    return sorted(rows.items())  # a resumed run may repeat a row: keep the last


def write_outputs(
    settings: Sequence[str], pushers: dict[str, str], root: str | Path = ".",
    out_dir: str | Path = "results",
) -> list[Path]:  # fmt: skip
    out = Path(root) / out_dir
    out.mkdir(parents=True, exist_ok=True)
    recorded = [write_record(train_dir(s, pushers[s], root), s, pushers[s], root) for s in settings]
    rows = collect_rows(settings, pushers, root)
    paths = [out / "table1.md", out / "table1.csv", out / "meta-iterations.png"]
    paths[0].write_text(table_markdown(rows) + "\n")
    write_csv(rows, paths[1])
    plot_meta_iterations(settings, pushers, root, paths[2])
    paths.append(out / "ppo-error.png")
    plot_ppo_error(settings, pushers, root, paths[3])
    paths.append(out / "recipe-times.md")
    paths[4].write_text(timings_markdown(settings, pushers, root) + "\n")
    return paths + [path for path in recorded if path is not None]
