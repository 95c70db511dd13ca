"""The paper's alternating training (Sec. 3.3): predictor and pushing policy in turn.

    predictor-0   trained on random-policy rollouts
    for i = 1..M (meta-iterations):
      policy-i      PPO against the frozen predictor-(i-1), continuing from policy-(i-1)
      data-i        fresh rollouts of policy-i (sampling its actions)
      predictor-i   predictor-(i-1) fine-tuned on data-i, then evaluated with policy-i
    data-final      rollouts of the deterministic policy-M
    predictor-final predictor-M fine-tuned on data-final (with `final_members` N > 1: N
                    predictors trained from scratch on it with seeds seed..seed+N-1,
                    their estimates averaged; a `width` other than the paper's in
                    `final_finetune` trains from scratch too)

TP is predictor-1 with policy-1, TP+ is predictor-final with policy-M [paper, Sec. 4.1].
Every stage writes its result into the run directory and is skipped when it is there, and
every stage resumes inside itself (collections by shard, training from checkpoints), so a
killed `masspush train` continues where it stopped when run again.

The last two stages (the final stage) may be resized on a run: resumed with a
`final_episodes`, `final_finetune` or `final_members` other than it recorded, it grows (or
cuts) data-final where the episodes differ and trains predictor-final again; everything
before stays. Resumed without
them, a run keeps the final stage it recorded (runs made before the record: the one they
were made with).
"""

from __future__ import annotations

import json
import os
import shutil
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from masspush.cluster.pool import Workers
from masspush.data.dataset import code_version, collect, load_dataset
from masspush.data.rollout import Policy
from masspush.evaluate import evaluate
from masspush.learn.estimator import PredictorEstimator
from masspush.learn.features import LOSS_REWARD
from masspush.learn.policy import LearnedPolicy, PolicyConfig, train_policy
from masspush.learn.predictor import (
    FAST,
    TrainConfig,
    load_model,
    recorded_config,
    train_ensemble,
    train_predictor,
)
from masspush.settings import Setting
from masspush.sim.pushers import pusher_kind

ADDED_POLICY_FIELDS = {"runs": 1, "reward": "paper", "loss_reward": LOSS_REWARD,
                       "lockstep_arms": False}  # fmt: skip
"""Policy fields added after runs were made, with the value every run before them used: a
run directory's recorded config leaves them out, so an old run still resumes (and one made
otherwise does not pass for it)."""

PREDICTOR = replace(FAST, features="relative")
"""Training of predictor-0: our shipped RP recipe (docs/notebook)."""
FINETUNE = replace(FAST, features="relative", steps=5_000, lr=1e-3)
"""Each fine-tuning of the predictor on a policy's rollouts [ours]."""
FINAL_FINETUNE = replace(FINETUNE, steps=20_000, lr=PREDICTOR.lr)
"""The fine-tuning of TP+ on the final policy's rollouts [ours: with 4x the episodes, 20k
steps gained 0.4 points over 5k in 2link-0.1-1; predictor-0's learning rate, 3e-3, gained
0.56 over 1e-3 in 3link-0.1-1 and 0.13 in 2link-0.1-1 on fresh episodes
(docs/notebook/2026-12-01-arm-speed.md)]."""
FINAL_FACTOR = 4
"""TP+'s deterministic-policy episodes per random episode of predictor-0 [ours]: with the
paper's first sizes (16k, 32k) that is as many as its RP+ had (64k, 128k; paper-details.md)."""
FINAL_FIELDS = ("final_episodes", "final_finetune", "final_members")
"""The final stage's sizes: given otherwise than a run recorded, they redo only its final
stage."""

MAX_MEMBERS = 16
"""The most predictors TP+ may average: each costs a training and its share of every
estimate [ours]."""

# Random-policy episodes for the first predictor [paper-details.md]: 16k (2 links), 32k (3).
FIRST_EPISODES = {2: 16_000, 3: 32_000}


def default_first_episodes(n_links: int) -> int:
    return FIRST_EPISODES.get(n_links, 16_000 * (n_links - 1))


def recorded_final(state: dict[str, Any], n_links: int) -> dict[str, Any]:
    """The final stage's sizes (episodes, fine-tuning config, predictors averaged) a run's
    state records. Runs made before the record collected first_episodes (or their
    final_episodes) and fine-tuned with their `finetune` config; runs made before
    ensembles trained one predictor."""
    if "final" in state:
        return {"members": 1, **state["final"]}
    config = state["config"]
    first = config["first_episodes"] or default_first_episodes(n_links)
    return {"episodes": config["final_episodes"] or first, "finetune": config["finetune"],
            "members": 1}  # fmt: skip


@dataclass(frozen=True)
class RecipeConfig:
    """The whole recipe's sizes; defaults are the paper's where it gives them."""

    meta_iterations: int = 6
    """Policy / predictor rounds [paper: 6]."""
    first_episodes: int | None = None
    """Random-policy episodes for predictor-0; None: FIRST_EPISODES for the chain."""
    iteration_episodes: int | None = None
    """Fresh policy rollouts per meta-iteration; None: half of first_episodes [ours]."""
    final_episodes: int | None = None
    """Deterministic-policy rollouts for TP+; None: a run's recorded number, for a new run 4 x
    first_episodes (`FINAL_FACTOR`), as many as the paper's RP+ had [ours]."""
    policy: PolicyConfig = field(default_factory=PolicyConfig)
    predictor: TrainConfig = PREDICTOR
    finetune: TrainConfig = FINETUNE
    final_finetune: TrainConfig | None = None
    """TP+'s fine-tuning; None: a run's recorded one, for a new run `FINAL_FINETUNE`."""
    final_members: int | None = None
    """Predictors trained alike from scratch on data-final for TP+ (seeds differing), their
    estimates averaged; 1 fine-tunes predictor-M as the paper does. None: a run's recorded
    number, for a new run 1 [ours: five averaged took 0.75 off a single one's error on fresh
    episodes in 3link-0.1-1; docs/notebook]."""
    eval_episodes: int = 800
    """Fresh episodes for the error after each meta-iteration [paper: 800]."""
    seed: int = 0
    """Seed of the recipe's collections and evaluations."""

    def __post_init__(self) -> None:
        if self.meta_iterations < 1:
            raise ValueError(f"meta_iterations must be >= 1, got {self.meta_iterations}")
        for name in ("first_episodes", "iteration_episodes", "final_episodes"):
            value = getattr(self, name)
            if value is not None and value < 2:
                raise ValueError(f"{name} must be >= 2, got {value}")
        if self.eval_episodes < 1:
            raise ValueError(f"eval_episodes must be >= 1, got {self.eval_episodes}")
        if self.final_members is not None and not 1 <= self.final_members <= MAX_MEMBERS:
            raise ValueError(f"final_members must be in 1..{MAX_MEMBERS}, got {self.final_members}")

    def episodes(self, n_links: int) -> tuple[int, int, int]:
        first = self.first_episodes or default_first_episodes(n_links)
        final = self.final_episodes or FINAL_FACTOR * first
        return first, self.iteration_episodes or first // 2, final


class Recipe:
    """One run of the recipe for one setting and pusher, in `run_dir`."""

    def __init__(
        self,
        setting: Setting,
        pusher: str,
        run_dir: str | os.PathLike,
        config: RecipeConfig = RecipeConfig(),
        log: Callable[[str], None] = print,
        progress: bool = True,
        workers: Workers = None,
    ):
        self.setting, self.pusher, self.config = setting, pusher, config
        self.dir = Path(run_dir)
        self.log, self.progress = log, progress
        # Local processes, or a cluster's pool for the collections, evaluations and PPO's
        # environments (the results are the same; only where they run differs).
        self.workers = workers
        self.env_config = setting.env_config(pusher)
        self.state_path = self.dir / "state.json"

    # --- state ------------------------------------------------------------------------
    def _state(self) -> dict[str, Any]:
        ours = self._identity()
        if not self.state_path.exists():
            return {"config": ours, "final": self._final(None), "timings": {}, "history": []}
        state = json.loads(self.state_path.read_text())
        differ = sorted(
            name
            for name in _differences(state["config"], ours)
            if name.split(".")[0] not in FINAL_FIELDS
        )
        if differ:
            raise ValueError(
                f"{self.dir} holds a run with another setting, pusher or config "
                f"({', '.join(differ)}); use another --out directory, or the run's own "
                "options"
            )
        recorded = recorded_final(state, self.setting.n_links)
        final = self._final(recorded)
        if recorded != final:
            self._redo_final(state, recorded, final)
        state["config"], state["final"] = ours, final
        return state

    def _final(self, recorded: dict[str, Any] | None) -> dict[str, Any]:
        """The final stage's sizes to run: those given, else those `recorded`, else the
        defaults."""
        cfg = self.config
        episodes = cfg.final_episodes or (
            recorded["episodes"] if recorded else cfg.episodes(self.setting.n_links)[2]
        )
        if cfg.final_finetune is not None:
            finetune = recorded_config(cfg.final_finetune)
        else:
            finetune = recorded["finetune"] if recorded else recorded_config(FINAL_FINETUNE)
        members = cfg.final_members or (recorded["members"] if recorded else 1)
        return {"episodes": episodes, "finetune": finetune, "members": members}

    def _redo_final(
        self, state: dict[str, Any], recorded: dict[str, Any], new: dict[str, Any]
    ) -> None:
        """Forget the final stage done at other sizes; data-final is kept, to be grown or
        cut where the episodes differ (its episodes stay those of its seeds), and
        predictor-final is trained again."""

        def sizes(final: dict[str, Any]) -> str:
            tune = final["finetune"]
            averaged = f", {final['members']} predictors averaged" if final["members"] > 1 else ""
            loss = f", {tune['loss']} loss" if "loss" in tune else ""
            width = f", {tune['width']} wide" if "width" in tune else ""
            return (
                f"{final['episodes']} episodes, {tune['steps']} steps at lr {tune['lr']:g}"
                f"{loss}{width}{averaged}"
            )

        self.log(
            f"[{self.setting.name}] the final stage was run with {sizes(recorded)}; "
            f"redoing it with {sizes(new)}"
        )
        timings = state["timings"]
        if "data-final" in timings and new["episodes"] != recorded["episodes"]:
            # The kept episodes' time counts towards the grown collection's; a cut keeps
            # only its share of it.
            kept = min(1.0, new["episodes"] / recorded["episodes"])
            state.setdefault("carried", {})["data-final"] = round(
                timings.pop("data-final") * kept, 1
            )
        for name in ("predictor-final", "evaluate-final"):
            timings.pop(name, None)
        state["history"] = [h for h in state["history"] if h["stage"] != "predictor-final"]
        shutil.rmtree(self.predictor("final").parent, ignore_errors=True)

    def _identity(self) -> dict[str, Any]:
        identity = json.loads(
            json.dumps(
                {"setting": self.setting.as_dict(), "pusher": self.pusher, **asdict(self.config)}
            )
        )
        policy = identity["policy"]
        if not pusher_kind(self.pusher).arm:
            del policy["lockstep_arms"]  # the stiff pusher always trains in lockstep
        for name, value in ADDED_POLICY_FIELDS.items():
            if name in policy and policy[name] == value:
                del policy[name]  # as runs made before the field existed say it
        for name in ("predictor", "finetune", "final_finetune"):
            given = getattr(self.config, name)
            identity[name] = None if given is None else recorded_config(given)
        return identity

    def _save(self, state: dict[str, Any]) -> None:
        tmp = self.state_path.with_suffix(".tmp")
        tmp.write_text(json.dumps(state, indent=2))
        tmp.replace(self.state_path)

    def _stage(self, state: dict[str, Any], name: str, run: Callable[[], Any]) -> None:
        """Run a stage unless done; record its wall-clock time."""
        if name in state["timings"]:
            return
        self.log(f"[{self.setting.name}] {name} ...")
        t0 = time.perf_counter()
        run()
        carried = state.get("carried", {}).pop(name, 0.0)
        state["timings"][name] = round(time.perf_counter() - t0 + carried, 1)
        self._save(state)
        self.log(f"[{self.setting.name}] {name} done in {state['timings'][name]:.0f} s")

    # --- paths ------------------------------------------------------------------------
    def predictor(self, i: int | str) -> Path:
        return self.dir / f"predictor-{i}" / "predictor.pt"

    def policy(self, i: int) -> Path:
        return self.dir / f"policy-{i}" / "policy.zip"

    def exports(self, shipped_rp: bool = True) -> dict[str, Path]:
        """What ships (`masspush.models.ship`): TP (predictor-1, policy-1) and TP+
        (predictor-final, policy-M); and, for a setting without RP baselines (`shipped_rp`
        False, e.g. real-ur10), predictor-0 as its random-push RP."""
        out = {} if shipped_rp else {"rp": self.predictor(0)}
        return {**out, "tp": self.predictor(1), "tp+": self.predictor("final")}

    # --- the recipe -------------------------------------------------------------------
    def run(self) -> dict[str, Any]:
        self.dir.mkdir(parents=True, exist_ok=True)
        state = self._state()
        self._save(state)
        cfg, n = self.config, self.setting.n_links
        first, per_iteration, _ = cfg.episodes(n)
        final = state["final"]["episodes"]
        final_finetune = TrainConfig(**state["final"]["finetune"])
        m = cfg.meta_iterations

        self._stage(state, "data-0", lambda: self._collect("data-0", first, "random", 0))
        self._stage(
            state,
            "predictor-0",
            lambda: self._train_predictor(0, "data-0", cfg.predictor, None, "random", None),
        )
        self._stage(state, "evaluate-0", lambda: self._evaluate(state, 0))
        for i in range(1, m + 1):
            self._stage(state, f"policy-{i}", lambda i=i: self._train_policy(i))
            self._stage(
                state,
                f"data-{i}",
                lambda i=i: self._collect(f"data-{i}", per_iteration, self._learned(i, False), i),
            )
            self._stage(
                state,
                f"predictor-{i}",
                lambda i=i: self._train_predictor(
                    i, f"data-{i}", cfg.finetune, self.predictor(i - 1), "learned", i
                ),
            )
            self._stage(state, f"evaluate-{i}", lambda i=i: self._evaluate(state, i))
        # resize: a final stage redone at a smaller size cuts the collection down.
        self._stage(
            state,
            "data-final",
            lambda: self._collect("data-final", final, self._learned(m), m + 1, resize=True),
        )
        self._stage(
            state,
            "predictor-final",
            lambda: self._train_predictor(
                "final",
                "data-final",
                final_finetune,
                self.predictor(m),
                "learned",
                m,
                members=state["final"]["members"],
            ),
        )
        self._stage(state, "evaluate-final", lambda: self._evaluate(state, "final"))
        return state

    def _learned(self, i: int, deterministic: bool = True) -> LearnedPolicy:
        policy = self.config.policy
        return LearnedPolicy(self.policy(i), policy.algo, deterministic, self.pusher, policy.runs)

    def _collect(
        self, name: str, episodes: int, policy: str | Policy, stream: int, resize: bool = False
    ) -> None:
        collect(
            self.setting,
            self.dir / name,
            episodes=episodes,
            pusher=self.pusher,
            policy=policy,
            base_seed=1000 * self.config.seed + stream,
            progress=self.progress,
            workers=self.workers,
            resize=resize,
        )

    def _train_policy(self, i: int) -> None:
        train_policy(
            self.env_config,
            self.predictor(i - 1),
            self.dir / f"policy-{i}",
            replace(self.config.policy, seed=self.config.policy.seed + i),
            init=self.policy(i - 1) if i > 1 else None,
            progress=self.progress,
            workers=self.workers,
            meta={
                "setting": self.setting.as_dict(),
                "code_version": code_version(),
                "recipe_stage": f"policy-{i}",
            },
        )

    def _train_predictor(
        self,
        i: int | str,
        data: str,
        train: TrainConfig,
        init: Path | None,
        policy: str,
        policy_index: int | None,
        members: int = 1,
    ) -> None:
        _, episodes = load_dataset(self.dir / data)
        meta = {
            "setting": self.setting.as_dict(),
            "pusher": self.pusher,
            "policy": policy,
            "dataset": str(self.dir / data),
            "dataset_episodes": len(episodes),
            "code_version": code_version(),
            "recipe_stage": f"predictor-{i}",
        }
        if policy_index is not None:
            # Relative to the model file, so that a copied pair of files stays a pair.
            meta["policy_file"] = f"../policy-{policy_index}/policy.zip"
            meta["policy_algo"] = self.config.policy.algo
            if self.config.policy.runs > 1:
                meta["policy_runs"] = self.config.policy.runs
        out = self.predictor(i).parent
        if members > 1:
            # From scratch: members fine-tuned from one predictor-M stay alike, and averaged
            # they gained less (3link-0.1-1 held out, 3 averaged: 14.28 against 14.04 from
            # scratch; docs/notebook/2026-12-01-arm-speed.md).
            train_ensemble(episodes, out, train, members, meta, self.progress)
        else:
            # A network of another width than predictor-M's cannot start from its weights.
            start = load_model(init)[0] if init is not None and train.width is None else None
            train_predictor(episodes, out, train, meta, progress=self.progress, init=start)

    def _evaluate(self, state: dict[str, Any], i: int | str) -> None:
        estimator = PredictorEstimator.from_file(self.predictor(i), self.setting.name)
        scores = evaluate(
            self.setting, estimator, self.config.eval_episodes, self.config.seed, self.workers
        )
        state["history"].append({"stage": f"predictor-{i}", **scores.to_dict()})


def _differences(recorded: Any, ours: Any, where: str = "") -> list[str]:
    """The dotted names of the entries where two recorded configs differ."""
    if isinstance(recorded, dict) and isinstance(ours, dict):
        return [
            name
            for key in sorted(set(recorded) | set(ours))
            for name in _differences(recorded.get(key), ours.get(key), f"{where}{key}.")
        ]
    return [] if recorded == ours else [where.rstrip(".") or "config"]
