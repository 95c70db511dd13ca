"""A Ray cluster as a `TaskPool`: one task per job, retried where a worker or node is lost.

Why these choices:
- A task asks for one CPU (`TASK_CPUS`) and the work inside it keeps to one thread, so a
  node runs as many tasks as it has cores and none oversubscribes them.
- At most a few tasks per CPU are in flight (`IN_FLIGHT_PER_CPU`): results wait in the
  object store only until the driver takes them, so a million-episode collection needs no
  more memory than a small one.
- A task whose worker process or node dies is run again (`MAX_RETRIES`); its result is taken
  only once, when it succeeds, and the driver alone writes files, so nothing is lost or
  written twice and no shared file system is needed.
- An exception raised by the task itself (bad input) is not retried: it would fail again.
  It reaches the caller as itself, so the command line prints it as one line.
- Workers must run the same masspush as the driver: a cluster whose workers run other code
  would give other episodes, so `connect` compares the package's source and refuses.
"""

from __future__ import annotations

import hashlib
import logging
import os
import socket
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tqdm import tqdm

from masspush.cluster.errors import RAY_EXTRA, ClusterError

if TYPE_CHECKING:
    from masspush.cluster.ray_vec_env import RayVecEnv

TASK_CPUS = 1
"""CPUs each task asks for (its work runs on one thread)."""
MAX_RETRIES = 3
"""Times a task is rerun after its worker or node died (Ray's own default)."""
IN_FLIGHT_PER_CPU = 2
"""Tasks submitted ahead per CPU: enough to keep every core busy between results."""


def source_fingerprint() -> str:
    """A hash of this masspush's source (its .py and .c files): equal on two machines only
    if they run the same code."""
    root = Path(__file__).parents[1]
    digest = hashlib.sha256()
    for path in sorted([*root.rglob("*.py"), *root.rglob("*.c")]):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _call(fn: Callable[[Any, Any], Any], shared: Any, job: Any) -> Any:
    return fn(shared, job)


class RayPool:
    """Tasks on the Ray cluster this process is connected to (`connect`)."""

    def __init__(self, address: str):
        import ray

        self.address = address
        self._remote = ray.remote(num_cpus=TASK_CPUS, max_retries=MAX_RETRIES)(_call)
        cpus = int(ray.cluster_resources().get("CPU", 0))
        if cpus < TASK_CPUS:
            raise ClusterError(
                f"the Ray cluster at {address} has {cpus} CPUs; each masspush task asks "
                f"for {TASK_CPUS}: add a worker node (ray start --address=... --num-cpus=N)"
            )
        self.size = cpus

    def imap(
        self,
        fn: Callable[[Any, Any], Any],
        jobs: Sequence[Any],
        shared: Any = None,
        desc: str | None = None,
    ) -> Iterator[tuple[int, Any]]:
        import ray
        from ray.exceptions import RayError, RayTaskError

        shared_ref = ray.put(shared)  # sent to each node once, not with every task
        window = max(1, IN_FLIGHT_PER_CPU * self.size)
        pending: dict[Any, int] = {}
        following = iter(enumerate(jobs))
        bar = tqdm(total=len(jobs), desc=desc, unit="task", disable=desc is None)
        try:
            while True:
                for i, job in following:
                    pending[self._remote.remote(fn, shared_ref, job)] = i
                    if len(pending) >= window:
                        break
                if not pending:
                    return
                done, _ = ray.wait(list(pending), num_returns=1)
                i = pending.pop(done[0])
                try:
                    result = ray.get(done[0])
                except RayTaskError as err:
                    raise err.cause from None  # the task's own error, as the caller raised it
                except RayError as err:
                    first = str(err).strip().splitlines()[0] if str(err).strip() else ""
                    raise ClusterError(
                        f"task {i} ({desc or fn.__name__}) was lost {MAX_RETRIES + 1} times "
                        f"on the Ray cluster at {self.address}: {type(err).__name__} {first}"
                    ) from None
                bar.update()
                yield i, result
        finally:
            bar.close()
            for ref in pending:
                ray.cancel(ref)

    def vec_env(self, env_fns: list[Callable[[], Any]]) -> RayVecEnv:
        """A stable-baselines3 VecEnv of `env_fns` as Ray actors (`ray_vec_env`)."""
        from masspush.cluster.ray_vec_env import RayVecEnv

        return RayVecEnv(env_fns, groups=min(len(env_fns), self.size))


def _fingerprint_task(_shared: Any, _job: Any) -> str:
    return source_fingerprint()


def _check_worker_code(pool: RayPool) -> None:
    here = source_fingerprint()
    there = next(pool.imap(_fingerprint_task, [None]))[1]
    if there != here:
        raise ClusterError(
            f"the Ray cluster at {pool.address} runs other masspush code (source {there}, "
            f"this driver {here}): install the same masspush on every node"
        )


PROBE_TIMEOUT_S = 5.0
"""How long a head node's port may take to answer before the address counts as unreachable
(Ray's own client would retry for minutes, printing as it goes)."""


def _probe(address: str) -> None:
    """A ClusterError at once where HOST:PORT does not accept a connection."""
    if address in ("auto", "local"):
        return
    host, _, port = address.removeprefix("ray://").rpartition(":")
    try:
        socket.create_connection((host.strip("[]"), int(port)), PROBE_TIMEOUT_S).close()
    except OSError as err:
        raise ClusterError(
            f"cannot reach a Ray cluster at {address}: {err.strerror or err} (is the head "
            "node up, and its port open to this machine?)"
        ) from None


@contextmanager
def connect(address: str, cpus: int | None = None) -> Iterator[RayPool]:
    """A pool on the cluster at `address` for the `with` block. `local` starts one on this
    machine (with `cpus` CPUs, default all) and stops it after; a process already connected
    to Ray (a notebook, a test) keeps its connection."""
    try:
        import ray
    except ImportError:
        raise ClusterError(f"--ray needs Ray: {RAY_EXTRA}") from None

    started = False
    if not ray.is_initialized():
        _probe(address)
        kwargs: dict[str, Any] = {"logging_level": logging.ERROR, "log_to_driver": True}
        if address == "local":
            # A new cluster even where one runs here already (that one is `auto`'s).
            kwargs.update(
                address="local", num_cpus=cpus or os.cpu_count() or 1, include_dashboard=False
            )
        else:
            kwargs["address"] = address
        try:
            ray.init(**kwargs)
        except (ConnectionError, RuntimeError, ValueError, TimeoutError) as err:
            hint = " (start one with `ray start --head`, or use --ray local)"
            raise ClusterError(
                f"cannot reach a Ray cluster at {address}: "
                f"{' '.join(str(err).split())[:200]}{hint if address == 'auto' else ''}"
            ) from None
        started = True
    try:
        pool = RayPool(address)
        _check_worker_code(pool)
        yield pool
    finally:
        if started:
            ray.shutdown()
