"""`masspush bench ray`: what a Ray cluster costs and gives on this machine.

The same collection three ways in one run: this machine's own path (processes for an arm,
threads for the stiff pusher), and `--ray local` with 1 and with 2 CPUs (or `cpus`); each
Ray collection is checked byte for byte against the local one. A task's overhead is the
round trip of empty tasks on the same cluster, so that a cluster's gain can be projected:
a task of E episodes costs E / (episodes per second per CPU) plus the overhead.
"""

from __future__ import annotations

import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from masspush.config import check_int
from masspush.data.dataset import collect
from masspush.settings import get_setting
from masspush.sim.pushers import pusher_field, pusher_kind

if TYPE_CHECKING:
    from masspush.cluster.pool import TaskPool


@dataclass(frozen=True)
class ClusterBench:
    """`masspush bench ray`: a collection on this machine against `--ray local` with 1 and 2
    CPUs, in the same run, and a task's overhead (needs pip install 'masspush[ray]')."""

    setting: str = "2link-0.1-1"
    """Named setting of the episodes."""
    pusher: str = pusher_field("kuka")
    """The pusher that pushes them."""
    episodes: int = 400
    """Episodes of each collection."""
    shard_size: int = 100
    """Episodes per shard."""
    cpus: tuple[int, ...] = (1, 2)
    """CPUs of each local Ray cluster measured; the local path uses the largest number."""
    overhead_tasks: int = 200
    """Empty tasks timed for the overhead per task."""

    def __post_init__(self) -> None:
        get_setting(self.setting)
        pusher_kind(self.pusher)
        check_int("episodes", self.episodes)
        check_int("shard_size", self.shard_size)
        check_int("overhead_tasks", self.overhead_tasks)
        if not self.cpus:
            raise ValueError("cpus must name at least one cluster size")
        for n in self.cpus:
            check_int("cpus", n)


def _nothing(_shared: Any, job: Any) -> Any:
    return job


def _shards(root: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(root.glob("shard-*.npz"))}


def bench_cluster(config: ClusterBench = ClusterBench(), progress: bool = False) -> dict:
    """The three collections' speeds, their ratios to the local path, the clusters' start
    times and overhead per task, and whether each Ray collection equals the local one."""
    from masspush.cluster.ray_pool import connect

    spec = get_setting(config.setting)
    workers = max(config.cpus)

    def run(out: Path, pool: TaskPool | None = None) -> float:
        t0 = time.perf_counter()
        collect(
            spec, out, episodes=config.episodes, pusher=config.pusher,
            shard_size=config.shard_size, workers=pool or workers, progress=progress,
        )  # fmt: skip
        return time.perf_counter() - t0

    result: dict[str, Any] = {
        "setting": spec.name, "pusher": config.pusher, "episodes": config.episodes,
        "shard_size": config.shard_size, "cores": os.cpu_count(),
    }  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        local = run(Path(tmp) / "local")
        result["local"] = {"workers": workers, "seconds": local,
                           "episodes_per_s": config.episodes / local}  # fmt: skip
        expected = _shards(Path(tmp) / "local")
        for n in config.cpus:
            t0 = time.perf_counter()
            with connect("local", cpus=n) as pool:
                start = time.perf_counter() - t0
                seconds = run(Path(tmp) / f"ray-{n}", pool)
                t1 = time.perf_counter()
                for _ in pool.imap(_nothing, list(range(config.overhead_tasks))):
                    pass
                overhead = (time.perf_counter() - t1) / config.overhead_tasks
            result[f"ray_{n}"] = {
                "cpus": n,
                "seconds": seconds,
                "episodes_per_s": config.episodes / seconds,
                "ratio_to_local": local / seconds,
                "cluster_start_s": start,
                "overhead_per_task_ms": 1000 * overhead,
                "identical": _shards(Path(tmp) / f"ray-{n}") == expected,
            }
    return result
