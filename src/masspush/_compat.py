"""The module paths of masspush before its subpackages (0.1, flat), kept importable.

`import masspush.robot` or `from masspush.chain import sample_chain` in a user's script,
and a pickle that names `masspush.predictor.MassPredictor`, find the module's new home. A
module that was split is served by one that re-exports its public names. The aliases load
only when asked for; no warning, so saved files keep loading quietly.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import types
from collections.abc import Sequence
from importlib.machinery import ModuleSpec

OLD_PATHS: dict[str, str] = {
    "actions": "masspush.sim.actions",
    "chain": "masspush.sim.chain",
    "simulate": "masspush.sim.simulate",
    "batch": "masspush.sim.batch",
    "validate": "masspush.sim.convergence",
    "pusher": "masspush.sim.pushers",
    "arm": "masspush.sim.pushers.arm",
    "osc": "masspush.sim.pushers.osc",
    "rollout": "masspush.data.rollout",
    "dataset": "masspush.data.dataset",
    "recording": "masspush.data.recording",
    "predictor": "masspush.learn.predictor",
    "policy": "masspush.learn.policy",
    "vec_env": "masspush.learn.vec_env",
    "uncertainty": "masspush.learn.uncertainty",
    "train": "masspush.learn.recipe",
    "arm_sims": "masspush.bayes.arm_scenes",
    "robot": "masspush.real",
    "robot_env": "masspush.real.robot_env",
    "finetune": "masspush.real.classifier",
    "target_world": "masspush.real.target_world",
    "randomise": "masspush.real.randomisation",
    "sim2real": "masspush.real.transfer",
    "baselines": "masspush.reports.baselines",
    "reproduce": "masspush.reports.reproduction",
    "bayes_table": "masspush.reports.bayes_report",
    "bench": "masspush.reports.bench",
    "demo": "masspush.reports.demonstration",
    "render": "masspush.reports.render",
}
"""Old module (masspush.<name>) -> where it lives now. `masspush.bayes` and
`masspush.evaluate` kept their names (the package re-exports the filter's names)."""


class _AliasLoader(importlib.abc.Loader):
    def __init__(self, target: str):
        self.target = target

    def create_module(self, spec: ModuleSpec) -> types.ModuleType:
        return importlib.import_module(self.target)

    def exec_module(self, module: types.ModuleType) -> None:
        pass


class OldPathFinder(importlib.abc.MetaPathFinder):
    """Finds `masspush.<old name>` as the module it became."""

    def find_spec(
        self,
        fullname: str,
        path: Sequence[str] | None = None,
        target: types.ModuleType | None = None,
    ) -> ModuleSpec | None:
        prefix, _, name = fullname.partition(".")
        if prefix != "masspush" or name not in OLD_PATHS:
            return None
        return importlib.util.spec_from_loader(fullname, _AliasLoader(OLD_PATHS[name]))


def install() -> None:
    if not any(isinstance(f, OldPathFinder) for f in sys.meta_path):
        sys.meta_path.append(OldPathFinder())
