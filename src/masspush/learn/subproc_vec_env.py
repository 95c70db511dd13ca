"""stable-baselines3's `SubprocVecEnv`, failing instead of hanging when a worker dies.

Under the fork start method each worker inherits open copies of the pipes of the workers
started after it. When one of those dies (an exception in its environment), its pipe stays
open in its older siblings, so the parent's `recv` never sees end-of-file and the trainer
waits forever. Here every `recv` waits in short slices and, between them, checks that the
worker is alive: a dead one raises `ChildProcessError` naming it, and a long run can be
resumed from its last checkpoint.
"""

from __future__ import annotations

from collections.abc import Callable
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from typing import Any

import gymnasium as gym
from stable_baselines3.common.vec_env import SubprocVecEnv

POLL_SECONDS = 1.0
"""How long a `recv` waits between checks that its worker still lives [ours]."""


class WorkerDiedError(ChildProcessError):
    """A vectorised environment's worker process ended while the trainer waited for it."""


class _WatchedPipe:
    """The parent's end of one worker's pipe: `recv` fails once the worker is dead."""

    def __init__(self, pipe: Connection, process: BaseProcess, index: int):
        self.pipe, self.process, self.index = pipe, process, index

    def send(self, obj: Any) -> None:
        self.pipe.send(obj)

    def recv(self) -> Any:
        try:
            while not self.pipe.poll(POLL_SECONDS):
                if not self.process.is_alive():
                    raise EOFError
            return self.pipe.recv()
        except EOFError:  # no sibling held this pipe: the plain end-of-file
            self.process.join(timeout=10)
            raise WorkerDiedError(
                f"environment worker {self.index} died (exit code {self.process.exitcode}; "
                "its error is printed above); rerun the command to resume from the last "
                "checkpoint"
            ) from None

    def poll(self, timeout: float = 0.0) -> bool:
        return self.pipe.poll(timeout)

    def close(self) -> None:
        self.pipe.close()


class WatchedSubprocVecEnv(SubprocVecEnv):
    """`SubprocVecEnv` whose waits end in `WorkerDiedError` when a worker has died."""

    def __init__(
        self, env_fns: list[Callable[[], gym.Env]], start_method: str | None = None
    ) -> None:
        super().__init__(env_fns, start_method)
        self.remotes = [  # type: ignore[assignment]
            _WatchedPipe(pipe, process, i)
            for i, (pipe, process) in enumerate(zip(self.remotes, self.processes, strict=True))
        ]

    def close(self) -> None:
        if self.closed:
            return
        # A dead worker cannot answer 'close', and the living ones may have answered a step
        # already: drain what is there, stop the living, reap them all.
        for remote in self.remotes:
            while remote.process.is_alive() and remote.poll(0.1):
                remote.pipe.recv()
        for remote in self.remotes:
            if remote.process.is_alive():
                remote.send(("close", None))
        for process in self.processes:
            process.join(timeout=10)
            if process.is_alive():
                process.terminate()
        self.closed = True
