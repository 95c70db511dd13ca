"""Independent tasks on a pool of workers: the protocol the package codes against.

Work that splits into independent tasks (a dataset's shards, chunks of evaluation episodes,
the classes of a sim-to-real test) takes `workers`: a number of processes on this machine
(the default path, unchanged), or a `TaskPool`, which runs `fn(shared, job)` for each job
somewhere and hands back the results as they finish. Every task is a pure function of its
job (an episode depends only on its seed and index), so where a task runs, how often it
was retried and in what order the results come back change nothing in what is written.

`open_pool(address)` gives a Ray cluster's pool (`masspush.cluster.ray_pool`): `auto` (the
cluster this machine belongs to, as `ray start --head` makes), `local` (one started on this
machine for the run), `ray://HOST:PORT` (Ray Client) or `HOST:PORT` (a head node's address).
"""

from __future__ import annotations

import importlib.util
import multiprocessing
import re
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from typing import Any, Protocol, runtime_checkable

import numpy as np

from masspush.cluster.errors import RAY_EXTRA

ADDRESS_HELP = "auto, local, ray://HOST:PORT or HOST:PORT"
_HOST_PORT = re.compile(r"^(ray://)?[A-Za-z0-9_.\-\[\]:]+:\d{1,5}$")


@runtime_checkable
class TaskPool(Protocol):
    """Runs independent tasks; `masspush.cluster.ray_pool.RayPool` is the one shipped."""

    size: int
    """How many tasks run at once (the cluster's CPUs): what work is split for."""

    def imap(
        self,
        fn: Callable[[Any, Any], Any],
        jobs: Sequence[Any],
        shared: Any = None,
        desc: str | None = None,
    ) -> Iterator[tuple[int, Any]]:
        """`fn(shared, job)` for every job, yielded as (position in `jobs`, result) in the
        order they finish. `shared` (a model, a policy) travels to the workers once; `desc`
        names a progress bar over the tasks (none without)."""


Workers = int | TaskPool | None
"""What `workers` parameters take: local processes (None: one per core), or a pool."""


def is_pool(workers: Any) -> bool:
    return isinstance(workers, TaskPool)


def check_address(address: str | None, name: str = "ray") -> None:
    """A one-line ValueError, before any work, for an address `open_pool` cannot use, or
    for any address where Ray is not installed."""
    if address is None:
        return
    if not isinstance(address, str) or not (
        address in ("auto", "local") or _HOST_PORT.match(address)
    ):
        raise ValueError(f"{name} must be {ADDRESS_HELP}, got {address!r}")
    if importlib.util.find_spec("ray") is None:
        raise ValueError(f"{name}: Ray is not installed here: {RAY_EXTRA}")


def local_processes(workers: int) -> ProcessPoolExecutor:
    """`workers` processes on this machine, started from a forkserver, not forked: a child
    forked from a process whose torch ran on several OpenMP threads can hang in its first
    parallel call (seen: a `randomise` worker loading its policy in a test run after other
    tests had used torch)."""
    return ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("forkserver"))


@contextmanager
def open_pool(address: str | None, workers: int | None = None) -> Iterator[Any]:
    """`workers` unchanged without an address; else a Ray cluster's `TaskPool`, connected
    for the `with` block (a cluster started for it, `local` with `workers` CPUs, is shut
    down after it)."""
    if address is None:
        yield workers
        return
    check_address(address)
    from masspush.cluster.ray_pool import connect

    with connect(address, cpus=workers) as pool:
        yield pool


def split(indices: np.ndarray, pool: TaskPool, per_task: int | None = None) -> list[np.ndarray]:
    """`indices` in contiguous chunks for `pool`: `per_task` each, or about four tasks per
    worker (small enough that a lost task costs little, large enough to pay its overhead)."""
    indices = np.asarray(indices)
    if per_task is None:
        per_task = max(1, -(-len(indices) // (4 * max(pool.size, 1))))
    return [indices[i : i + per_task] for i in range(0, len(indices), per_task)]


def gather(results: Iterator[tuple[int, Any]], count: int) -> list[Any]:
    """The results of `imap` in the order of their jobs."""
    out: list[Any] = [None] * count
    for i, result in results:
        out[i] = result
    return out
